"""A local Dask cluster against the threaded renderer on the same image (raytrace/rendering/distributed.py).

    RAYTRACE_ASSETS=../shared/scenes python benchmarks/cluster.py [--workers 2] [--repeats 3] [--quick]

Prints the machine load (`os.getloadavg`: 1, 5, 15 minutes) before, after and per round, then:
  1. efficiency: the same render with the threaded renderer (all cores) and on a local cluster of
     --workers single-threaded worker processes, taking turns --repeats times; efficiency = threaded
     time / cluster time, the median over the rounds (each round's pair shares the machine's load
     of the moment; compile and scene loading excluded, as in the EXR header's render_seconds); the
     images are checked to be bit-identical. The CPU seconds of both (this process, and with the
     cluster also its workers) give a second efficiency that other processes on the machine hardly
     move: it counts the work that distribution adds, not the idle tail;
  2. per-task cost: from the same cluster renders, the tasks' own compute seconds against
     workers x wall time: overhead per task = (workers x wall - sum of compute) / tasks (scheduling,
     transfer, reduction on the client and the idle tail), next to Dask's floor (no-op tasks);
  3. scene loading (meshes, Embree, kernel warm-up) on fresh clusters of 1 .. --workers processes:
     the slowest worker's wall time, and one process's prepare() for comparison.
"""
import argparse
import os
import resource
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import raytrace  # noqa: E402
from raytrace.rendering import distributed, renderer  # noqa: E402
from raytrace.methods import get_method, resolve_params  # noqa: E402
from raytrace.options import RenderOptions  # noqa: E402


def cpu_seconds():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def cluster_render(client, prep, method, params, seed, workers):
    """One render through distributed.map_tiles, keeping the tasks' compute times."""
    cam = prep.scene.camera
    box = (0, 0, cam.width, cam.height)
    m = get_method(method)
    job = distributed.Job(prep.scene, renderer.Task(m.name, resolve_params(m, params, "bench"), seed, None, box))
    distributed.prepare_workers(client, job)
    work = renderer.tiles(cam, box)
    acc = renderer.Accumulator(work, box, cam.spp, m.stochastic, renderer.stats_size(m))
    timings = []
    cpu = cpu_seconds() + sum(client.run(cpu_seconds).values())
    start = time.perf_counter()
    for i, result in distributed.map_tiles(client, job, work, timings):
        acc.add(i, result)
    wall = time.perf_counter() - start
    cpu = cpu_seconds() + sum(client.run(cpu_seconds).values()) - cpu
    return acc.image, wall, cpu, len(work), sum(timings), (workers * wall - sum(timings)) / len(work)


def noop_floor(client, n=2000):
    client.gather(client.map(abs, range(-50, 0), pure=False))  # warm
    start = time.perf_counter()
    client.gather(client.map(abs, range(-n, 0), pure=False))
    return (time.perf_counter() - start) / n


def load_times(scene_name, max_workers):
    scene = raytrace.load(scene_name)
    start = time.perf_counter()
    prep = renderer.prepare(scene)
    print(f"  {scene_name}: one process prepare() {time.perf_counter() - start:.2f} s")
    renderer.render(prep, "analytic", options=RenderOptions(crop=(0, 0, 1, 1)))  # the kernels in the disk cache
    m = get_method("analytic")
    job = distributed.Job(scene, renderer.Task(m.name, resolve_params(m, {}, "bench"), 0, None, (0, 0, 1, 1)))
    for n in range(1, max_workers + 1):
        with distributed.connect(f"local:{n}") as client:
            start = time.perf_counter()
            found = client.run(distributed._preload, job)
            wall = time.perf_counter() - start
            loads = ", ".join(f"{r['load']:.2f}" for r in found.values())
            print(f"  {scene_name}: {n} worker(s): all loaded in {wall:.2f} s (per worker load {loads} s)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scene", default="sibenik")
    ap.add_argument("--method", default="montecarlo")
    ap.add_argument("--samples", type=int, default=96, help="montecarlo samples per ray")
    ap.add_argument("--width", type=int, default=1024)
    ap.add_argument("--height", type=int, default=512)
    ap.add_argument("--spp", type=int, default=4)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--quick", action="store_true", help="a 256x128 image, 1 repeat (a smoke test)")
    args = ap.parse_args()
    if args.quick:
        args.width, args.height, args.samples, args.repeats = 256, 128, 16, 1
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())} ({os.cpu_count()} cores)")
    scene = raytrace.load(args.scene, [f"camera.width={args.width}", f"camera.height={args.height}",
                                       f"camera.spp={args.spp}"])
    prep = renderer.prepare(scene)
    params = {"samples": args.samples} if args.method == "montecarlo" else {}
    print(f"{args.scene} {args.width}x{args.height} {args.spp} spp, {args.method} {params}, "
          f"{len(renderer.tiles(scene.camera, (0, 0, args.width, args.height)))} tiles")
    single, multi, overheads, cpu_ratios = [], [], [], []
    with distributed.connect(f"local:{args.workers}") as client:
        floor = noop_floor(client)
        for rep in range(args.repeats):
            cpu = cpu_seconds()
            ref = renderer.render(prep, args.method, params)
            cpu = cpu_seconds() - cpu
            single.append(ref.seconds)
            image, wall, cpu_n, tasks, compute, overhead = cluster_render(client, prep, args.method, params, 0,
                                                                          args.workers)
            multi.append(wall)
            overheads.append(overhead)
            cpu_ratios.append(cpu / cpu_n)
            same = image.tobytes() == ref.image.tobytes()
            print(f"  round {rep + 1}: threaded {ref.seconds:.2f} s, cluster {wall:.2f} s ({tasks} tasks, "
                  f"{compute / tasks * 1e3:.1f} ms compute each, overhead {overhead * 1e3:.1f} ms/task), "
                  f"CPU {cpu:.1f} / {cpu_n:.1f} s, bit-identical: {same}; load {os.getloadavg()[0]:.2f}")
            if not same:
                raise SystemExit("the cluster's image differs from the threaded one")
    ratios = np.array(single) / np.array(multi)
    print(f"efficiency (threaded / cluster of {args.workers} workers, median of {args.repeats} rounds): "
          f"{np.median(ratios):.3f} (rounds {' '.join(f'{r:.3f}' for r in ratios)}; median times "
          f"{np.median(single):.2f} / {np.median(multi):.2f} s)")
    print(f"CPU efficiency (threaded CPU s / cluster CPU s incl. workers, median): {np.median(cpu_ratios):.3f}")
    print(f"per-task overhead (median): {np.median(overheads) * 1e3:.1f} ms; Dask no-op task floor "
          f"{floor * 1e3:.2f} ms")
    print("scene loading (meshes, Embree, kernel warm-up):")
    for name in (args.scene, "conference") if not args.quick else (args.scene,):
        load_times(name, args.workers)
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
