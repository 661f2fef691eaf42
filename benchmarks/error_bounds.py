"""The cost of the per-pixel error bounds (docs/error_bounds.md): the same render by this checkout and by
a baseline checkout without them, in turns.

    RAYTRACE_ASSETS=../shared/scenes python benchmarks/error_bounds.py --baseline ../main
        [--scenes bridge,box_room] [--rounds 5] [--threads 2] [--set "--width=256:--height=256"]

Each render is `render.py render SCENE --method analytic --precision 1e-6 --quiet` (with the bounds'
EXR channels written by this checkout) in a subprocess whose working directory is the checkout, so
each imports its own `raytrace` (and its own kernel cache, compiled by a first untimed run of each).
Rounds alternate the two checkouts; the table gives the median render_seconds of the EXR header
(wall time of the render, compilation excluded), the median CPU seconds of the whole child process
(its threads, startup and file writing included) and this checkout's ratio to the baseline's.
"""
import argparse
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from raytrace.output.film import read_exr  # noqa: E402


def run(checkout: Path, scene: str, extra: list[str]):
    """(render seconds of the EXR header, CPU seconds of the child process)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "x.exr"
        cmd = [sys.executable, "render.py", "render", scene, "--method", "analytic", "--precision", "1e-6",
               "--quiet", "--out", str(out), *extra]
        proc = subprocess.Popen(cmd, cwd=checkout, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        err = proc.stderr.read().decode(errors="replace")
        _, status, usage = os.wait4(proc.pid, 0)
        if os.waitstatus_to_exitcode(status) != 0:
            raise SystemExit(f"{checkout}: {' '.join(cmd)} failed: {err.strip()}")
        return float(read_exr(out)[1]["render_seconds"]), usage.ru_utime + usage.ru_stime


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", required=True, help="a checkout without the bounds (e.g. main's)")
    ap.add_argument("--scenes", default="bridge,box_room")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--set", default="", help='more render flags, ":"-separated, e.g. "--width=256:--height=256"')
    args = ap.parse_args()
    extra = ["--threads", str(args.threads)] + [f for f in args.set.split(":") if f]
    checkouts = {"bounds": ROOT, "baseline": Path(args.baseline).resolve()}
    print(f"analytic, precision 1e-6, {' '.join(extra)}; {args.rounds} rounds in turns; medians\n")
    print("| scene | baseline render s | bounds render s | ratio | baseline CPU s | bounds CPU s | ratio |")
    print("|---|---|---|---|---|---|---|")
    for scene in args.scenes.split(","):
        for checkout in checkouts.values():
            run(checkout, scene, extra)  # compile (or load) the kernels, untimed
        times = {k: [] for k in checkouts}
        for _ in range(args.rounds):
            for k, checkout in checkouts.items():
                times[k].append(run(checkout, scene, extra))
        med = {k: [statistics.median(t[i] for t in v) for i in range(2)] for k, v in times.items()}
        (b0, c0), (b1, c1) = med["baseline"], med["bounds"]
        print(f"| {scene} | {b0:.2f} | {b1:.2f} | {b1 / b0:.3f} | {c0:.2f} | {c1:.2f} | {c1 / c0:.3f} |", flush=True)


if __name__ == "__main__":
    main()
