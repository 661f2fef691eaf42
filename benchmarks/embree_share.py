"""A whole render against Embree alone for the same rays: the bundled Sibenik scene (two point lights,
isotropic dust, `analytic` at its default precision, no volumetric shadows), one thread.

    RAYTRACE_ASSETS=../shared/scenes python benchmarks/embree_share.py [--width 1024 --height 512 --rounds 3]
                                                                       [--stages]

Embree's time is that of the queries a render cannot do without, through
`raytrace.geometry.accel.Accelerator` (so with the float64 refinement of hit distances): every camera
ray's first hit, and from each hit point a shadow ray to each light, in tile-sized batches as the
renderer makes them. The render's time is `api.render` with `threads=1`, after a render that compiles
its kernels. Both are CPU seconds of the process (`time.process_time`: a busy machine inflates them far
less than wall time). Best of `--rounds` for each, taken in turn; the ratio of the two is the figure.

`--stages` then renders once more with the tile's stages timed (thread CPU of each call, inclusive,
summed over the tiles; the timing wrappers add a few microseconds a call): where the render's time
beyond Embree's goes.
"""
import argparse
import collections
import functools
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from raytrace import api  # noqa: E402
from raytrace.camera import generate_rays  # noqa: E402
from raytrace.geometry.accel import CHUNK, Accelerator  # noqa: E402
from raytrace.methods import analytic  # noqa: E402
from raytrace.rendering import renderer  # noqa: E402


def embree_alone(prep, origins, dirs) -> float:
    """Seconds of Embree's queries for the camera rays' first hits and their hit points' shadow rays
    to every light, in batches of CHUNK rays."""
    accel, lights = prep.accel, prep.scene.lights
    spent = 0.0
    for start in range(0, len(origins), CHUNK):
        o, d = origins[start:start + CHUNK], dirs[start:start + CHUNK]
        t0 = time.process_time()
        t, prim = accel.first_hit(o, d)
        spent += time.process_time() - t0
        hit = prim >= 0
        points = o[hit] + t[hit, None] * d[hit]
        for light in lights:
            so, sd, stmax, as32 = accel.shadow_rays(points, accel.normals[prim[hit]], np.asarray(light.position, float))
            t0 = time.process_time()
            accel.occluded(so, sd, stmax, as32=as32)
            spent += time.process_time() - t0
    return spent


# (owner, attribute, label): the stages timed by --stages, each inclusive of those below it in the call tree
STAGES = ((renderer, "render_tile", "tiles"), (renderer, "pixel_rays", "camera rays"),
          (renderer, "shade_rays", "shade_rays"), (Accelerator, "first_hit", "Embree: first hits"),
          (renderer, "surface_radiance", "surface term"), (Accelerator, "occluded", "Embree: shadow rays"),
          (renderer, "airlight", "air-light"), (analytic, "evaluate_deferred", "analytic's kernel"),
          (renderer, "whole_rays", "segments"), (renderer, "sum_samples", "sums of samples"))


def stages(scene, prep) -> dict:
    """Thread CPU seconds of each of STAGES in one render (wrapped for that render only)."""
    spent = collections.Counter()

    def timed(fn, label):
        @functools.wraps(fn)
        def call(*args, **kwargs):
            start = time.thread_time()
            try:
                return fn(*args, **kwargs)
            finally:
                spent[label] += time.thread_time() - start
        return call

    saved = [(owner, name, getattr(owner, name)) for owner, name, _ in STAGES]
    try:
        for (owner, name, label), (_, _, fn) in zip(STAGES, saved):
            setattr(owner, name, timed(fn, label))
        t0 = time.process_time()
        api.render(scene, prepared=prep, threads=1, volumetric_shadows=False)
        spent["render"] = time.process_time() - t0
    finally:
        for owner, name, fn in saved:
            setattr(owner, name, fn)
    return spent


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=1024)
    ap.add_argument("--height", type=int, default=512)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--stages", action="store_true", help="then the CPU seconds of the tile's stages in one render")
    args = ap.parse_args()
    scene = api.load("sibenik", [f"camera.width={args.width}", f"camera.height={args.height}"])
    prep = renderer.prepare(scene)
    api.render(scene, prepared=prep, threads=1, volumetric_shadows=False, crop=(0, 0, 16, 8))  # compiles
    origins, dirs = generate_rays(scene.camera)
    renders, embree = [], []
    for _ in range(args.rounds):
        t0 = time.process_time()
        api.render(scene, prepared=prep, threads=1, volumetric_shadows=False)
        renders.append(time.process_time() - t0)
        embree.append(embree_alone(prep, origins, dirs))
    render, alone = min(renders), min(embree)
    cam = scene.camera
    print(f"Sibenik {cam.width}x{cam.height}, {cam.spp} spp ({len(origins)} camera rays, {len(scene.lights)} lights), "
          f"analytic, unshadowed, one thread, best of {args.rounds}")
    print(f"render {render:.3f} s; Embree alone {alone:.3f} s; render / Embree {render / alone:.2f}x")
    if args.stages:
        spent = stages(scene, prep)
        print(f"stages of one more render ({spent['render']:.3f} s), thread CPU s, inclusive:")
        for _, _, label in STAGES:
            print(f"  {label:22s} {spent[label]:.3f}")


if __name__ == "__main__":
    main()
