"""How much of a tile's CPU time holds the GIL, on a busy machine, and where.

    RAYTRACE_ASSETS=../shared/scenes python benchmarks/gil_profile.py [--row unshadowed|shadowed|fog]
                                                                      [--passes N] [--tree DIR] [--top K]
                                                                      [--lines FUNC,...] [--size WxH]

A child process renders every tile of one of `scaling.py --quick`'s rows once (untimed: kernels the
warm-up leaves out load then), then N passes over all of them on one thread, each pass followed by
CALIBRATE seconds of a Python spin that holds the GIL throughout. Two py-spy samplers attach to it
at once, one with `--gil` (it keeps only the samples that find the thread holding the GIL) and one
without (every sample of the running thread, in Python or in a kernel). Both count the spin whole,
so the ratio of their spin counts is the ratio of their rates, and the tiles' GIL share is

    (GIL-holding samples in the tiles / GIL spin samples) / (all samples in the tiles / all spin samples).

Unlike `scaling.py`'s share (GIL samples over py-spy's rate times the tiles' wall time), this needs
neither the rate nor the wall time: a thread descheduled by other processes is sampled the same way
by both samplers, so the load cancels (as far as it falls evenly on Python and on the kernels). The
GIL-holding CPU time is that share times the tiles' thread CPU time. Then, per function of the
tiles' stacks, its share of the GIL-holding samples (inclusive), and the lines of render_tile and
shade_rays (or of the functions `--lines` names, the innermost of them in each stack) by what they
call. `--size 1024x512` renders the row at another size (the Sibenik rows' tiles grow with it: 1,024
rays at 256x128, 8,192 at 1024x512). Attaching to a process needs ptrace permission (root, or
kernel.yama.ptrace_scope = 0); py-spy: `pip install py-spy`.
"""
import argparse
import collections
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ROWS = {"unshadowed": "Sibenik 256x128, 4 spp, analytic, unshadowed",
        "shadowed": "Sibenik 256x128, 4 spp, analytic, volumetric shadows",
        "fog": "sun over height fog 160x120, quadrature"}
CALIBRATE = 0.25  # seconds of GIL-holding spin after each pass
RATE = 400  # each sampler's samples a second


def child(row: str, passes: int, out: Path, size: str | None = None):
    import raytrace  # the --tree's (PYTHONPATH), before scaling.py puts its own checkout first on the path

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import scaling
    from raytrace.rendering import renderer

    name, overrides, method, shadows = scaling.QUICK[ROWS[row]]
    if size:
        width, height = size.split("x")
        overrides = [*overrides, f"camera.width={width}", f"camera.height={height}"]
    scene, method, shadows = scaling.load((name, overrides, method, shadows))
    prep = renderer.prepare(scene)
    task = scaling.task_of(scene, method, shadows)
    renderer.prepare_task(prep, task)
    work = renderer.tiles(scene.camera, task.box)

    def tiles_pass():
        for tile in work:
            renderer.render_tile(prep, task, tile)

    def spin():
        start = now = time.monotonic()
        while now - start < CALIBRATE:
            now = time.monotonic()

    for tile in work:  # untimed (and not tiles_pass: the samplers leave it out)
        renderer.render_tile(prep, task, tile)
    time.sleep(1.0)  # the samplers attach
    cpu = []
    for _ in range(passes):
        start = time.thread_time()
        tiles_pass()
        cpu.append(time.thread_time() - start)
        spin()
    out.write_text(json.dumps({"cpu": cpu, "tiles": len(work), "package": str(Path(raytrace.__file__).parent)}))


def stacks(path: Path):
    """(frames, their function names without the enclosing ones, count) of py-spy's raw output."""
    for line in path.read_text().splitlines():
        stack, _, count = line.rpartition(" ")
        frames = stack.split(";")
        yield frames, [f.split(" (")[0].rpartition(".")[2] for f in frames], int(count)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--row", choices=ROWS, default="unshadowed")
    ap.add_argument("--passes", type=int, default=15)
    ap.add_argument("--tree", type=Path, default=ROOT, help="the checkout whose raytrace is profiled")
    ap.add_argument("--top", type=int, default=25)
    ap.add_argument("--lines", default="render_tile,shade_rays",
                    help="the functions whose lines are listed by what they call (comma-separated)")
    ap.add_argument("--size", help="WxH: the row's image at this size instead")
    ap.add_argument("--child", type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        return child(args.row, args.passes, args.child, args.size)
    spy = shutil.which("py-spy") or str(Path(sys.executable).parent / "py-spy")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        env = dict(os.environ, PYTHONPATH=str(args.tree))
        proc = subprocess.Popen([sys.executable, __file__, "--row", args.row, "--passes", str(args.passes), "--child",
                                 str(tmp / "out.json")] + (["--size", args.size] if args.size else []), env=env)
        spies = []
        for name, flags in (("gil", ["--gil"]), ("all", [])):
            # --nonblocking: two samplers cannot both suspend the process for each sample
            spies.append(subprocess.Popen([spy, "record", "--pid", str(proc.pid), "--rate", str(RATE), "--nonblocking",
                                           "--format", "raw", "--output", str(tmp / f"{name}.txt")] + flags,
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        codes = [proc.wait()] + [s.wait() for s in spies]
        if any(codes):
            raise SystemExit(f"the profiled child or a sampler failed: exit codes {codes}")
        cpu = json.loads((tmp / "out.json").read_text())
        counts = {}
        for name in ("gil", "all"):
            spin = tiles = 0
            for frames, names, n in stacks(tmp / f"{name}.txt"):
                spin += n * ("spin" in names)
                tiles += n * ("tiles_pass" in names)
            counts[name] = (spin, tiles)
        inclusive, lines, total = collections.Counter(), collections.Counter(), 0
        for frames, names, n in stacks(tmp / "gil.txt"):
            if "tiles_pass" not in names:
                continue
            total += n
            for key in {re.sub(r":\d+\)$", ")", f) for f in frames[names.index("tiles_pass") + 1:]}:
                inclusive[key] += n
            mine = [i for i, f in enumerate(names) if f in args.lines.split(",")]
            if mine:
                i = mine[-1]
                lines[frames[i] + (" -> " + frames[i + 1].split(" (")[0] if i + 1 < len(frames) else "")] += n
    (gil_spin, gil_tiles), (all_spin, all_tiles) = counts["gil"], counts["all"]
    share = (gil_tiles / gil_spin) / (all_tiles / all_spin)
    per_pass = sum(cpu["cpu"]) / len(cpu["cpu"])
    size = f" at {args.size}" if args.size else ""
    print(f"# {ROWS[args.row]}{size}, {cpu['tiles']} tiles, {cpu['package']}; load {os.getloadavg()[0]:.1f}")
    print(f"CPU per pass {1e3 * per_pass:.1f} ms; GIL share {share:.3f}; GIL-holding CPU per pass "
          f"{1e3 * share * per_pass:.1f} ms, per tile {1e6 * share * per_pass / cpu['tiles']:.0f} us")
    print(f"functions (share of the tiles' {total} GIL-holding samples, inclusive):")
    for key, n in inclusive.most_common(args.top):
        print(f"  {n / total:6.1%}  {key}")
    print(f"{' and '.join(args.lines.split(','))} by line:")
    for key, n in lines.most_common(args.top):
        print(f"  {n / total:6.1%}  {key}")


if __name__ == "__main__":
    main()
