"""Regenerate tests/data/near_emitter_twins.json, the exact twins of tests/test_near_emitters.py.

    python -m tests.make_near_twins            # a few minutes on one core

Per case: a flat emitter (a quad or a disk of tests/test_area_lights.py) in its isotropic fog, seen from
below by a 4 x 3 camera whose rays end on it or pass beside its edges, and each ray's radiance by
tests/area_twin.py with `exact=True` (polar about each point's foot on the plane: the geometry and
scipy alone, no project code).
"""
import json
from pathlib import Path

import numpy as np

from . import area_twin as twin
from .test_area_lights import DISK, FOG, KS, KT, QUAD

OUT = Path(__file__).resolve().parent / "data" / "near_emitter_twins.json"
CAMERA = {"position": [0.25, 0.6, 0.15], "look_at": [0.15, 1.5, 0.3], "up": [0.0, 0.0, -1.0], "fov": 60.0,
          "width": 4, "height": 3}
CASES = {"quad": (QUAD, lambda: twin.Quad(QUAD["corners"], 10.0, exact=True)),
         "disk": (DISK, lambda: twin.Disk(DISK["center"], DISK["normal"], 0.5, 10.0, exact=True))}


def main():
    o = np.array(CAMERA["position"])
    dirs = twin.camera_rays(o, CAMERA["look_at"], CAMERA["up"], CAMERA["fov"], CAMERA["width"], CAMERA["height"])
    out = {}
    for name, (light, make) in CASES.items():
        em = make()
        out[name] = {"light": light, "medium": FOG, "camera": CAMERA,
                     "radiance": [[twin.radiance(em, o, d, KT, KS) for d in row] for row in dirs]}
        print(name, out[name]["radiance"])
    OUT.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
