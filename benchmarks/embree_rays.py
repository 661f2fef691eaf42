"""Embree throughput on the Sibenik cathedral: first-hit and shadow rays per second, 1 and all threads.

    RAYTRACE_ASSETS=../shared/scenes python benchmarks/embree_rays.py [--rays N]

First-hit rays are the camera rays of an environment camera in the nave (coherent, as in the
paper's fig. 3) and random directions (incoherent); shadow rays go from the first-hit points to a
light. Times are medians of 3 runs, measured through `raytrace.geometry.accel.Accelerator`, so they include
the float64 refinement of hit distances.
"""
import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from raytrace.geometry.accel import Accelerator  # noqa: E402
from raytrace.camera import generate_rays  # noqa: E402
from raytrace.media import Homogeneous  # noqa: E402
from raytrace.rendering.renderer import default_threads  # noqa: E402
from raytrace.scene.format import Camera  # noqa: E402
from raytrace.scene.meshes import load_mesh  # noqa: E402
from raytrace.scene.format import Shape, Transform, Scene  # noqa: E402


def median_time(fn, repeats=3):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rays", type=int, default=2_000_000)
    args = ap.parse_args()
    cam = Camera("environment", np.array([-8.0, -10.0, 0.0]), np.array([10.0, -9.0, 0.0]), np.array([0.0, 1.0, 0.0]),
                 60.0, 2048, max(1, args.rays // 2048), 1)
    shape = Shape("mesh", {"mesh": "sibenik/sibenik.obj"}, None, Transform(np.ones(3), np.zeros(3), np.zeros(3)))
    scene = Scene("sibenik", None, cam, [shape], [], Homogeneous.vacuum(), np.zeros(3))
    tris, _ = load_mesh(shape, scene, "shape[0]")
    light = np.array([0.0, -5.0, 0.0])
    accel = Accelerator(tris, light[None, :])
    o, d = generate_rays(cam)
    rng = np.random.default_rng(1)
    d_rand = rng.normal(size=d.shape)
    d_rand /= np.linalg.norm(d_rand, axis=1)[:, None]
    t, prim = accel.first_hit(o, d)
    hit = prim >= 0
    pts = o[hit] + t[hit, None] * d[hit]
    so, sd, stmax, _ = accel.shadow_rays(pts, accel.normals[prim[hit]], light)
    n = len(o)
    print(f"Sibenik: {len(tris)} triangles, {n} rays per batch, {os.cpu_count()} CPUs")
    print(f"{'query':34s} {'threads':>7s} {'Mrays/s':>9s}")
    for threads in sorted({1, default_threads()}):
        for label, fn, count in [
            ("first hit, camera rays (coherent)", lambda: accel.first_hit(o, d, threads), n),
            ("first hit, random directions", lambda: accel.first_hit(o, d_rand, threads), n),
            ("shadow rays to a light", lambda: accel.occluded(so, sd, stmax, threads), len(so)),
        ]:
            fn()
            print(f"{label:34s} {threads:7d} {count / median_time(fn) / 1e6:9.2f}")


if __name__ == "__main__":
    main()
