"""How the renderer's tiles would scale on many cores, measured on few.

    RAYTRACE_ASSETS=../shared/scenes python benchmarks/scaling.py [--quick] [--only TEXT] [--balance [SCENE ...]]

Per row (a scene, size and method): every tile of the render is run once on one thread under `py-spy
record --gil` (py-spy samples the stack only while the thread holds the GIL; NumPy's large
operations, Embree's batches and the numba kernels release it). A tile's CPU time is its thread
time; its GIL share is its GIL-holding samples (the tile's call is named tile_<index> so py-spy's
stacks tell the tiles apart) over the samples py-spy took while it ran. py-spy's sampling rate is
measured in the same run: with --gil it records (and counts) only the samples that find a thread
holding the GIL, so its count over the run's wall time is not the rate; the child first spins in
Python for CALIBRATE seconds (holding the GIL throughout), and that call's samples over its wall
time are. From these figures a schedule of 16 and of 64 threads is simulated: each thread takes the
next tile as renderer.Threads does; a tile is ten alternating pieces, its GIL-holding share in
pieces that wait for the one GIL (first come first served) and the rest in pieces that run freely.
The simulated efficiency is the CPU time over threads x makespan. It ignores the GIL's hand-off
latency, memory bandwidth and clock drop, so it is an upper bound: a row must reach 0.85 for 16
threads to have a chance. Beside it, the measured 2-thread speedup: one-thread and two-thread
renders of the row taking turns (ROUNDS each, the median wall times), on this machine however busy
it is (the load average is printed).

--balance prints, for the built-in default scene and every bundled scene (or the scenes it names) at its
own size and method, the largest tile's share of the render's CPU time (the target: at most 1/64);
--rows, for each row of the table, the largest image row's share (what a tile of whole rows would at
least hold).
"""
import argparse
import heapq
import json
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import raytrace  # noqa: E402
from raytrace import api  # noqa: E402
from raytrace.rendering import renderer  # noqa: E402
from raytrace.methods import get_method, resolve_params  # noqa: E402

from run import machine  # noqa: E402

FOG = str(ROOT / "benchmarks" / "scenes" / "sun_over_height_fog.toml")
# name: (scene, overrides, method, volumetric shadows)
ROWS = {
    "Sibenik 1024x512, 4 spp, analytic, unshadowed": ("sibenik", [], "analytic", False),
    "Sibenik 1024x512, 4 spp, analytic, volumetric shadows": ("sibenik", [], "analytic", True),
    "sun over height fog 160x120, quadrature": (FOG, [], "quadrature", True),
    "sun over height fog 640x480, quadrature": (FOG, ["camera.width=640", "camera.height=480"], "quadrature", True),
}
QUICK = {
    "Sibenik 256x128, 4 spp, analytic, unshadowed": ("sibenik", ["camera.width=256", "camera.height=128"],
                                                     "analytic", False),
    "Sibenik 256x128, 4 spp, analytic, volumetric shadows": ("sibenik", ["camera.width=256", "camera.height=128"],
                                                             "analytic", True),
    "sun over height fog 160x120, quadrature": ROWS["sun over height fog 160x120, quadrature"],
}
RATE = 250  # py-spy's samples a second
ROUNDS = 3  # of the timed one- and two-thread renders
PIECES = 10  # a simulated tile's alternating GIL-holding and free pieces
CALIBRATE = 1.0  # seconds of the child's GIL-holding spin that measures py-spy's sampling rate


def load(row):
    scene, overrides, method, shadows = row
    return api.load(scene, overrides), method, shadows


def task_of(scene, method_name: str, shadows: bool):
    m = get_method(method_name)
    params = resolve_params(m, api.scene_defaults(api.table_params(scene), m, "scaling"), "scaling")
    cam = scene.camera
    return renderer.Task(m.name, params, 0, 1.0 if shadows else None, (0, 0, cam.width, cam.height))


def row_shares(row) -> np.ndarray:
    """Each image row's share of the render's CPU time: the row rendered as one tile, on this
    thread (the first row once more before, untimed)."""
    scene, method, shadows = load(row)
    prep = renderer.prepare(scene)
    task = task_of(scene, method, shadows)
    renderer.prepare_task(prep, task)
    cam = scene.camera
    rows = [renderer.Tile(slice(r, r + 1), slice(0, cam.width), slice(0, cam.spp)) for r in range(cam.height)]
    renderer.render_tile(prep, task, rows[0])
    cpu = []
    for tile in rows:
        start = time.thread_time()
        renderer.render_tile(prep, task, tile)
        cpu.append(time.thread_time() - start)
    return np.array(cpu) / sum(cpu)


def tile_times(row) -> list[dict]:
    """Every tile of `row` run in order on this thread: its CPU (thread) seconds and its wall
    start and end (time.monotonic), each call named tile_<index>. The first tile is run once more
    before: its first run pays for kernels that renderer.warm_up does not reach (0.8 s of the
    height fog's 4.2 s of tiles), a cost of the compile, not of the tiles' balance."""
    scene, method, shadows = load(row)
    prep = renderer.prepare(scene)
    task = task_of(scene, method, shadows)
    renderer.prepare_task(prep, task)  # the compile, before the tiles
    work = renderer.tiles(scene.camera, task.box)
    renderer.render_tile(prep, task, work[0])  # untimed: the first tile still loads kernels warm_up left out

    def call(prep, task, tile):
        return renderer.render_tile(prep, task, tile)

    times = []
    for i, tile in enumerate(work):
        named = type(call)(call.__code__.replace(co_name=f"tile_{i}", co_qualname=f"tile_{i}"), globals())
        start, cpu = time.monotonic(), time.thread_time()
        named(prep, task, tile)
        times.append({"cpu": time.thread_time() - cpu, "start": start, "end": time.monotonic()})
    return times


def gil_calibration() -> float:
    """Spin in Python, holding the GIL, for CALIBRATE seconds; returns the wall seconds spun."""
    start = now = time.monotonic()
    while now - start < CALIBRATE:
        now = time.monotonic()
    return now - start


def profiled(row_name: str, rows: dict) -> tuple[np.ndarray, np.ndarray]:
    """(CPU seconds, GIL share) of every tile of the row, from a child process under py-spy."""
    spy = shutil.which("py-spy") or str(Path(sys.executable).parent / "py-spy")
    if not Path(spy).exists():
        raise SystemExit("py-spy is needed for the GIL shares: pip install py-spy")
    with tempfile.TemporaryDirectory() as tmp:
        raw, out = Path(tmp) / "raw.txt", Path(tmp) / "times.json"
        child = [sys.executable, __file__, "--child", row_name, str(out)] + (["--quick"] if rows is QUICK else [])
        run = subprocess.run([spy, "record", "--gil", "--rate", str(RATE), "--format", "raw", "--output", str(raw),
                              "--", *child], capture_output=True, text=True)
        if run.returncode or not out.exists():  # py-spy exits 0 when its child fails
            raise SystemExit(f"{row_name}: the profiled child failed:\n{run.stderr}")
        child_out = json.loads(out.read_text())
        times = child_out["tiles"]
        gil, spin = np.zeros(len(times)), 0
        for line in raw.read_text().splitlines():
            stack, _, count = line.rpartition(" ")
            found = re.search(r"\btile_(\d+) ", stack)
            if found:
                gil[int(found.group(1))] += int(count)
            elif re.search(r"\bgil_calibration ", stack):
                spin += int(count)
    cpu = np.array([t["cpu"] for t in times])
    tile_wall = np.array([t["end"] - t["start"] for t in times])
    rate = spin / child_out["calibration"]  # py-spy's actual samples a second
    return cpu, np.clip(gil / rate / np.maximum(tile_wall, 1e-9), 0.0, 1.0)


def makespan(cpu: np.ndarray, gil: np.ndarray, threads: int) -> float:
    """The simulated schedule's makespan: tiles taken in order by the next free thread, each in
    PIECES alternating GIL-holding and free pieces; the GIL served first come first served."""
    gil_free = 0.0
    pending = [(0.0, i, 0) for i in range(min(threads, len(cpu)))]  # (when, tile, its next piece)
    nxt, end = len(pending), 0.0
    while pending:  # in time order: the GIL's requests are served in the order they are made
        t, i, p = heapq.heappop(pending)
        if p == 2 * PIECES:  # the tile is done: its thread takes the next one
            end = max(end, t)
            if nxt < len(cpu):
                heapq.heappush(pending, (t, nxt, 0))
                nxt += 1
        elif p % 2 == 0:  # a GIL-holding piece
            gil_free = max(t, gil_free) + cpu[i] * gil[i] / PIECES
            heapq.heappush(pending, (gil_free, i, p + 1))
        else:
            heapq.heappush(pending, (t + cpu[i] * (1.0 - gil[i]) / PIECES, i, p + 1))
    return end


def speedup(row) -> tuple[float, float]:
    """Median wall seconds of one-thread and two-thread renders taking turns, ROUNDS each."""
    scene, method, shadows = load(row)
    prep = raytrace.rendering.renderer.prepare(scene)
    opts = {"method": method, "volumetric_shadows": shadows, "prepared": prep}
    raytrace.render(**opts, threads=1)  # compile
    one, two = [], []
    for _ in range(ROUNDS):
        one.append(raytrace.render(**opts, threads=1).seconds)
        two.append(raytrace.render(**opts, threads=2).seconds)
    return statistics.median(one), statistics.median(two)


DEFAULT = "(default)"  # the built-in default scene (render.py without a scene)


def balance(names: list[str] | None = None):
    """The largest tile's share of the CPU time, per scene of `names` (default: the built-in default scene
    and every bundled scene)."""
    names = names or [DEFAULT] + sorted(p.stem for p in (ROOT / "scenes").glob("*.toml"))
    print(f"{'scene':<20} {'tiles':>6} {'CPU s':>8} {'largest tile':>13}")
    for name in names:
        scene = api.load(None if name == DEFAULT else str(ROOT / "scenes" / f"{name}.toml"))
        method = scene.render.get("method", "analytic")
        row = (scene, [], method, bool(scene.render.get("volumetric_shadows", True)))
        try:
            cpu = np.array([t["cpu"] for t in tile_times(row)])
        except raytrace.errors.UserError as exc:  # a scene whose meshes RAYTRACE_ASSETS does not find
            print(f"{name:<20} skipped: {exc}")
            continue
        print(f"{name:<20} {len(cpu):>6} {cpu.sum():>8.2f} {cpu.max() / cpu.sum():>12.4f}", flush=True)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="small Sibenik and the 160x120 fog: minutes")
    p.add_argument("--balance", nargs="*", metavar="SCENE",
                   help="the largest tile's share on these scenes (none named: the default and every bundled scene)")
    p.add_argument("--rows", action="store_true", help="the largest image row's share of each row's render")
    p.add_argument("--only", metavar="TEXT", help="the rows whose name contains TEXT")
    p.add_argument("--child", nargs=2, metavar=("ROW", "OUT"), help=argparse.SUPPRESS)
    args = p.parse_args()
    rows = QUICK if args.quick else ROWS
    if args.child:
        spun = gil_calibration()
        Path(args.child[1]).write_text(json.dumps({"calibration": spun, "tiles": tile_times(rows[args.child[0]])}))
        return
    if args.balance is not None:
        balance(args.balance)
        return
    if args.rows:
        for name, row in rows.items():
            shares = row_shares(row)
            print(f"{name}: the largest row (of {len(shares)}) holds {shares.max():.3f} of the CPU time", flush=True)
        return
    info = machine()
    print(f"# {info['cpu']}, {info['cores']} cores, load {info['load']}; commit {info['commit']}; "
          f"embreex {info['embreex']}, numba {info['numba']}")
    print(f"{'row':<56} {'tiles':>5} {'CPU s':>7} {'GIL':>5} {'largest':>8} {'eff16':>6} {'eff64':>6} "
          f"{'1 thr s':>8} {'2 thr s':>8} {'speedup':>7}")
    for name, row in rows.items():
        if args.only and args.only not in name:
            continue
        cpu, gil = profiled(name, rows)
        eff = [cpu.sum() / (n * makespan(cpu, gil, n)) for n in (16, 64)]
        one, two = speedup(row)
        print(f"{name:<56} {len(cpu):>5} {cpu.sum():>7.2f} {(cpu * gil).sum() / cpu.sum():>5.2f} "
              f"{cpu.max() / cpu.sum():>8.4f} {eff[0]:>6.2f} {eff[1]:>6.2f} {one:>8.2f} {two:>8.2f} {one / two:>7.2f}",
              flush=True)


if __name__ == "__main__":
    main()
