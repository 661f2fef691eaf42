"""Air-light evaluations per second and error, `analytic` versus `quadrature`, on the same rays.

    python benchmarks/airlight.py [--width 240 --height 160] [--precisions 1e-3,1e-6,1e-8]

The rays are the camera rays of the built-in default scene (two lamps in a hall, 1 spp) with
their first hits; the medium's phase function is switched between isotropic, Rayleigh and
Henyey-Greenstein. The error of each run is measured against `quadrature` at rtol 1e-13 (itself
checked against scipy in the tests): max and 99.9th percentile of the relative error per ray.
Times are single-thread CPU seconds of the air-light of whole rays alone
(`visibility.unshadowed_airlight`: one segment per ray and light, the method's kernel, the sum
onto the rays; least of 5 rounds in which the compared runs take turns), so figures are ratios
measured in one run on one machine. The last table compares a whole render of the same rays
(first hits, surface term, shadow rays) without any air-light term and with `analytic`.

    RAYTRACE_ASSETS=../shared/scenes python benchmarks/airlight.py --scene conference [--spp 4 --rounds 5]

prints only the cost of the air-light in whole renders of a bundled scene (the conference room at
512 x 512: one light): `analytic` at its default precision, unshadowed, one thread, over the same
render without air-light (sigma_s = 0, the same sigma_t), per phase function (the scene's medium
with its phase function replaced; `--phases "hg g=0.9"` for one); the two take turns in each round,
CPU seconds, medians of the rounds and of the per-round ratios.
"""
import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import raytrace  # noqa: E402
from raytrace.camera import generate_rays  # noqa: E402
from raytrace.default_scene import DEFAULT_TOML  # noqa: E402
from raytrace.methods import get_method, resolve_params  # noqa: E402
from raytrace.media.phase import HG, ISOTROPIC, RAYLEIGH  # noqa: E402
from raytrace.rendering.renderer import prepare, shade_rays  # noqa: E402
from raytrace.scene.format import scene_from_text  # noqa: E402
from raytrace.segments import unshadowed_airlight  # noqa: E402

PHASES = [("isotropic", ISOTROPIC, 0.0), ("rayleigh", RAYLEIGH, 0.0), ("hg g=0.5", HG, 0.5),
          ("hg g=-0.5", HG, -0.5), ("hg g=0.9", HG, 0.9), ("hg g=0.95", HG, 0.95)]


def cpu_best(*fns, repeats=5):
    """Least single-thread CPU time of each function over `repeats` rounds, the functions taking
    turns within a round (so that both see the same machine), and each one's result."""
    times = [[] for _ in fns]
    outs = [None] * len(fns)
    for _ in range(repeats):
        for i, fn in enumerate(fns):
            t0 = time.process_time()
            outs[i] = fn()
            times[i].append(time.process_time() - t0)
    return [(float(np.min(t)), out) for t, out in zip(times, outs)]


def airlight(method, params, rays, medium, prep):
    """The air-light of whole rays [0, t_hit] summed over the lights (segments, the method's
    kernel and the gather onto the rays; the same work as the renderer without volumetric shadows)."""
    m = get_method(method)
    p = resolve_params(m, params, "benchmark")
    return lambda: unshadowed_airlight(m, medium, prep.lights, p, *rays, 0, prep.accel.scale)


def rel_errors(test, ref):
    mask = ref > 0
    rel = np.abs(test[mask] - ref[mask]) / ref[mask]
    return float(rel.max()), float(np.percentile(rel, 99.9))


def render_cost(name, spp, rounds, phases):
    """The air-light's share of whole renders of bundled scene `name` (its medium's sigma_t kept, its
    phase function replaced), `analytic` at its default precision, unshadowed, one thread."""
    prep = prepare(raytrace.load(name))
    medium = prep.scene.medium

    def render(**changes):
        p = dataclasses.replace(prep, scene=dataclasses.replace(prep.scene,
                                                                medium=dataclasses.replace(medium, **changes)))
        return lambda: raytrace.render(prepared=p, method="analytic", threads=1, volumetric_shadows=False, spp=spp)

    none = render(sigma_a=medium.sigma_a + medium.sigma_s, sigma_s=np.zeros(3))
    print(f"{name}, {spp or prep.scene.camera.spp} spp, analytic at its default precision, unshadowed, one "
          f"thread; CPU s, medians of {rounds} rounds\n")
    print("| phase | no air-light s | analytic s | ratio (median of per-round ratios) |")
    print("|---|---|---|---|")
    for label, code, g in (p for p in PHASES if p[0] in phases):
        air = render(phase=code, g=g)
        air(), none()  # compile, build the coefficient blocks
        times = [[], []]
        for _ in range(rounds):
            for i, fn in enumerate((none, air)):
                t0 = time.process_time()
                fn()
                times[i].append(time.process_time() - t0)
        t0, t1 = np.array(times[0]), np.array(times[1])
        print(f"| {label} | {np.median(t0):.3f} | {np.median(t1):.3f} | {np.median(t1 / t0):.2f}x |", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=240)
    ap.add_argument("--height", type=int, default=160)
    ap.add_argument("--precisions", default="1e-3,1e-6,1e-8")
    ap.add_argument("--scene", help="only the air-light's cost in whole renders of this bundled scene")
    ap.add_argument("--spp", type=int, help="samples per pixel of --scene (default: the scene's)")
    ap.add_argument("--rounds", type=int, default=5, help="interleaved rounds of --scene")
    ap.add_argument("--phases", default=",".join(label for label, _, _ in PHASES),
                    help="comma-separated phase functions of --scene's table (default: all)")
    args = ap.parse_args()
    if args.scene:
        render_cost(args.scene, args.spp, args.rounds, args.phases.split(","))
        return
    precisions = [float(p) for p in args.precisions.split(",")]
    scene = scene_from_text(DEFAULT_TOML, "default scene",
                            overrides=[f"camera.width={args.width}", f"camera.height={args.height}", "camera.spp=1"])
    prep = prepare(scene)
    o, d = generate_rays(scene.camera)
    t, _ = prep.accel.first_hit(o, d)
    keys = np.arange(len(o), dtype=np.uint64)
    rays = (o, d, t, keys)
    n_eval = len(o) * len(prep.lights)
    print(f"{len(o)} rays x {len(prep.lights)} lights = {n_eval} air-light evaluations per run "
          f"(channels share coefficients); single-thread CPU time\n")
    print("| phase | precision | analytic Mevals/s | analytic max rel | p99.9 | quadrature (rtol = precision) Mevals/s "
          "| quadrature max rel | speed-up |")
    print("|---|---|---|---|---|---|---|---|")
    for label, code, g in PHASES:
        medium = dataclasses.replace(scene.medium, phase=code, g=g)
        airlight("analytic", {"precision": 1e-3}, rays, medium, prep)()  # compile
        airlight("quadrature", {"rtol": 1e-3}, rays, medium, prep)()
        ref = airlight("quadrature", {"rtol": 1e-13}, rays, medium, prep)()[0]
        for prec in precisions:
            (ta, (va, *_)), (tq, (vq, *_)) = cpu_best(airlight("analytic", {"precision": prec}, rays, medium, prep),
                                                      airlight("quadrature", {"rtol": prec}, rays, medium, prep))
            ea, eq = rel_errors(va, ref), rel_errors(vq, ref)
            print(f"| {label} | {prec:g} | {n_eval / ta / 1e6:.2f} | {ea[0]:.2e} | {ea[1]:.2e} | "
                  f"{n_eval / tq / 1e6:.2f} | {eq[0]:.2e} | {tq / ta:.1f}x |")

    print("\nWhole render of the same rays (first hit, surface term, shadow rays, air-light), single thread:\n")
    print("| phase | precision | no air-light s | analytic s | ratio |")
    print("|---|---|---|---|---|")
    for label, code, g in PHASES:
        medium = dataclasses.replace(scene.medium, phase=code, g=g)
        no_air = dataclasses.replace(scene, medium=dataclasses.replace(medium, sigma_s=np.zeros(3)))
        prep_none = dataclasses.replace(prep, scene=no_air)
        prep_air = dataclasses.replace(prep, scene=dataclasses.replace(scene, medium=medium))
        method = get_method("analytic")
        for prec in precisions[:1]:
            params = resolve_params(method, {"precision": prec}, "benchmark")
            (t0, _), (t1, _) = cpu_best(lambda: shade_rays(prep_none, method, params, o, d, keys, 0),
                                        lambda: shade_rays(prep_air, method, params, o, d, keys, 0))
            print(f"| {label} | {prec:g} | {t0:.3f} | {t1:.3f} | {t1 / t0:.2f} |")


if __name__ == "__main__":
    main()
