"""A closed non-convex mesh holding a medium: a torus of fog beside a point light, at several
tessellations (trimesh.creation.torus), rendered by quadrature, raymarch and montecarlo on one thread.
Prints each render's time and the inside integrals that stopped short of their tolerance (`inside:
integrals not converged`: a non-convex shape's light paths are traced walks, interiors/paths.py). With
`--ior 1.5` the torus is glass in an absorbing outside (the lamp's light refracted through every face,
media/nonconvex_refraction.py), and quadrature's line adds the lit pixels whose bound is finite and their
median bound over value and rtol.

    python benchmarks/torus.py [--sections 40 250] [--width 48 --height 32] [--rtol 1e-10] [--ior 1.5]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh

from raytrace import api
from raytrace.scene.format import load_scene

SCENE = """
[camera]
position = [0.0, 2.2, 3.2]
look_at = [0.0, 0.0, 0.0]
fov = 45.0
width = {width}
height = {height}

{outside}
[[shape]]
mesh = "torus.obj"
interior = {{ sigma_a = [0.2, 0.25, 0.3], sigma_s = [0.6, 0.5, 0.4], phase = {{ type = "hg", g = 0.3 }}{ior} }}

[[light]]
position = [1.6, 0.9, 0.4]
intensity = 4.0
"""


def torus_scene(folder: Path, sections: int, width: int, height: int, ior: float | None = None):
    """The scene with a torus of major radius 1 and minor radius 0.35, `sections` around its ring and
    4/5 of that around its tube (2 x sections x 4/5 sections triangles); with `ior`, of that index in an
    outside of sigma_a 0.05."""
    mesh = trimesh.creation.torus(1.0, 0.35, major_sections=sections, minor_sections=max(3, 4 * sections // 5))
    mesh.export(folder / "torus.obj")
    glass = ior is not None
    (folder / "torus.toml").write_text(SCENE.format(width=width, height=height, ior=f", ior = {ior}" if glass else "",
                                                    outside="[medium]\nsigma_a = 0.05\n" if glass else ""))
    return load_scene(folder / "torus.toml"), len(mesh.faces)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sections", type=int, nargs="+", default=[40, 250])
    ap.add_argument("--width", type=int, default=48)
    ap.add_argument("--height", type=int, default=32)
    ap.add_argument("--rtol", type=float, default=1e-10)
    ap.add_argument("--ior", type=float, default=None)
    args = ap.parse_args()
    methods = {"quadrature": {"rtol": args.rtol}, "raymarch": {"steps": 64}, "montecarlo": {"samples": 64}}
    print("| triangles | method | time (s) | inside: integrals not converged |")
    print("|---:|---|---:|---:|")
    for sections in args.sections:
        with tempfile.TemporaryDirectory() as tmp:
            scene, triangles = torus_scene(Path(tmp), sections, args.width, args.height, args.ior)
            for method, params in methods.items():
                api.render(scene, method, threads=1, width=8, height=6, **params)  # compile and load once
                start = time.perf_counter()
                img = api.render(scene, method, threads=1, **params)
                took = time.perf_counter() - start
                print(f"| {triangles:,} | {method} | {took:.2f} | "
                      f"{img.stats.get('inside: integrals not converged', 0):,.0f} |{_bounded(img, args, method)}", flush=True)


def _bounded(img, args, method):
    """With --ior, quadrature's lit pixels with a finite bound and their median bound / value / rtol."""
    if args.ior is None or method != "quadrature":
        return ""
    lit = np.all(img.array > 0.0, axis=2)
    ok = lit & np.all(np.isfinite(img.error_bound), axis=2)
    median = np.median(img.error_bound[ok] / img.array[ok]) / args.rtol if ok.any() else np.inf
    return f" bound finite on {ok.sum()} of {lit.sum()} lit pixels, median {median:.2f} rtol |"


if __name__ == "__main__":
    main()
