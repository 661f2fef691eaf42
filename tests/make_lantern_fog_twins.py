"""Writes tests/data/lantern_fog_twins.json: tests/test_lantern_fog.py's twin air-light (`fog_pixel`, scipy quad_vec
at epsrel 1e-10 over 30-digit refraction points, cut where they cross the faces' edges and a spot's cone levels) on
the chosen pixels of the lamp (tests/test_lantern_fog.py `PIXELS`) and of the smooth and hard-edged spots
(tests/test_lantern_fog_spot.py `PIXELS`). Too slow for CI (about 50 CPU s, 3 to 6 s a pixel): run
`python -m tests.make_lantern_fog_twins` from the repository root after changing the lantern, the lights, the fog
or the pixels; the tests recompute one pixel of each file live."""
import json
import pathlib

from . import test_lantern_fog as lamp
from . import test_lantern_fog_spot as spot
from .test_lamp_in_glass import LAMP

OUT = pathlib.Path(__file__).with_name("data") / "lantern_fog_twins.json"
LIGHTS = {"lamp": (LAMP, lamp.PIXELS), "spot": (spot.SIDE, spot.PIXELS), "hard": (spot.HARD, spot.PIXELS)}


def main():
    OUT.write_text(json.dumps({name: {"pixels": pixels, "air": [list(map(float, lamp.fog_pixel(light, j, i, 1e-10)))
                                                                for j, i in pixels]}
                               for name, (light, pixels) in LIGHTS.items()}, indent=1))


if __name__ == "__main__":
    main()
