"""Point, spot and directional renders against another checkout: CPU seconds, paired, in turns.

    python benchmarks/light_kinds_speed.py --before DIR [--tree .] [--rounds 3] [--repeat 2] [--smooth]

Area and environment lights came in behind one light interface; the scenes lit by point, spot and
directional lights must not pay for them. DIR is another checkout (for example
`git archive 9596215 | tar -x -C DIR`, the tree before the lights' interface); both trees render DIR's
bundled scene files (box_room's point lamp, stage's spots, ocean's and valley_fog's sun), so that
scenes edited since then do not count, and the present tree renders them with flat shading (every shape's
`smooth = false`; `--smooth` keeps its default, the interpolated normals of curved primitives, which
change the images there), so that the images are comparable bit for bit. Each round runs one
process per tree, the trees taking turns; a process renders every case once (the compile, or the
kernels loaded from that tree's own cache) and then `--repeat` times, keeping its least CPU time
(`time.process_time`, one render thread, volumetric shadows as the scene says). The table gives each
case's median over the rounds, per tree, and their ratio. Images are compared too: the largest
relative difference between the trees' images (0 where they are equal bit for bit).
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

# (name, scene of DIR's scenes/, method, width): a point lamp, spots, the sun
CASES = [("box_room, a point lamp", "box_room", "analytic", 160),
         ("box_room, a point lamp", "box_room", "quadrature", 160),
         ("stage, 3 spots", "stage", "analytic", 160), ("stage, 3 spots", "stage", "quadrature", 160),
         ("ocean, directional", "ocean", "quadrature", 160),
         ("valley_fog, directional in height fog", "valley_fog", "quadrature", 96)]


def child(scenes: Path, repeat: int, out: Path, flat_shading: bool) -> None:
    """In this process (raytrace imported from PYTHONPATH's tree): each case's least CPU time and its image,
    the scene files read from `scenes` (DIR's, the same files for both trees), with `flat_shading` every
    shape's `smooth = false` (the shading of a tree from before smooth shading)."""
    import tomllib

    from raytrace import api

    times, images = [], {}
    for k, (_, scene, method, width) in enumerate(CASES):
        path = str(scenes / f"{scene}.toml")
        shapes = len(tomllib.loads(Path(path).read_text()).get("shape", []))
        flat = tuple(f"shape[{i}].smooth=false" for i in range(shapes)) if flat_shading else ()
        api.render(path, method, width=width, threads=1, overrides=flat)  # compile or load the kernels
        best = np.inf
        for _ in range(repeat):
            start = time.process_time()
            img = api.render(path, method, width=width, threads=1, overrides=flat)
            best = min(best, time.process_time() - start)
        times.append(best)
        images[f"case{k}"] = np.asarray(img.array, dtype=np.float64)
    np.savez(out, **images)
    print(json.dumps(times))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", type=Path, required=True)
    ap.add_argument("--tree", type=Path, default=Path(__file__).resolve().parents[1])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--smooth", action="store_true", help="the tree's default smooth shading (images then differ "
                    "from a tree before it on curved primitives)")
    ap.add_argument("--child", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("--flat", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--out", type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        return child(args.child, args.repeat, args.out, args.flat)
    trees = {"before": args.before.resolve(), "now": args.tree.resolve()}
    runs = {name: [] for name in trees}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.rounds):
            for name, tree in trees.items():
                env = dict(os.environ, PYTHONPATH=str(tree), RAYTRACE_CACHE=str(Path(tmp) / f"cache_{name}"))
                proc = subprocess.run([sys.executable, __file__, "--before", str(tree), "--child",
                                       str(trees["before"] / "scenes"),
                                       "--repeat", str(args.repeat), "--out", str(Path(tmp) / f"{name}.npz")]
                                      + (["--flat"] if name == "now" and not args.smooth else []),
                                      env=env, capture_output=True, text=True, check=True, cwd=tree)
                runs[name].append(json.loads(proc.stdout.strip().splitlines()[-1]))
        images = {name: np.load(Path(tmp) / f"{name}.npz") for name in trees}
        print(f"CPU s a render (median of {args.rounds} rounds, each the least of {args.repeat}); "
              f"before = {trees['before']}, now = {trees['now']}")
        print("| case | method | width | before | now | now / before | max relative image difference |")
        print("|---|---|---|---|---|---|---|")
        for k, (label, _, method, width) in enumerate(CASES):
            b, n = (float(np.median([r[k] for r in runs[name]])) for name in trees)
            a, c = images["before"][f"case{k}"], images["now"][f"case{k}"]
            diff = float(np.max(np.abs(c - a) / np.maximum(np.abs(a), 1e-300))) if a.shape == c.shape else np.nan
            print(f"| {label} | {method} | {width} | {b:.3f} | {n:.3f} | {n / b:.3f} | {diff:.2e} |")


if __name__ == "__main__":
    main()
