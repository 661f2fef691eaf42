"""The cost of volumetric shadows around a sphere that holds a medium, in fog, under a point light
(benchmarks/sphere_in_fog.toml, after Houdini's pbrt-v4 exporter test
TestMediums/test_exterior_cam_interior_obj_pointlight): each method that takes the scene, with and
without volumetric shadows, one thread, best of `--rounds` interleaved runs (compile excluded).

    python benchmarks/cliff.py [--rounds 3] [--width 64 --height 48]
"""
import argparse
import pathlib

import raytrace

SCENE = pathlib.Path(__file__).with_name("sphere_in_fog.toml")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--width", type=int, default=64)
    ap.add_argument("--height", type=int, default=48)
    args = ap.parse_args()
    print(f"{'method':12s} {'unshadowed':>11s} {'shadowed':>9s} {'ratio':>6s}")
    for method in ("quadrature", "raymarch", "montecarlo", "slab_approx"):
        best = {}
        for _ in range(args.rounds):
            for shadows in (False, True):
                img = raytrace.render(str(SCENE), method=method, volumetric_shadows=shadows, threads=1,
                                      width=args.width, height=args.height)
                best[shadows] = min(best.get(shadows, float("inf")), img.seconds)
        print(f"{method:12s} {best[False]:10.2f}s {best[True]:8.2f}s {best[True] / best[False]:6.1f}")


if __name__ == "__main__":
    main()
