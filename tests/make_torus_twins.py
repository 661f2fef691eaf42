"""Writes tests/data/torus_twins.json: pixels of the glass torus of benchmarks/torus.py (12 sections around its
ring, 9 around its tube: 216 triangles; ior 1.5 holding a fog, an absorbing outside, the lamp beside it) at 12 x 9,
by the twin of tests/refraction_twin.py from the OBJ's triangles alone (no renderer code), about 20 s a pixel.

    python -m tests.make_torus_twins
"""
from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh

from . import oracle
from .refraction_twin import Glass, obj_triangles

SECTIONS, MINOR = 12, 9  # trimesh.creation.torus(1.0, 0.35, 12, 9), as benchmarks/torus.py `torus_scene(..., 12, ...)`
CAMERA = {"position": [0.0, 2.2, 3.2], "look_at": [0.0, 0.0, 0.0], "fov": 45.0, "width": 12, "height": 9}
LAMP = {"type": "point", "position": [1.6, 0.9, 0.4], "intensity": 4.0}
KA, KS, G, KT_OUT, ETA = [0.2, 0.25, 0.3], [0.6, 0.5, 0.4], 0.3, 0.05, 1.5
# lit pixels across the ring (the two whose bound was inf at rtol 1e-6 included: (4, 2), (8, 5)) and two whose
# camera rays cross the glass where no path lights them
PIXELS = [(4, 1), (6, 1), (7, 1), (3, 2), (4, 2), (7, 2), (2, 3), (8, 3), (3, 4), (9, 4), (3, 5), (8, 5), (5, 6),
          (4, 5), (8, 6)]
PATH = Path(__file__).parent / "data" / "torus_twins.json"


def glass() -> Glass:
    """The twin's torus, from the OBJ trimesh writes (the file the scene loads)."""
    with tempfile.TemporaryDirectory() as tmp:
        trimesh.creation.torus(1.0, 0.35, major_sections=SECTIONS, minor_sections=MINOR).export(Path(tmp) / "t.obj")
        tris = obj_triangles((Path(tmp) / "t.obj").read_text())
    return Glass(tris, ETA, np.array(KA), np.array(KS), G, KT_OUT, LAMP)


def pixel(twin: Glass, i: int, j: int):
    """(radiance (3,), cuts) of pixel (i, j)'s centre (`Glass.pixel`)."""
    return twin.pixel(*oracle.camera_ray(CAMERA, i, j))


def main():
    twin = glass()
    out = {"sections": SECTIONS, "width": CAMERA["width"], "height": CAMERA["height"], "pixels": []}
    for i, j in PIXELS:
        start = time.process_time()
        value, cuts = pixel(twin, i, j)
        out["pixels"].append({"i": i, "j": j, "value": [float(v) for v in value], "breaks": len(cuts) - 2})
        print(i, j, value, len(cuts) - 2, f"{time.process_time() - start:.1f} s", flush=True)
    PATH.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
