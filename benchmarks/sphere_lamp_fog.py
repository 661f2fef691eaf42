"""CPU seconds of fog renders of a floor under a sphere lamp (the lamp above it, or sunk into it), with
volumetric shadows: `quadrature` rtol 1e-6, one thread, the pilot's rows and the statistics printed,
and the pixels whose air-light was sampled (a variance: the lamp's penumbrae and the segments the
occluders' test did not clear). `--walls`: a back and a side wall too, the camera looking up over
them so that the top of the image sees the sky (rays that leave the scene).

    PYTHONPATH=. python benchmarks/sphere_lamp_fog.py [--size 32x24] [--rounds 1] [--plate] [--walls]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from raytrace import api
from raytrace.scene.format import scene_from_text
from tests.conftest import to_toml

FOG = {"sigma_a": [0.05, 0.05, 0.05], "sigma_s": [0.1, 0.1, 0.1]}
FLOOR = {"primitive": "quad", "corners": [[-20.0, 0.0, 20.0], [20.0, 0.0, 20.0], [20.0, 0.0, -20.0],
                                          [-20.0, 0.0, -20.0]], "reflectance": 0.5}
PLATE = {"primitive": "quad", "corners": [[0.19, 0.45, 0.09], [0.31, 0.45, 0.09], [0.31, 0.45, 0.21],
                                          [0.19, 0.45, 0.21]], "reflectance": 0.5}
WALLS = [{"primitive": "quad", "corners": [[-3.0, 0.0, -2.5], [3.0, 0.0, -2.5], [3.0, 2.0, -2.5], [-3.0, 2.0, -2.5]],
          "reflectance": 0.5},
         {"primitive": "quad", "corners": [[-3.0, 0.0, 3.5], [-3.0, 0.0, -2.5], [-3.0, 2.0, -2.5], [-3.0, 2.0, 3.5]],
          "reflectance": 0.5}]


def scene(height: float, width: int, rows: int, plate: bool = False, walls: bool = False):
    lamp = {"type": "sphere", "center": [0.0, height, 0.0], "radius": 0.3, "radiance": 10.0}
    camera = {"position": [0.0, 2.0, 3.0], "look_at": [0.0, 0.0, 0.0], "fov": 50.0, "width": width, "height": rows}
    if walls:
        camera.update(position=[0.5, 1.0, 3.5], look_at=[0.0, 1.4, 0.0], fov=60.0)
    shapes = [FLOOR] + ([PLATE] if plate else []) + (WALLS if walls else [])
    return scene_from_text(to_toml({"camera": camera, "shape": shapes, "light": [lamp], "medium": FOG}), "fog.toml")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--size", default="32x24")
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--plate", action="store_true", help="a small plate under the lamp")
    parser.add_argument("--walls", action="store_true", help="a back and a side wall, the camera seeing the sky")
    parser.add_argument("--save", help="save the images to this .npz")
    args = parser.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    images = {}
    for name, height in (("above", 1.0), ("sunk", 0.2)):
        sc = scene(height, w, h, args.plate, args.walls)
        for _ in range(args.rounds):
            t0 = time.process_time()
            img = api.render(sc, "quadrature", rtol=1e-6, threads=1)
            cpu = time.process_time() - t0
            keep = {k: v for k, v in img.stats.items() if k.startswith("cubature")}
            sampled = int(np.any(img.variance > 0.0, axis=-1).sum())
            print(f"{name}: {cpu:.2f} CPU s (render {img.seconds:.2f} s), {sampled} pixels sampled, {keep}", flush=True)
        images[name], images[name + "_var"] = img.array, img.variance
    if args.save:
        np.savez(args.save, **images)


if __name__ == "__main__":
    main()
