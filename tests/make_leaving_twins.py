"""Writes tests/data/leaving_twins.json: tests/test_leaving_bounds.py's twin (tests/test_lantern_fog.py `airlight`,
scipy quad_vec at epsrel 1e-12 between the twin's own breaks) on its fog segments, for each of its lights. Too slow
for CI (minutes a light): run `python -m tests.make_leaving_twins` from the repository root after changing the
segments or the lights."""
import json
import pathlib

from .test_leaving_bounds import LIGHTS, SEGMENTS
from .test_lantern_fog import airlight

OUT = pathlib.Path(__file__).with_name("data") / "leaving_twins.json"


def main():
    twins = {name: [list(map(float, airlight(light, o, d, t, 1e-12))) for o, d, t in SEGMENTS]
             for name, light in LIGHTS.items()}
    OUT.write_text(json.dumps({"segments": [[list(map(float, o)), list(map(float, d)), float(t)]
                                            for o, d, t in SEGMENTS], "twins": twins}, indent=1))


if __name__ == "__main__":
    main()
