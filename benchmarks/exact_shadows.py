"""Exact lit intervals (raytrace/shadows/frusta.py) against the sampled search that preceded them
(benchmarks/sampled_search.py).

    RAYTRACE_ASSETS=../shared/scenes python benchmarks/exact_shadows.py [--quick] [--rounds N]

On Sibenik (1024x512, 4 spp; --quick: 256x128, 1 spp):
1. Build: the texel lists of both lights (time, entries per triangle, memory).
2. Intervals: the time per (ray, light) segment of the exact intervals and of the sampled search
   at 0.01 rad (its default, with its depth maps) on the same segments, one thread, tile by tile;
   the search at 1e-4 rad on every SUBSAMPLE-th segment (its depth maps cannot go that fine, so every
   sample is a shadow ray); how often the lit length of a segment differs by more than 1e-6 of the
   scene's size between them.
3. Renders: analytic at its defaults, 2 threads, interleaved rounds (the least time of each, and the
   median over rounds of the ratio to the same round's unshadowed render, resist a shared machine's
   load): unshadowed, shadowed with the sampled search at 0.01, and shadowed with the exact
   intervals (the renderer's own; for the sampled search its call to `exact_lit_intervals` is replaced
   in this process, without the end normals the renderer used to pass; texel lists and depth maps built
   beforehand).
"""
import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import raytrace  # noqa: E402
import raytrace.rendering.renderer as renderer  # noqa: E402
from benchmarks import shadow_maps  # noqa: E402
from benchmarks.sampled_search import lit_intervals  # noqa: E402
from raytrace.camera import generate_rays  # noqa: E402
from raytrace.rendering.renderer import prepare, tiles  # noqa: E402
from raytrace.segments import cone_segments, whole_rays  # noqa: E402
from raytrace.shadows.frusta import STATS_NAMES, build, exact_lit_intervals  # noqa: E402

SUBSAMPLE = 512


def tile_segments(prep, tile, width):
    """The tile's (ray, light) segments, cut to spot cones, and the surface normals they end on."""
    cam = prep.scene.camera
    o, d = generate_rays(cam, tile.rows, slice(0, width), tile.samples)
    t, prim = prep.accel.first_hit(o, d)
    n = len(prep.lights)
    segs = whole_rays(o, d, t, np.zeros(len(o), np.uint64), n, 0, prep.accel.scale)
    normals = np.where((prim >= 0)[:, None], prep.accel.normals[np.maximum(prim, 0)], 0.0)
    return cone_segments(segs, prep.lights, np.repeat(normals, n, axis=0))


def lit_length(pieces, n_lights, n):
    return np.bincount(pieces.ray * n_lights + pieces.light, pieces.length, n)


def intervals(prep, bins):
    cam = prep.scene.camera
    n_l = len(prep.lights)
    maps = shadow_maps.build(prep.accel, prep.lights, 0.01)
    t_exact = t_old = t_fine = 0.0
    n_seg = n_fine = differ = differ_fine = 0
    stats = np.zeros(len(STATS_NAMES))
    tol = 1e-6 * prep.accel.scale
    for tile in tiles(cam, (0, 0, cam.width, cam.height)):
        segs, ends = tile_segments(prep, tile, cam.width)
        size = int(segs.ray.max() + 1) * n_l
        start = time.perf_counter()
        exact, st = exact_lit_intervals(prep.accel, segs, prep.lights, n_l, bins)
        t_exact += time.perf_counter() - start
        stats += st
        start = time.perf_counter()
        old, _ = lit_intervals(prep.accel, segs, prep.lights, n_l, 0.01, ends, maps)
        t_old += time.perf_counter() - start
        a, b = lit_length(exact, n_l, size), lit_length(old, n_l, size)
        differ += int(np.sum(np.abs(a - b) > tol))
        pick = np.nonzero((n_seg + np.arange(len(segs))) % SUBSAMPLE == 0)[0]
        n_seg += len(segs)
        if len(pick):
            sub = segs.take(pick)
            start = time.perf_counter()
            fine, _ = lit_intervals(prep.accel, sub, prep.lights, n_l, 1e-4, ends[pick])
            t_fine += time.perf_counter() - start
            ex, _ = exact_lit_intervals(prep.accel, sub, prep.lights, n_l, bins)
            a, b = lit_length(ex, n_l, size), lit_length(fine, n_l, size)
            differ_fine += int(np.sum(np.abs(a - b) > tol))
            n_fine += len(pick)
    us = 1e6 / n_seg
    print("| search | segments | time per segment (us) | total (s) | segments whose lit length differs from "
          "the exact |")
    print("|---|---|---|---|---|")
    print(f"| exact | {n_seg} | {t_exact * us:.2f} | {t_exact:.2f} | - |")
    print(f"| sampled, 0.01 rad | {n_seg} | {t_old * us:.2f} | {t_old:.2f} | {differ / n_seg:.2%} |")
    print(f"| sampled, 1e-4 rad | {n_fine} (every {SUBSAMPLE}th) | {t_fine / max(n_fine, 1) * 1e6:.1f} | "
          f"{t_fine:.2f} (all segments: ~{t_fine / max(n_fine, 1) * n_seg:.0f}) | {differ_fine / max(n_fine, 1):.2%} |")
    print("\nExact intervals, per segment: " + ", ".join(f"{k} {v / n_seg:.2f}" for k, v in zip(STATS_NAMES[1:],
                                                                                            stats[1:])))


def renders(prep, bins, rounds):
    maps = shadow_maps.build(prep.accel, prep.lights, 0.01)

    def sampled(accel, segs, lights, n_lights, _bins):  # the search the renderer used before (no end normals)
        return lit_intervals(accel, segs, lights, n_lights, 0.01, None, maps)

    original = renderer.exact_lit_intervals
    kinds = {"unshadowed": (False, original), "sampled 0.01": (True, sampled), "exact": (True, original)}
    times = {k: [] for k in kinds}
    for r in range(rounds + 1):  # the first round compiles and is not counted
        for name, (vs, fn) in kinds.items():
            renderer.exact_lit_intervals = fn
            try:
                img = raytrace.render(prepared=prep, method="analytic", volumetric_shadows=vs)
            finally:
                renderer.exact_lit_intervals = original
            if r:
                times[name].append(img.seconds)
    base = np.array(times["unshadowed"])
    print("| render | least time (s) | all rounds (s) | ratio to unshadowed: of least times, median of rounds |")
    print("|---|---|---|---|")
    for name, t in times.items():
        t = np.array(t)
        print(f"| {name} | {t.min():.2f} | {' '.join(f'{x:.2f}' for x in t)} | {t.min() / base.min():.2f}x, "
              f"{np.median(t / base):.2f}x |")

def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="256x128, 1 spp")
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    size = ["camera.width=256", "camera.height=128", "camera.spp=1"] if args.quick else []
    try:
        sc = raytrace.load("sibenik", overrides=size)
    except raytrace.UserError as exc:
        sys.exit(f"Sibenik not found ({exc})")
    prep = prepare(sc)
    cam = sc.camera
    print(f"# Exact lit intervals: Sibenik {cam.width}x{cam.height}, {cam.spp} spp, {len(prep.accel.triangles)} "
          "triangles\n")
    build(prep.accel, prep.lights, 16)  # compile
    start = time.perf_counter()
    bins = build(prep.accel, prep.lights)
    took = time.perf_counter() - start
    entries = sum(len(b.tri) for b in bins)
    mem = sum(sum(a.nbytes for a in (b.planes, b.signs, b.start, b.tri, b.lb, b.cover, b.cover_depth)) for b in bins)
    per_tri = entries / len(bins) / len(prep.accel.triangles)
    print(f"Texel lists: resolution {bins[0].res}, built in {took:.2f} s, {per_tri:.1f} entries per triangle and "
          f"light, {mem / 2**20:.0f} MB for {len(bins)} lights.\n")
    exact_lit_intervals(prep.accel, whole_rays(np.zeros((1, 3)), np.array([[1.0, 0, 0]]), np.ones(1),
                                               np.zeros(1, np.uint64), 1), prep.lights, 1, bins)  # compile
    intervals(prep, bins)
    print()
    renders(prep, bins, args.rounds)


if __name__ == "__main__":
    main()
