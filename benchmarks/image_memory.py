"""Does api.check_memory's estimate cover what an image really costs?

    python benchmarks/image_memory.py [--method analytic|montecarlo] [--sizes 1024x512,4096x2048]

Renders a vacuum box room (the image's arrays dominate: no air-light work) with `render.py render
... --out X.exr --png X.png` in a subprocess per size and reports its peak RSS (ru_maxrss) less
that of a 64 x 32 render, against the estimate width x height x (PIXEL_BYTES [+ VARIANCE_BYTES]).
Exits with status 1 if the growth exceeds the estimate at the largest size (an underestimate).
Measured (2 cores), 4096 x 2048: analytic 623 MiB against 720 estimated, montecarlo
(--samples 1) 972 MiB against 1120 (with the error bounds' arrays, docs/error_bounds.md).
"""
import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from raytrace import api  # noqa: E402
from tests.conftest import box_room, to_toml  # noqa: E402

CHILD = ("import resource, sys; from raytrace.cli import main; main(sys.argv[1:]); "
         "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)")


def peak_mib(scene, method, w, h, folder, extra):
    out = subprocess.run([sys.executable, "-c", CHILD, "render", scene, "--method", method, "--width", str(w),
                          "--height", str(h), "--out", f"{folder}/x.exr", "--png", f"{folder}/x.png", "--quiet",
                          *extra], capture_output=True, text=True, cwd=ROOT)
    if out.returncode:
        sys.exit(out.stderr)
    return int(out.stdout.split()[-1]) / 1024


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", default="analytic", choices=("analytic", "montecarlo"))
    ap.add_argument("--sizes", default="1024x512,2048x1024,4096x2048")
    args = ap.parse_args()
    extra = ["--samples", "1"] if args.method == "montecarlo" else []
    per_pixel = api.PIXEL_BYTES + (api.VARIANCE_BYTES if args.method == "montecarlo" else 0)
    with tempfile.TemporaryDirectory() as folder:
        scene = os.path.join(folder, "vacuum.toml")
        Path(scene).write_text(to_toml(box_room(medium={"sigma_a": 0.0, "sigma_s": 0.0})))
        peak_mib(scene, args.method, 64, 32, folder, extra)  # compiles the kernels into the cache
        base = peak_mib(scene, args.method, 64, 32, folder, extra)
        for size in args.sizes.split(","):
            w, h = map(int, size.split("x"))
            growth = peak_mib(scene, args.method, w, h, folder, extra) - base
            estimate = w * h * per_pixel / 2**20
            print(f"{args.method} {w}x{h}: peak RSS growth {growth:.0f} MiB, estimate {estimate:.0f} MiB "
                  f"({growth / estimate:.2f})", flush=True)
    return 1 if growth > estimate else 0


if __name__ == "__main__":
    sys.exit(main())
