"""Regenerate tests/data/passing_twins.json, the exact twin of tests/test_passing_rays.py's image.

    python -m tests.make_passing_twins         # a few minutes on one core

The quad light of tests/test_area_lights.py in its isotropic fog, seen by a 1 x 12 camera 0.12 below its
plane whose rays pass under it without crossing its plane (0.09 to 0.4 of its diameter from it), and
each ray's radiance by tests/area_twin.py with `exact=True` (the geometry and scipy alone, no project code).
"""
from pathlib import Path

from .make_grazing_twins import write

OUT = Path(__file__).resolve().parent / "data" / "passing_twins.json"
CAMERA = {"position": [0.1, 1.38, 2.5], "look_at": [0.1, 1.0951, 0.0], "up": [0.0, 1.0, 0.0], "fov": 14.0,
          "width": 1, "height": 12}


def main():
    write(CAMERA, OUT)


if __name__ == "__main__":
    main()
