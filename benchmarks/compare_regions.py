"""Errors of `compare` images by region of the view: towards or away from the light, and inside or
beyond Sun's table (u = kt h <= u_max).

    python render.py compare scenes/box_room.toml --methods lecocq,sun,analytic --out out/box
    python benchmarks/compare_regions.py scenes/box_room.toml out/box [--set KEY=VALUE ...]

Give compare's `--set` overrides again (the medium sets u).

For a one-light scene at 1 spp: a pixel looks "towards" the light when the light lies ahead of the
camera along its ray (x_h > 0) and within 30° of the ray, "away" when the light is behind the
camera (x_h < 0, Lecocq's theta_a > 0). Prints the mean and max relative error of every image of
the folder in each region.
"""
import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from raytrace.camera import generate_rays  # noqa: E402
from raytrace.output.film import read_exr  # noqa: E402
from raytrace.scene.format import load_scene  # noqa: E402


def main(scene_path, folder, overrides=(), u_max=10.0):
    scene = load_scene(scene_path, overrides)
    cam = scene.camera
    if cam.spp != 1 or len(scene.lights) != 1:
        raise SystemExit("needs a one-light scene rendered at 1 spp")
    ref, _ = read_exr(Path(folder) / "reference.exr")
    cam.height, cam.width = ref.shape[:2]  # the images' size (compare --width/--height)
    o, d = generate_rays(cam)
    rel = scene.lights[0].position - o
    xh = np.einsum("ij,ij->i", rel, d)
    h = np.linalg.norm(np.cross(rel, d), axis=1)
    angle = np.degrees(np.arctan2(h, xh))
    u = h * float(scene.medium.sigma_t.max())
    regions = {"towards the light (< 30°)": angle < 30.0, "away (light behind)": xh < 0.0,
               f"u <= {u_max:g}": u <= u_max, f"u > {u_max:g}": u > u_max}
    print("| image | " + " | ".join(f"{k}: mean / max rel. error" for k in regions) + " |")
    print("|---" * (len(regions) + 1) + "|")
    for path in sorted(Path(folder).glob("*.exr")):
        if path.name == "reference.exr":
            continue
        img, _ = read_exr(path)
        err = (np.abs(img - ref) / np.abs(ref)).mean(axis=2).ravel()
        neg = (img < 0).any(axis=2).ravel()
        cells = []
        for mask in regions.values():
            if mask.any():
                cells.append(f"{err[mask].mean():.2e} / {err[mask].max():.2e}" + (f" ({neg[mask].mean():.0%} neg.)"
                                                                                   if neg[mask].any() else ""))
            else:
                cells.append("–")
        print(f"| {path.stem} | " + " | ".join(cells) + " |")
    print("\npixels per region: " + ", ".join(f"{k}: {int(m.sum())}" for k, m in regions.items()))


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene")
    ap.add_argument("folder")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="the overrides compare was given")
    args = ap.parse_args()
    main(args.scene, args.folder, args.set)
