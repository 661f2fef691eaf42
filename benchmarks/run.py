"""One benchmark table: ratios measured in one process, with the machine and versions in its header.

    RAYTRACE_ASSETS=../shared/scenes python benchmarks/run.py [--quick] [--all] [--json out/benchmarks.json]

Every figure is a ratio of two measurements taken in the same run (timed renders take turns in
interleaved rounds; the median of each), so tables from different commits on the same machine can
be compared through the JSON file. Renders run on 2 threads (compile excluded: every configuration
is rendered once before timing) and are timed in CPU seconds of this process (all its threads),
which other jobs on a shared machine move far less than the wall time. Rows:

- air-light cost: analytic render (precision 1e-6) / the same render without air-light, per phase
  function, on the box room of tests/conftest.py. "Without air-light" is the same scene with
  sigma_s = 0 and sigma_a = sigma_a + sigma_s (same sigma_t): the renderer skips the air-light
  when no channel scatters (`medium.scatters`).
- equal error: quadrature / analytic and fixed Gauss-Legendre / analytic air-light time, per phase
  function, on the rays of the black-walled box room (tests/conftest.plate_room without its plate;
  the segments' air-light alone, `Method.airlight`, one thread). Each method runs at the loosest
  setting of its ladder (analytic precision, quadrature rtol, the rule's order n) whose max relative
  error over all rays and channels against quadrature at rtol 1e-12 is at most TARGET = 1e-6. The
  fixed rule is what a user would write instead: one n-point Gauss-Legendre rule in the scattering
  angle over each segment's range of it (quadrature.py's integrand, no adaptivity).
- equal time: ray-marching error / analytic error (mean relative, against quadrature at rtol
  1e-12) on the paper's scenes, ray marching's steps doubled until its render takes at least as
  long as analytic's (the two timed in turns at each step count). Skipped with a note when RAYTRACE_ASSETS does not find the meshes.
- spot / point: analytic render time (precision 1e-6) with the box room's light made a spot light
  (cone 60 degrees, full within 40, aimed down across the view) / with it a point light, per phase
  function.
- shadows: shadowed / unshadowed analytic render time (`volumetric_shadows=True`) on Sibenik, or on
  the plate room when the meshes are missing.

With --all, also the rows of the other scripts, through their own measuring functions:
benchmarks/height_fog.py (numerically integrated / closed-form optical depth at equal max error),
benchmarks/cluster.py (threaded / local-cluster render time, 2 single-threaded workers) and
benchmarks/vs_mitsuba.py (Mitsuba's time / ours to equal mean error; skipped with a note without the
mitsuba package).
"""
import argparse
import json
import math
import os
import platform
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import raytrace  # noqa: E402
from raytrace.camera import generate_rays  # noqa: E402
from raytrace.jit import njit  # noqa: E402
from raytrace.methods import get_method, resolve_params  # noqa: E402
from raytrace.methods.geometry import by_channel  # noqa: E402
from raytrace.methods.quadrature import _rule as quad_rule  # noqa: E402
from raytrace.output.metrics import errors  # noqa: E402
from raytrace.rendering.renderer import prepare  # noqa: E402
from raytrace.segments import whole_rays  # noqa: E402
from tests.conftest import box_room, plate_room  # noqa: E402

PHASES = {"isotropic": "isotropic", "rayleigh": "rayleigh", "hg g=0.5": {"type": "hg", "g": 0.5},
          "hg g=0.9": {"type": "hg", "g": 0.9}, "hg g=0.95": {"type": "hg", "g": 0.95},
          "hg g=-0.5": {"type": "hg", "g": -0.5}}
PRECISION = 1e-6
TARGET = 1e-6  # the equal-error rows' max relative error
# from each method's loosest allowed setting (analytic precision <= 0.1, quadrature rtol <= 0.5)
LADDERS = {"analytic": ("precision", [10.0 ** -k for k in range(1, 9)]),
           "quadrature": ("rtol", [0.5] + [10.0 ** -k for k in range(1, 12)]),
           "fixed Gauss-Legendre": ("n", [4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024])}
THREADS = 2


def machine():
    cpu = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                if line.startswith("model name")), platform.processor() or "unknown")

    def version(pkg):
        try:
            return metadata.version(pkg)
        except metadata.PackageNotFoundError:
            return "missing"

    def git(*args):
        return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True).stdout.strip()

    dirty = git("status", "--porcelain", "--", "raytrace")
    return {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(), "numpy": version("numpy"),
            "numba": version("numba"), "embreex": version("embreex"),
            "commit": git("rev-parse", "--short", "HEAD") + ("+dirty raytrace/" if dirty else ""),
            "load": " ".join(f"{x:.1f}" for x in os.getloadavg())}


def render(prep, method="analytic", **kw):
    """A render of the rows: unshadowed (the paper's air-light) unless a row asks for shadows, which
    are the API's default, so that the rows time what they say."""
    kw.setdefault("volumetric_shadows", False)
    return raytrace.render(prepared=prep, method=method, threads=THREADS, **kw)


def medians(jobs, rounds):
    """Median CPU seconds (all threads of this process: other jobs on a shared machine move it far
    less than the wall time) of each (prep, method, kwargs) render over `rounds` interleaved rounds,
    after one untimed warm-up render of each; and each job's last image."""
    for prep, method, kw in jobs:
        render(prep, method, **kw)
    times = [[] for _ in jobs]
    images = [None] * len(jobs)
    for _ in range(rounds):
        for i, (prep, method, kw) in enumerate(jobs):
            start = time.process_time()
            images[i] = render(prep, method, **kw)
            times[i].append(time.process_time() - start)
    return [float(np.median(t)) for t in times], images


def airlight_cost(size, rounds):
    rows = []
    for label, phase in PHASES.items():
        camera = {**box_room()["camera"], "width": size[0], "height": size[1]}
        air = box_room(camera=camera, medium={"sigma_a": 0.05, "sigma_s": 0.15, "phase": phase})
        none = box_room(camera=camera, medium={"sigma_a": 0.2, "sigma_s": 0.0, "phase": phase})
        (t_air, t_none), _ = medians([(prepare(raytrace.load(air)), "analytic", {"precision": PRECISION}),
                                      (prepare(raytrace.load(none)), "analytic", {"precision": PRECISION})], rounds)
        rows.append({"row": "analytic / no air-light (time)", "case": f"box room, {label}", "ratio": t_air / t_none,
                     "detail": f"{t_air:.3f} s / {t_none:.3f} s"})
    return rows


@njit
def _fixed_gl(xh, h, ell, kt, ks, code, g, cone, nodes, weights, out):
    """One n-point Gauss-Legendre rule in the scattering angle phi over each segment's range
    [phi_a, phi_b] (phi_b = pi for a segment to infinity), of quadrature.py's integrand."""
    for s in range(xh.shape[0]):
        a = math.atan2(h[s], xh[s])
        b = math.pi if ell[s] == math.inf else math.atan2(h[s], xh[s] - ell[s])
        out[s] = ks / h[s] * quad_rule(0, a, b, xh[s], h[s], kt, code, g, cone[s], nodes, weights)


def fixed_gl_airlight(segs, medium, lights, n):
    nodes, weights = np.polynomial.legendre.leggauss(n)

    def evaluate(xh, h, da, ell, kt, ks, cone):
        out = np.empty_like(xh)
        _fixed_gl(xh, h, ell, kt, ks, medium.phase, medium.g, cone, nodes, weights, out)
        return out

    return by_channel(segs, medium, lights, evaluate)


def airlight_job(prep, segs, name, value):
    """A function computing the segments' air-light (S, 3) with method `name` at its ladder `value`."""
    medium, lights = prep.scene.medium, prep.lights
    if name == "fixed Gauss-Legendre":
        return lambda: fixed_gl_airlight(segs, medium, lights, value)
    m = get_method(name)
    p = resolve_params(m, {LADDERS[name][0]: value}, "benchmark")
    return lambda: m.airlight(segs, medium, lights, p)[0]


def loosest(prep, segs, name, ref):
    """The loosest setting of `name`'s ladder whose max relative error is at most TARGET (the
    tightest if none), and that error."""
    mask = ref > 0.0
    err = None
    for value in LADDERS[name][1]:
        out = airlight_job(prep, segs, name, value)()
        err = float(np.max(np.abs(out[mask] - ref[mask]) / ref[mask]))
        if err <= TARGET:
            return value, err, True
    return value, err, False


def cpu_medians(jobs, rounds):
    """Median single-thread CPU seconds of each function over `rounds` interleaved rounds (after one
    untimed call of each)."""
    for job in jobs:
        job()
    times = [[] for _ in jobs]
    for _ in range(rounds):
        for i, job in enumerate(jobs):
            start = time.process_time()
            job()
            times[i].append(time.process_time() - start)
    return [float(np.median(t)) for t in times]


def equal_error(size, rounds):
    rows = []
    for label, phase in PHASES.items():
        prep = plate_room(phase, plate=False, width=size[0], height=size[1])
        o, d = generate_rays(prep.scene.camera)
        t, _ = prep.accel.first_hit(o, d)
        segs = whole_rays(o, d, t, np.arange(len(o), dtype=np.uint64), len(prep.lights), 0, prep.accel.scale)
        ref = airlight_job(prep, segs, "quadrature", 1e-12)()
        found = {name: loosest(prep, segs, name, ref) for name in LADDERS}
        times = dict(zip(LADDERS, cpu_medians([airlight_job(prep, segs, name, found[name][0]) for name in LADDERS],
                                              rounds)))

        def cell(name):
            value, err, ok = found[name]
            return (f"{name} {LADDERS[name][0]} {value:g}{'' if ok else ' (not reached: tightest)'}: "
                    f"{times[name]:.3f} s, err {err:.1e}")

        for name in ("quadrature", "fixed Gauss-Legendre"):
            rows.append({"row": f"{name} / analytic at max error {TARGET:g} (air-light time)",
                         "case": f"air-light box, {label}", "ratio": times[name] / times["analytic"],
                         "detail": f"{cell('analytic')}; {cell(name)}"})
    return rows


def paper_scenes(size):
    out, notes = {}, []
    for name in ("sibenik", "bridge", "conference"):
        try:
            out[name] = prepare(raytrace.load(name, overrides=[f"camera.width={size[0]}", f"camera.height={size[1]}",
                                                               "camera.spp=1"]))
        except raytrace.UserError as exc:
            notes.append(f"{name} skipped: {str(exc).splitlines()[0]}")
    return out, notes


def equal_time(scenes, rounds):
    rows = []
    for name, prep in scenes.items():
        ref = render(prep, "quadrature", rtol=1e-12).array
        steps = 1
        while True:  # each step count timed in turns with analytic
            (t_a, t_m), (img_a, img_m) = medians([(prep, "analytic", {"precision": PRECISION}),
                                                  (prep, "raymarch", {"steps": steps})], rounds)
            if t_m >= t_a or steps >= 2 ** 14:
                break
            steps *= 2
        e_a, e_m = errors(img_a.array, ref)["mean_rel"], errors(img_m.array, ref)["mean_rel"]
        rows.append({"row": "ray marching / analytic at equal time (mean rel. error)", "case": name,
                     "ratio": e_m / max(e_a, 1e-300),
                     "detail": f"analytic 1e-6: {t_a:.3f} s, err {e_a:.1e}; raymarch {steps} steps: {t_m:.3f} s, "
                               f"err {e_m:.1e}"})
    return rows


def spot_vs_point(size, rounds):
    rows = []
    for label, phase in PHASES.items():
        camera = {**box_room()["camera"], "width": size[0], "height": size[1]}
        medium = {"sigma_a": 0.05, "sigma_s": 0.15, "phase": phase}
        point = box_room(camera=camera, medium=medium)
        light = {**point["light"][0], "type": "spot", "look_at": [0.0, -2.0, -2.0], "cone_angle": 60.0,
                 "falloff_start": 40.0}
        spot = box_room(camera=camera, medium=medium, light=[light])
        (t_spot, t_point), images = medians([(prepare(raytrace.load(spot)), "analytic", {"precision": PRECISION}),
                                             (prepare(raytrace.load(point)), "analytic", {"precision": PRECISION})],
                                            rounds)
        st = images[0].stats
        rows.append({"row": "spot / point analytic (time)", "case": f"box room, {label}", "ratio": t_spot / t_point,
                     "detail": f"{t_spot:.3f} s / {t_point:.3f} s; {st['spot_band_pieces']} band pieces, "
                               f"{st['spot_pieces_by_quadrature']} pieces by quadrature, "
                               f"fallback {100 * st['fallback_fraction']:.2f}%"})
    return rows


def shadows(prep, case, rounds):
    (t0, t1), _ = medians([(prep, "analytic", {"precision": PRECISION}),
                           (prep, "analytic", {"precision": PRECISION, "volumetric_shadows": True})], rounds)
    return [{"row": "shadowed / unshadowed analytic (time)", "case": case, "ratio": t1 / t0,
             "detail": f"{t1:.3f} s / {t0:.3f} s"}]


def height_fog_rows(quick, rounds):
    """benchmarks/height_fog.py's comparison: the midpoint rule's optical depth of an exponential fog
    at the fewest steps n (of 1, 4, 16, ...) whose max relative error is at most 1e-3 / 1e-6, against
    the closed form, on that script's random segments; time ratio of interleaved rounds."""
    import height_fog as hf

    n_seg = 50_000 if quick else hf.N_SEGMENTS
    rng = np.random.default_rng(4)  # height_fog.main's segments
    h = rng.uniform(-2.0, 10.0, n_seg) * hf.H
    mu = rng.uniform(-1.0, 1.0, n_seg)
    length = rng.uniform(0.0, 20.0, n_seg) * hf.H
    ref, out = np.empty(n_seg), np.empty(n_seg)
    hf.closed(h, mu, length, ref)
    rows = []
    for target in (1e-3, 1e-6):
        n = 1
        while True:
            hf.midpoint(h, mu, length, n, out)
            if np.max(np.abs(out - ref) / ref) <= target or n >= 4 ** 7:
                break
            n *= 4
        t_closed, t_mid = cpu_medians([lambda: hf.closed(h, mu, length, ref),
                                       lambda: hf.midpoint(h, mu, length, n, out)], rounds)
        rows.append({"row": f"midpoint / closed-form optical depth at max error {target:g} (time)",
                     "case": f"height fog, {n_seg} random segments", "ratio": t_mid / t_closed,
                     "detail": f"{n} midpoint steps: {t_mid / n_seg * 1e9:.0f} ns; closed form (eq. 34) "
                               f"{t_closed / n_seg * 1e9:.0f} ns per segment"})
    return rows


def cluster_rows(quick, rounds):
    """benchmarks/cluster.py's efficiency: threaded render time / the same render on a local Dask
    cluster of 2 single-threaded workers (`cluster.cluster_render`), median of interleaved rounds."""
    import cluster
    from raytrace.rendering import distributed, renderer

    size, samples = ((256, 128), 16) if quick else ((512, 256), 48)
    name = "sibenik"
    try:
        scene = raytrace.load(name, [f"camera.width={size[0]}", f"camera.height={size[1]}", "camera.spp=1"])
    except raytrace.UserError:
        name = "box room"
        scene = raytrace.load(box_room(camera={**box_room()["camera"], "width": size[0], "height": size[1]}))
    prep = renderer.prepare(scene)
    params = {"samples": samples}
    ratios = []
    with distributed.connect("local:2") as client:
        renderer.render(prep, "montecarlo", params)
        cluster.cluster_render(client, prep, "montecarlo", params, 0, 2)
        for _ in range(3):  # each round a threaded and a cluster render in turn
            threaded = renderer.render(prep, "montecarlo", params).seconds
            ratios.append(threaded / cluster.cluster_render(client, prep, "montecarlo", params, 0, 2)[1])
    return [{"row": "threaded / local cluster, 2 workers (time)", "case": f"{name} {size[0]}x{size[1]}, montecarlo "
             f"{samples} samples", "ratio": float(np.median(ratios)),
             "detail": f"efficiency, median of {len(ratios)} rounds ({' '.join(f'{r:.3f}' for r in ratios)})"}]


def mitsuba_rows(quick, notes):
    """benchmarks/vs_mitsuba.py's time to equal mean relative error (1e-2, 1e-3): Mitsuba's time / ours,
    per scene, through that script's `bench_scene`; a note if the mitsuba package is missing."""
    import importlib.util

    if importlib.util.find_spec("mitsuba") is None:
        notes.append("Mitsuba rows skipped: the mitsuba package is not installed (pip install -e '.[bench]')")
        return []
    import vs_mitsuba as vm
    import drjit as dr
    import mitsuba as mi

    variant, _ = vm.choose_variant("auto")
    mi.set_variant(variant)
    rows = []
    for index, (name, scene, shadows) in enumerate(vm.scenes(quick)):
        res = vm.bench_scene(mi, dr, index, name, scene, shadows, quick, variant != "scalar_rgb")
        for ours in ("analytic", "montecarlo"):
            for target in vm.TARGETS:
                value = res["mitsuba_over_ours_time"][ours][f"{target:g}"]
                if value is not None:
                    rows.append({"row": f"Mitsuba 3 / {ours} at mean error {target:g} (time)",
                                 "case": f"{name} {res['width']}x{res['height']}", "ratio": value,
                                 "detail": f"Mitsuba {mi.__version__} {variant}; time to error "
                                           f"{vm.fmt_t(res['time_to_error']['mitsuba'][f'{target:g}'])} s / "
                                           f"{vm.fmt_t(res['time_to_error'][ours][f'{target:g}'])} s"})
    return rows


def table(info, rows, notes, seconds, quick):
    head = (f"**raytrace benchmarks** ({'quick' if quick else 'full'}, {seconds:.0f} s): commit {info['commit']}; "
            f"{info['cpu']}, {info['cores']} cores; Python {info['python']}, numpy {info['numpy']}, "
            f"numba {info['numba']}, embreex {info['embreex']}; load average {info['load']} (1, 5, 15 min) at the end; "
            f"renders on {THREADS} threads, air-light alone on 1; CPU seconds, medians of interleaved rounds")
    lines = [head, "", "| ratio | case | value | measured |", "|---|---|---|---|"]
    lines += [f"| {r['row']} | {r['case']} | {r['ratio']:.3g}x | {r['detail']} |" for r in rows]
    lines += [f"\n({n})" for n in notes]
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small images, fewer rounds (under 3 minutes)")
    ap.add_argument("--all", action="store_true", help="also the rows of height_fog.py, cluster.py and vs_mitsuba.py")
    ap.add_argument("--json", default=str(ROOT / "out" / "benchmarks.json"), help="where to write the rows as JSON")
    args = ap.parse_args()
    sys.path.insert(0, str(ROOT / "benchmarks"))
    start = time.perf_counter()
    box, equal, paper, sibenik, rounds = ((240, 180), (120, 90), (384, 192), (512, 256), 5) if args.quick else \
        ((320, 240), (240, 180), (512, 256), (1024, 512), 9)
    # the box-room renders take 20-60 ms: more rounds for their ratios
    rows = airlight_cost(box, 4 * rounds) + equal_error(equal, rounds) + spot_vs_point(box, 2 * rounds)
    scenes, notes = paper_scenes(paper)
    rows += equal_time(scenes, rounds)
    if "sibenik" in scenes:
        big = prepare(raytrace.load("sibenik", overrides=[f"camera.width={sibenik[0]}",
                                                          f"camera.height={sibenik[1]}", "camera.spp=1"]))
        rows += shadows(big, f"sibenik {sibenik[0]}x{sibenik[1]}", max(3, rounds // 2))
    else:
        notes.append("paper scenes missing: shadow row on the plate room instead (set RAYTRACE_ASSETS)")
        rows += shadows(plate_room({"type": "hg", "g": 0.5}, width=box[0], height=box[1]), "plate room", rounds)
    if args.all:
        rows += height_fog_rows(args.quick, rounds) + cluster_rows(args.quick, rounds) + mitsuba_rows(args.quick, notes)
    info = machine()
    seconds = time.perf_counter() - start
    print(table(info, rows, notes, seconds, args.quick))
    path = Path(args.json)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"machine": info, "quick": args.quick, "seconds": seconds, "rows": rows,
                                "notes": notes}, indent=2) + "\n")
    print(f"\n(written to {path})")


if __name__ == "__main__":
    main()
