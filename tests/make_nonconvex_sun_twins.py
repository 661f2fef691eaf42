"""Writes tests/data/nonconvex_sun_twins.json: tests/test_nonconvex_sun.py's twin (`twin_pixel`) on its pixels, with
the sun and camera it was made for. Too slow for CI (about 10 s): run `python -m tests.make_nonconvex_sun_twins`
from the repository root after changing the scene or the pixels."""
import json

from .test_nonconvex_sun import CAMERA, PIXELS, SUN, TWINS, twin_pixel


def main():
    TWINS.write_text(json.dumps({"sun": SUN, "camera": CAMERA,
                                 "twins": [[i, j, list(map(float, twin_pixel(i, j)))] for i, j in PIXELS]}, indent=1))


if __name__ == "__main__":
    main()
