"""An index-matched bounded medium against Mitsuba 3 `volpath`: single scattering inside a
box seen and lit through its top face.

    pip install -e '.[bench]'   # mitsuba; exits 0 with a skip message without it
    python benchmarks/bounded_vs_mitsuba.py [--spp 4096] [--depth 2]

Scenes (`--scene`): `top`, a box [-2, -1, -2] x [2, 0, 2] holding a grey medium (ior 1: Mitsuba's
`null` BSDF on a `cube` with a `homogeneous` interior), a point light above the top face within its
footprint and a camera looking down at the top face, so that every camera ray enters through the top
and every straight path from inside to the light leaves through it (the slab note's planar boundary is
the exact geometry); `beside`, a unit cube seen on three faces and lit from beside, where the light's
paths leave through any face (our convex shapes' exact straight paths). Mitsuba traces the actual box. Vacuum outside, black background, no other
surfaces. Mitsuba: `scalar_rgb`, volpath with max_depth = 2 (null-surface crossings do not count:
single scattering with next-event estimation), its box pixel filter. Ours: `quadrature` with a
stratified 8 x 8 grid per pixel (the pixel average, as Mitsuba's box filter). Printed: the mean
ratio Mitsuba / ours over pixels with its standard error from the spread of 4 independent
Mitsuba runs, and the per-pixel z-scores' mean square (the standard error from 4 runs: a t variable
with 3 degrees of freedom, whose square has mean 3 for an unbiased match).

Measured (2 cores, shared), 4096 spp x 4 runs: `top` total ratio 1.00039 +- 0.00080 (per pixel
median 1.0002, mean squared z 2.7, expected 3); `beside` 1.00065 +- 0.00103 (median 1.0006, mean
squared z 2.8), where the slab note's entry-plane model is more than 5 % off (tests/test_bounded_media.py).
`u`: a U-shaped prism (an OBJ written to a temporary folder; non-convex, light paths leave one arm and
enter the other, Embree-traced) over a grey floor lit through it: total ratio 0.99989 +- 0.00021,
per-pixel median 1.0000 (5-95 % 0.985 .. 1.012), per-pixel z^2 median 0.65 (0.59 expected) but mean
16.6: the floor's far edge (partly covered pixels: our 64 stratified samples; ours moves 7 % from 256
to 1024 samples there) and two floor pixels lit through the U where Mitsuba is 0.5 % and 2 % darker
while ours equals a 48 x 48-sample pixel average of the analytic twin (tests/test_inside_paths.py's
slab lengths) to 1e-6 and Mitsuba's own ray intersections find the same crossings: not explained.
With max_depth = 3 the `top` ratio is 1.269 (double scattering), so max_depth = 2 is single
scattering through the null boundary.
"""
from __future__ import annotations

import argparse
import importlib.util
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

KA, KS = 0.3, 0.5
INTENSITY = 3.0
# "top": a wide box seen and lit through its top face (the slab note's planar boundary is exact);
# "beside": a unit cube seen on three faces, lit from beside (light paths leave through any face:
# our convex shapes' exact straight paths)
SCENES = {
    "top": {"box": ([-2.0, -1.0, -2.0], [2.0, 0.0, 2.0]), "light": [0.3, 1.0, 0.2],
            "cam": {"position": [0.2, 3.0, 0.4], "look_at": [0.0, 0.0, 0.0], "fov": 30.0, "width": 24, "height": 16}},
    "beside": {"box": ([-0.5, -1.0, -0.5], [0.5, 0.0, 0.5]), "light": [1.2, -0.3, 0.4],
               "cam": {"position": [1.0, 0.8, 1.8], "look_at": [0.0, -0.5, 0.0], "fov": 40.0, "width": 24,
                       "height": 16}},
    # a U-shaped prism (non-convex: light paths leave one arm and enter the other, Embree-traced) over
    # a grey floor lit through it (shadows through the medium)
    "u": {"mesh": True, "light": [1.6, 0.25, 0.1],
          "cam": {"position": [0.3, 1.4, 3.0], "look_at": [0.0, -0.6, 0.0], "fov": 50.0, "width": 24, "height": 16}},
}
FLOOR_Y, FLOOR_RHO = -1.5, 0.6
# the U's outline in the xy-plane, counter-clockwise, extruded over z in [-0.5, 0.5]; its caps' triangles
U_OUTLINE = [(-1, -1), (1, -1), (1, -0.5), (1, 0.5), (0.4, 0.5), (0.4, -0.5), (-0.4, -0.5), (-0.4, 0.5), (-1, 0.5),
             (-1, -0.5)]
U_CAP = [(0, 1, 2), (0, 2, 5), (0, 5, 6), (0, 6, 9), (9, 6, 7), (9, 7, 8), (2, 3, 4), (2, 4, 5)]


def write_u(path):
    """The U as a closed OBJ with outward faces (Mitsuba puts the interior behind the normals)."""
    m = len(U_OUTLINE)
    lines = [f"v {x} {y} {z}" for z in (-0.5, 0.5) for x, y in U_OUTLINE]
    lines += [f"f {a + 1} {c + 1} {b + 1}" for a, b, c in U_CAP] + [f"f {a + m + 1} {b + m + 1} {c + m + 1}"
                                                                     for a, b, c in U_CAP]
    for i in range(m):
        j = (i + 1) % m
        lines += [f"f {i + 1} {j + 1} {j + m + 1}", f"f {i + 1} {j + m + 1} {i + m + 1}"]
    path.write_text("\n".join(lines) + "\n")


def ours(sc, folder, spp_side=8):
    from raytrace.rendering.renderer import prepare, render
    from raytrace.scene.format import scene_from_dict

    inner = {"interior": {"sigma_a": KA, "sigma_s": KS}}
    if sc.get("mesh"):
        shapes = [{"mesh": str(folder / "u.obj"), **inner},
                  {"primitive": "quad", "reflectance": FLOOR_RHO,
                   "corners": [[-9.0, FLOOR_Y, -9.0], [9.0, FLOOR_Y, -9.0], [9.0, FLOOR_Y, 9.0], [-9.0, FLOOR_Y, 9.0]]}]
    else:
        shapes = [{"primitive": "box", "min": sc["box"][0], "max": sc["box"][1], **inner}]
    scene = {"camera": {**sc["cam"], "spp": spp_side * spp_side}, "shape": shapes,
             "light": [{"type": "point", "position": sc["light"], "intensity": INTENSITY}]}
    res = render(prepare(scene_from_dict(scene, "bounded_vs_mitsuba")), "quadrature", {"rtol": 1e-6})
    return res.image, res.seconds


def mitsuba_image(sc, folder, spp, seed, depth):
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    T = mi.ScalarTransform4f
    CAM = sc["cam"]
    interior = {"type": "homogeneous", "sigma_t": KA + KS, "albedo": KS / (KA + KS), "phase": {"type": "isotropic"}}
    if sc.get("mesh"):
        shapes = {"u": {"type": "obj", "filename": str(folder / "u.obj"), "face_normals": True,
                        "bsdf": {"type": "null"}, "interior": interior},
                  "floor": {"type": "rectangle", "to_world": T().translate([0.0, FLOOR_Y, 0.0]).rotate([1, 0, 0], -90)
                            .scale(9.0), "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb",
                                                                                     "value": [FLOOR_RHO] * 3}}}}
    else:
        lo, hi = np.array(sc["box"][0]), np.array(sc["box"][1])
        shapes = {"box": {"type": "cube", "to_world": T().translate(((lo + hi) / 2).tolist())
                          .scale(((hi - lo) / 2).tolist()), "bsdf": {"type": "null"}, "interior": interior}}
    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "volpath", "max_depth": depth},
        "sensor": {"type": "perspective", "fov": CAM["fov"], "fov_axis": "y",
                   "to_world": T().look_at(origin=CAM["position"], target=CAM["look_at"], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": CAM["width"], "height": CAM["height"], "rfilter": {"type": "box"},
                            "pixel_format": "rgb"},
                   "sampler": {"type": "independent", "sample_count": spp, "seed": seed}},
        **shapes,
        "light": {"type": "point", "position": sc["light"], "intensity": {"type": "rgb", "value": [INTENSITY] * 3}},
    })
    return np.array(mi.render(scene, spp=spp, seed=seed))[:, :, :3]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spp", type=int, default=4096)
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--depth", type=int, default=2)
    ap.add_argument("--scene", choices=tuple(SCENES), default="top")
    args = ap.parse_args(argv)
    if importlib.util.find_spec("mitsuba") is None:
        print("mitsuba is not installed (pip install -e '.[bench]'): skipped")
        return 0
    sc = SCENES[args.scene]
    folder = Path(tempfile.mkdtemp())
    write_u(folder / "u.obj")
    ref, ours_s = ours(sc, folder)
    start = time.perf_counter()
    runs = np.array([mitsuba_image(sc, folder, args.spp, seed, args.depth) for seed in range(args.runs)])
    mi_s = (time.perf_counter() - start) / args.runs
    mean = runs.mean(axis=0)
    sem = runs.std(axis=0, ddof=1) / np.sqrt(args.runs)
    ours_sum, mi_sum = ref.sum(axis=2), mean.sum(axis=2)
    with np.errstate(divide="ignore", invalid="ignore"):  # pixels off the box: 0 / 0
        ratio = mi_sum / ours_sum
    lit = ours_sum > 1e-3 * ours_sum.max()
    per_run = runs.sum(axis=3)[:, lit].sum(axis=1) / ours_sum[lit].sum()
    print(f"scene {args.scene}: pixels {int(lit.sum())}, Mitsuba volpath max_depth={args.depth} {args.spp} spp x {args.runs} runs "
          f"({mi_s:.1f} s per run, scalar_rgb), ours quadrature 64 spp ({ours_s:.2f} s)")
    print(f"total ratio Mitsuba / ours: {per_run.mean():.5f} +- {per_run.std(ddof=1) / np.sqrt(args.runs):.5f} "
          f"(runs {np.round(per_run, 5).tolist()})")
    print(f"per-pixel ratio: median {np.median(ratio[lit]):.4f}, 5-95 % {np.percentile(ratio[lit], 5):.4f} .. "
          f"{np.percentile(ratio[lit], 95):.4f}")
    z = (mean - ref)[lit] / np.maximum(sem[lit], 1e-300)
    print(f"mean squared z-score per pixel-channel (sem from the runs): {np.mean(z ** 2):.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
