"""Writes tests/data/globe_twins.json: tests/test_globe_bounds.py's twin (tests/test_globe_fog.py `airlight`, scipy
quad_vec at epsrel 1e-12 over 30-digit paths out, cut where a spot's leaving cosine crosses its band edges:
`band_cuts`, stored too) on its fog segments, for each of its lights. Too slow for CI (about 70 CPU s: the lamp
32, the spot 39): run `python -m tests.make_globe_twins` from the repository root after changing the segments or
the lights."""
import json
import pathlib
import sys

from .test_globe_bounds import LIGHTS, SEGMENTS, band_cuts
from .test_globe_fog import airlight

OUT = pathlib.Path(__file__).with_name("data") / "globe_twins.json"


def main(names=None):
    """The twins of the lights `names` (all by default) into OUT, keeping the others' already there."""
    old = json.loads(OUT.read_text()) if OUT.exists() else {"twins": {}, "cuts": {}}
    twins, cuts = old["twins"], old["cuts"]
    for name in names or list(LIGHTS):
        light = LIGHTS[name]
        spot = light.get("type") == "spot"
        cuts[name] = [band_cuts(light, o, d, t) if spot else [] for o, d, t in SEGMENTS]
        twins[name] = [list(map(float, airlight(light, o, d, t, 1e-12, c)))
                       for (o, d, t), c in zip(SEGMENTS, cuts[name])]
        OUT.write_text(json.dumps({"segments": [[list(map(float, o)), list(map(float, d)), float(t)]
                                                for o, d, t in SEGMENTS], "twins": twins, "cuts": cuts}, indent=1))


if __name__ == "__main__":
    main(sys.argv[1:])
