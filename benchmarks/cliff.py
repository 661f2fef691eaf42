"""The cost of volumetric shadows around a sphere that holds a medium, in fog, under a point light
(benchmarks/sphere_in_fog.toml, after Houdini's pbrt-v4 exporter test
TestMediums/test_exterior_cam_interior_obj_pointlight): each method, with and without volumetric
shadows, one thread, CPU seconds of the process (`time.process_time`), best of `--rounds`
interleaved runs (compile excluded), for the file's 32-segment mesh and for the exact sphere
(`exact = true`, as the pbrt importer reads Houdini's sphere). A method that refuses the scene is
listed with its one-line reason.

    python benchmarks/cliff.py [--rounds 3] [--width 64 --height 48]
"""
import argparse
import pathlib
import time

import raytrace
from raytrace.errors import UserError

SCENE = pathlib.Path(__file__).with_name("sphere_in_fog.toml")
METHODS = ("analytic", "quadrature", "raymarch", "montecarlo", "slab_approx")
SPHERES = {"mesh": (), "exact": ("shape[1].exact=true",)}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--width", type=int, default=64)
    ap.add_argument("--height", type=int, default=48)
    args = ap.parse_args()
    print("| sphere | method | unshadowed | volumetric shadows | ratio |")
    print("|---|---|---|---|---|")
    for sphere, overrides in SPHERES.items():
        for method in METHODS:
            best = {}
            try:
                for _ in range(args.rounds + 1):  # the first round compiles
                    for shadows in (False, True):
                        start = time.process_time()
                        raytrace.render(str(SCENE), method=method, volumetric_shadows=shadows, threads=1,
                                        width=args.width, height=args.height, overrides=overrides)
                        best.setdefault(shadows, []).append(time.process_time() - start)
            except UserError as e:
                print(f"| {sphere} | {method} | refused: {str(e).split(': ', 1)[-1]} | | |")
                continue
            off, on = (min(best[s][1:]) for s in (False, True))
            print(f"| {sphere} | {method} | {off:.2f} s | {on:.2f} s | {on / off:.1f} |")


if __name__ == "__main__":
    main()
