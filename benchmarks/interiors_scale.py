"""Media inside finely tessellated shapes: load and render time and peak memory against triangle count.

    python benchmarks/interiors_scale.py [--segments 32 100 320] [--width 12 --height 8] [--repeat 5]
    python benchmarks/interiors_scale.py --blender 4 7        # Blender's icospheres (1,280 and 81,920 triangles)

A sphere primitive of radius 1 holding a scattering medium, 2 x segments x (segments / 2 - 1)
triangles (32, 100, 320 segments: about 1k, 10k and 100k), a point light beside it, the camera
outside in a thin absorbing medium, one thread. `load` is `renderer.prepare` plus the convexity
check of the interior (scene/meshes.py convex_planes, Qhull and a k-d tree) with its peak of traced
allocations (tracemalloc: numpy's arrays included); `render` is the median over `--repeat` renders
of the timed part of `renderer.render` (compilation excluded) for `quadrature` (adaptive to its
rtol from the pieces of the facet walk, so its evaluations grow with the kinks of the integrand,
one wherever the light path's exit crosses a face edge), `raymarch` (64 steps) and `montecarlo`
(64 samples), whose evaluations are fixed; `evals` counts the points where a light path's exit is
measured (on the walk's facet planes, or by Embree, batched). The last column is the peak resident
memory of the process.
With `--blender LEVELS`, the shapes are instead unit icospheres made by Blender itself
(tests/data/blender/make_icospheres.py, run headless; Blender's level n has 20 * 4^(n - 1) triangles),
read as PLY meshes.
"""
import argparse
import resource
import statistics
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from raytrace.interiors import paths  # noqa: E402
from raytrace.interiors.shapes import convex_planes, hull_planes  # noqa: E402
from raytrace.options import RenderOptions  # noqa: E402
from raytrace.rendering.renderer import prepare, render  # noqa: E402
from raytrace.scene.format import scene_from_text  # noqa: E402

SCENE = """
[camera]
position = [0.0, 0.5, 3.0]
look_at = [0.0, 0.0, 0.0]
fov = 40.0
width = {width}
height = {height}
spp = 1
[medium]
sigma_a = 0.02
[[shape]]
primitive = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
segments = {segments}
{mesh}[shape.interior]
sigma_a = [0.3, 0.2, 0.1]
sigma_s = [0.5, 0.4, 0.3]
[[light]]
type = "point"
position = [2.0, 2.0, 1.0]
intensity = 5.0
"""
METHODS = {"quadrature": {}, "raymarch": {"steps": 64}, "montecarlo": {"samples": 64}}


def counted_exits():
    """Wrap paths._geometry to count the points where a light path's exit is measured."""
    count = [0]
    geometry = paths._geometry

    def wrapped(prep, sid, geo, directional, seg, x, *rest):
        count[0] += len(x)
        return geometry(prep, sid, geo, directional, seg, x, *rest)
    paths._geometry = wrapped
    return count


def shapes(args, folder):
    """(label, the [[shape]] lines that differ) for each sphere of the run."""
    if not args.blender:
        return [(seg, "") for seg in args.segments]
    maker = Path(__file__).resolve().parents[1] / "tests" / "data" / "blender" / "make_icospheres.py"
    subprocess.run(["blender", "-b", "--factory-startup", "--python", str(maker), "--", folder,
                    *map(str, args.blender)], check=True, capture_output=True)
    return [(0, f'mesh = "{folder}/icosphere_{level}.ply"\n') for level in args.blender]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--segments", type=int, nargs="+", default=[32, 100, 320])
    ap.add_argument("--width", type=int, default=12)
    ap.add_argument("--height", type=int, default=8)
    ap.add_argument("--repeat", type=int, default=5, help="renders per method; the median is printed")
    ap.add_argument("--blender", type=int, nargs="+", metavar="LEVEL",
                    help="Blender's icospheres of these subdivision levels instead of sphere primitives")
    args = ap.parse_args()
    folder = tempfile.mkdtemp()
    count = counted_exits()
    print("| triangles | load s | load peak MB | convex | method | render s | evals |")
    print("|---:|---:|---:|---|---|---:|---:|")
    for seg, mesh in shapes(args, folder):
        text = SCENE.format(width=args.width, height=args.height, segments=seg, mesh=mesh)
        if mesh:  # a mesh file instead of the primitive
            text = text.replace('primitive = "sphere"\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nsegments = 0\n', "")
        tracemalloc.start()
        t0 = time.perf_counter()
        prep = prepare(scene_from_text(text, "interiors_scale"))
        convex = hull_planes(prep, 0) is not None
        load = time.perf_counter() - t0
        peak = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
        kernel = "kernel" if len(convex_planes(prep, 0)) else "Embree"
        for name, params in METHODS.items():
            seconds = []
            for _ in range(args.repeat):
                count[0] = 0
                seconds.append(render(prep, name, params, RenderOptions(threads=1)).seconds)
            print(f"| {len(prep.accel.triangles)} | {load:.2f} | {peak:.0f} | {convex} ({kernel}) | {name} | "
                  f"{statistics.median(seconds):.3f} | {count[0]} |", flush=True)
    print(f"peak resident memory: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")


if __name__ == "__main__":
    main()
