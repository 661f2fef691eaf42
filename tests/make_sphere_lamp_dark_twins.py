"""Writes tests/data/sphere_lamp_dark_twins.json: tests/test_sphere_lamp_dark.py's twin (`twin`: each pixel's fog lit
by the lamp's cap above the floor, scipy quad to 1e-8 over the cap's Gauss-Legendre nodes), its 8 x 6 pixels. Too
slow for CI (about 30 CPU s): run `python -m tests.make_sphere_lamp_dark_twins` from the repository root after
changing the lamp, the fog, the camera or the nodes; the test recomputes one pixel live."""
import json

from .test_sphere_lamp_dark import TWINS, twin


def main():
    TWINS.write_text(json.dumps({"twin": twin().tolist()}, indent=1))


if __name__ == "__main__":
    main()
