"""Time each method needs to reach a mean relative error of 1e-3 against `quadrature` on the
default scene, or its best error within 10x the analytic method's time.

    python benchmarks/time_to_error.py [--width 240 --height 160 --target 1e-3]

Every method climbs a ladder of settings, cheapest first (ray-marching steps, Sun's table size,
Monte Carlo samples, the analytic precision, ...) until its image reaches the target or its render
time exceeds the limit. Times are wall-clock seconds of `renderer.render` on all cores (compile
time excluded, median of 3 for deterministic methods); errors use `metrics.errors` (mean relative
error over pixels and channels) against `quadrature` at rtol 1e-12 on the same camera samples.
"""
import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from raytrace.default_scene import DEFAULT_TOML  # noqa: E402
from raytrace.output.metrics import errors  # noqa: E402
from raytrace.options import RenderOptions  # noqa: E402
from raytrace.rendering.renderer import prepare, render  # noqa: E402
from raytrace.scene.format import scene_from_text  # noqa: E402

LADDERS = {
    "analytic": [{"precision": p} for p in (1e-1, 1e-2, 1e-3, 1e-4)],
    "quadrature": [{"rtol": r} for r in (1e-1, 1e-2, 1e-3)],
    "raymarch": [{"steps": 2 ** k} for k in range(1, 14)],
    "lecocq": [{"terms": t} for t in (3, 5, 7, 9)],
    "sun": [{"table_size": n} for n in (32, 64, 128, 256, 512, 1024, 2048)],
    "montecarlo": [{"samples": 4 ** k} for k in range(0, 8)],
}


def timed(prep, name, params):
    runs = [render(prep, name, params, RenderOptions(seed=1)) for _ in range(1 if name == "montecarlo" else 3)]
    return float(np.median([r.seconds for r in runs])), runs[0].image


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=240)
    ap.add_argument("--height", type=int, default=160)
    ap.add_argument("--target", type=float, default=1e-3)
    args = ap.parse_args()
    scene = scene_from_text(DEFAULT_TOML, "default scene",
                            overrides=[f"camera.width={args.width}", f"camera.height={args.height}", "camera.spp=1"])
    prep = prepare(scene)
    ref = render(prep, "quadrature", {"rtol": 1e-12}).image
    t_analytic = None
    print(f"default scene {args.width}x{args.height}, 1 spp; target mean relative error {args.target:g}\n")
    print("| method | setting | time (s) | mean rel. error | reached |")
    print("|---|---|---|---|---|")
    for name, ladder in LADDERS.items():
        best = None
        for params in ladder:
            seconds, img = timed(prep, name, params)
            err = errors(img, ref)["mean_rel"]
            if best is None or err < best[2]:
                best = (params, seconds, err)
            if err <= args.target:
                break
            if t_analytic is not None and seconds > 10 * t_analytic:
                break
        params, seconds, err = best
        if name == "analytic":
            t_analytic = seconds
        setting = ", ".join(f"{k}={v}" for k, v in params.items())
        print(f"| {name} | {setting} | {seconds:.3f} | {err:.2e} | {'yes' if err <= args.target else 'no (best)'} |")


if __name__ == "__main__":
    main()
