"""Regenerate tests/data/grazing_twins.json, the exact twin of tests/test_planar_grazing.py's image.

    python -m tests.make_grazing_twins         # about three minutes on one core

The quad light of tests/test_area_lights.py in its isotropic fog, seen by a 6 x 1 camera whose rays
graze its plane (sine about 0.012) and cross it on the quad and beside its edge, and each ray's radiance
by tests/area_twin.py with `exact=True` (the geometry and scipy alone, no project code).
"""
import json
from pathlib import Path

import numpy as np

from . import area_twin as twin
from .test_area_lights import KS, KT, QUAD

OUT = Path(__file__).resolve().parent / "data" / "grazing_twins.json"
CAMERA = {"position": [0.0, 1.47, 2.5], "look_at": [0.45, 1.5, 0.0], "up": [0.0, 1.0, 0.0], "fov": 2.0,
          "width": 6, "height": 1}


def main():
    write(CAMERA, OUT)


def write(camera: dict, path: Path):
    """The exact radiance of each of `camera`'s pixel rays under the quad light in its fog, as JSON at `path`."""
    o = np.array(camera["position"])
    dirs = twin.camera_rays(o, camera["look_at"], camera["up"], camera["fov"], camera["width"], camera["height"])
    em = twin.Quad(QUAD["corners"], QUAD["radiance"], exact=True)
    out = {"camera": camera, "radiance": [[twin.radiance(em, o, d, KT, KS) for d in row] for row in dirs]}
    print(out["radiance"])
    path.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
