"""Peak memory (resident set) of whole renders of the paper's scenes at their own resolutions.

    RAYTRACE_ASSETS=../shared/scenes python benchmarks/peak_memory.py [--scenes sibenik,bridge]
        [--limit-gib 2] [--threads N]
        [--extra "raymarch:--steps=100000:--volumetric-shadows:--shadow-test=samples:--crop=0,0,64,8"]

Every render runs in a subprocess of its own (`render.py render SCENE --method M ... --quiet`) and
its peak RSS is that child's `ru_maxrss` (os.wait4), so one render's memory never counts towards
another's. Runs: `analytic` without and with volumetric shadows (lit intervals), and `raymarch` and
`montecarlo` (their default parameters) with volumetric shadows by lit intervals and by a shadow
ray per medium sample (`--shadow-test samples`: the renders that hold medium points, in chunks of
bounded size); `--extra` adds runs. The render time is the EXR header's
render_seconds (compilation excluded). Exits with status 1 if a render fails or peaks above the
limit (default 2 GiB).
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from raytrace.output.film import read_exr  # noqa: E402
from raytrace.scene.format import load_scene  # noqa: E402

SCENES = ("sibenik", "bridge", "conference")
SHADOWS = ["--volumetric-shadows"]
PER_SAMPLE = SHADOWS + ["--shadow-test", "samples"]
RUNS = [("analytic", []), ("analytic", SHADOWS), ("raymarch", SHADOWS), ("raymarch", PER_SAMPLE),
        ("montecarlo", SHADOWS), ("montecarlo", PER_SAMPLE)]


def run(scene: Path, method: str, options: list[str], threads: int | None):
    """(exit status, wall seconds, render seconds or None, peak RSS in bytes, last line of stderr)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "x.exr"
        cmd = [sys.executable, str(ROOT / "render.py"), "render", str(scene), "--method", method, *options,
               "--quiet", "--out", str(out)] + (["--threads", str(threads)] if threads else [])
        start = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=ROOT)
        err = proc.stderr.read().decode(errors="replace")
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        wall = time.perf_counter() - start
        seconds = float(read_exr(out)[1]["render_seconds"]) if proc.returncode == 0 and out.exists() else None
        last = err.strip().splitlines()[-1] if err.strip() else ""
        return proc.returncode, wall, seconds, usage.ru_maxrss * 1024, last  # ru_maxrss is in KiB on Linux


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--limit-gib", type=float, default=2.0)
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--extra", action="append", default=[],
                    help='another run, "method:--flag=value:...", e.g. "raymarch:--steps=100000:--volumetric-shadows"')
    args = ap.parse_args()
    runs = RUNS + [(e.split(":")[0], [o for o in e.split(":")[1:] if o]) for e in args.extra]
    limit = args.limit_gib * 2**30
    failed = False
    print(f"peak RSS of each render in its own process, limit {args.limit_gib:g} GiB; {os.cpu_count()} CPUs\n")
    print("| scene | resolution | method | options | render s | wall s | peak RSS MiB | under limit |")
    print("|---|---|---|---|---|---|---|---|")
    for name in args.scenes.split(","):
        path = ROOT / "scenes" / f"{name}.toml"
        cam = load_scene(path).camera
        for method, options in runs:
            code, wall, seconds, rss, last = run(path, method, options, args.threads)
            ok = code == 0 and rss < limit
            failed |= not ok
            render_s = f"{seconds:.2f}" if seconds is not None else f"failed ({code}): {last}"
            print(f"| {name} | {cam.width}x{cam.height}, {cam.spp} spp | {method} | {' '.join(options) or '-'} | "
                  f"{render_s} | {wall:.1f} | {rss / 2**20:.0f} | {'yes' if ok else 'NO'} |", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
