"""Light shafts (volumetric shadows over exact lit intervals): accuracy, speed, equal time.

    RAYTRACE_ASSETS=../shared/scenes python benchmarks/light_shafts.py [--quick]

1. Accuracy: `analytic` with shadows against shadowed `quadrature` (the same lit intervals,
   adaptive Gauss-Legendre on each) on box rooms with occluders (plates, a grid of bars, a sphere)
   and on the paper's scenes: the largest per-pixel relative error, against 10 x precision.
2. Speed: a shadowed analytic render over the unshadowed one (interleaved rounds, median), and
   the lit intervals and occluder frusta per segment.
3. Equal time: ray marching with a shadow ray per sample (`shadow_test = samples`, the classic),
   its step count matched to the shadowed analytic render's time, and both errors.
"""
import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import raytrace  # noqa: E402
from raytrace.rendering.renderer import prepare  # noqa: E402


def box(shapes, w, h):
    room = {"camera": {"position": [0.0, 0.0, 3.5], "look_at": [0.0, 0.0, -1.0], "fov": 80.0, "width": w,
                       "height": h, "spp": 1},
            "shape": [{"primitive": "box", "min": [-3.0, -2.0, -4.0], "max": [3.0, 2.0, 4.0],
                       "reflectance": [0.6, 0.5, 0.4]}] + shapes,
            "light": [{"position": [0.0, 1.5, -1.0], "intensity": 20.0}],
            "medium": {"sigma_a": 0.05, "sigma_s": [0.2, 0.3, 0.5], "phase": {"type": "hg", "g": 0.5}}}
    return raytrace.load(room)


def quad(y, x0, x1, z0, z1):
    return {"primitive": "quad", "corners": [[x0, y, z0], [x1, y, z0], [x1, y, z1], [x0, y, z1]]}


def scenes(quick):
    w, h = (48, 36) if quick else (160, 120)
    bars = [quad(0.9, -2.5, 2.5, z, z + 0.08) for z in np.arange(-3.0, 1.0, 0.35)]
    out = {"box: plate": box([quad(1.2, -1.0, 1.0, -2.0, 0.0)], w, h),
           "box: grid of bars": box(bars, w, h),
           "box: sphere": box([{"primitive": "sphere", "center": [0.5, 0.6, -1.2], "radius": 0.4}], w, h)}
    size = ["camera.width=128", "camera.height=64", "camera.spp=1"] if quick else \
        ["camera.width=256", "camera.height=128", "camera.spp=1"]
    for name in ("sibenik", "bridge", "conference"):
        try:
            out[name] = raytrace.load(name, overrides=size)
        except raytrace.UserError as exc:
            print(f"({name} skipped: {exc})")
    return out


def rel_error(img, ref):
    lit = ref > 1e-6 * ref.max()
    return float(np.max(np.abs(img - ref)[lit] / ref[lit])), float(np.mean(np.abs(img - ref)[lit] / ref[lit]))


def render(prep, method, **kw):
    return raytrace.render(prepared=prep, method=method, **kw)


def accuracy(all_scenes):
    print("\n## Accuracy: analytic with shadows against shadowed quadrature (rtol 1e-10)\n")
    print("| scene | precision | max rel. error | mean rel. error | fallback share |")
    print("|---|---|---|---|---|")
    refs = {}
    for name, sc in all_scenes.items():
        prep = prepare(sc)
        refs[name] = (prep, render(prep, "quadrature", rtol=1e-10, volumetric_shadows=True).array)
        for p in (1e-3, 1e-6):
            img = render(prep, "analytic", precision=p, volumetric_shadows=True)
            mx, mean = rel_error(img.array, refs[name][1])
            print(f"| {name} | {p:g} | {mx:.2e} ({'ok' if mx <= 10 * p else 'ABOVE 10 P'}) | {mean:.2e} | "
                  f"{img.stats['fallback_fraction']:.2%} |")
    return refs


def speed(sc, rounds, label):
    print(f"\n## Speed: {label}, {sc.camera.width}x{sc.camera.height}, {sc.camera.spp} spp, 2 threads\n")
    prep = prepare(sc)
    render(prep, "analytic", volumetric_shadows=True)  # compile, maps
    times = {False: [], True: []}
    stats = None
    for _ in range(rounds):
        for vs in (False, True):
            img = render(prep, "analytic", volumetric_shadows=vs)
            times[vs].append(img.seconds)
            stats = img.stats if vs else stats
    t0, t1 = np.median(times[False]), np.median(times[True])
    segs = stats["shadows: segments searched"]
    print("| unshadowed (s) | shadowed (s) | ratio | lit intervals / segment | frusta intersected / segment |")
    print("|---|---|---|---|---|")
    print(f"| {t0:.2f} | {t1:.2f} | {t1 / t0:.1f}x | {stats['shadows: lit intervals'] / segs:.2f} | "
          f"{stats['shadows: frusta intersected'] / segs:.1f} |")


def equal_time(refs):
    print("\n## Equal time: analytic against ray marching with a shadow ray per sample (the classic)\n")
    print("Ray marching's step count is doubled until its render takes at least as long as analytic's at "
          "precision 1e-6; errors are mean relative errors against shadowed quadrature.\n")
    print("| scene | analytic 1e-3: time (s), error | analytic 1e-6: time (s), error | raymarch steps | "
          "raymarch time (s) | raymarch error | error ratio (raymarch / analytic 1e-6) |")
    print("|---|---|---|---|---|---|---|")
    for name, (prep, ref) in refs.items():
        a3 = render(prep, "analytic", precision=1e-3, volumetric_shadows=True)
        a6 = render(prep, "analytic", precision=1e-6, volumetric_shadows=True)
        e3, e6 = rel_error(a3.array, ref)[1], rel_error(a6.array, ref)[1]
        steps, best = 4, None
        while steps <= 8192:
            r = render(prep, "raymarch", steps=steps, shadow_test="samples", volumetric_shadows=True)
            best = (steps, r.seconds, rel_error(r.array, ref)[1])
            if r.seconds >= a6.seconds:
                break
            steps *= 2
        print(f"| {name} | {a3.seconds:.2f}, {e3:.1e} | {a6.seconds:.2f}, {e6:.1e} | {best[0]} | {best[1]:.2f} | "
              f"{best[2]:.1e} | {best[2] / max(e6, 1e-300):.0f}x |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small images, fewer rounds (about a minute)")
    args = ap.parse_args()
    start = time.perf_counter()
    print(f"# Light shafts benchmark ({'quick' if args.quick else 'full'})")
    all_scenes = scenes(args.quick)
    refs = accuracy(all_scenes)
    equal_time(refs)
    if "sibenik" in all_scenes:
        full = raytrace.load("sibenik", overrides=["camera.width=256", "camera.height=128", "camera.spp=1"]) \
            if args.quick else raytrace.load("sibenik")
        speed(full, 2 if args.quick else 3, "Sibenik")
    print(f"\n({time.perf_counter() - start:.0f} s)")


if __name__ == "__main__":
    main()
