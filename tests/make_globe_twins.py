"""Writes tests/data/globe_twins.json: tests/test_globe_bounds.py's twin (tests/test_globe_fog.py `airlight`, scipy
quad_vec at epsrel 1e-12 over 30-digit paths out, cut where a spot's leaving cosine crosses its band edges:
`band_cuts`, stored too) on its fog segments, for each of its lights; and for the spot tests/test_globe_spot.py's
pixels of tests/test_globe_fog.py's scene (`pixels`). Too slow for CI (about 2.5 CPU min: the lamp 32 s, the spot
118 s, 39 of them its segments): run `python -m tests.make_globe_twins` from the repository root after changing the
segments, the lights or the scene (`python -m tests.make_globe_twins spot`: the spot's alone). `shadow`:
tests/test_globe_shadow.py's pixels (the lamp's fog shadowed by a plate: `shadowed_air`, about 1 CPU min)."""
import json
import pathlib
import sys

import numpy as np

from .test_globe_bounds import LIGHTS, SEGMENTS, band_cuts
from .test_globe_fog import airlight, fog_pixel
from .test_globe_shadow import PIXELS, shadowed_air
from .test_lamp_in_glass import CAMERA
from .test_lamp_in_globe import twin

OUT = pathlib.Path(__file__).with_name("data") / "globe_twins.json"
PIXEL_LIGHTS = ("spot",)  # the lamp's pixels: tests/test_globe_fog.py computes them


def pixels(light):
    """(pixels, air) (H, W, 3) of tests/test_globe_fog.py's scene (the globe in fog on the floor) under `light`:
    tests/test_lamp_in_globe.py `twin`'s pixel (the floor and the globe's inside, seen straight, mirrored and
    through the glass) plus `fog_pixel`'s air-light (quad_vec at epsrel 1e-12, cut at `band_cuts`), and the latter."""
    spot = light.get("type") == "spot"
    air = np.array([[fog_pixel(light, j, i, 1e-12, lambda o, d, t: band_cuts(light, o, d, t) if spot else ())
                     for i in range(CAMERA["width"])] for j in range(CAMERA["height"])])
    return twin(light) + air, air


def main(names=None):
    """The twins of the lights `names` (all by default) into OUT, keeping the others' already there."""
    old = json.loads(OUT.read_text()) if OUT.exists() else {}
    twins, cuts, images = old.get("twins", {}), old.get("cuts", {}), old.get("pixels", {})
    shadow = old.get("shadow", {})
    if not names or "shadow" in names:
        air, shadow_cuts = zip(*(shadowed_air(j, i, 1e-12) for j, i in PIXELS))
        shadow = {"air": [list(map(float, a)) for a in air], "cuts": [list(map(float, c)) for c in shadow_cuts]}
    for name in [n for n in names or list(LIGHTS) if n != "shadow"]:
        light = LIGHTS[name]
        spot = light.get("type") == "spot"
        cuts[name] = [band_cuts(light, o, d, t) if spot else [] for o, d, t in SEGMENTS]
        twins[name] = [list(map(float, airlight(light, o, d, t, 1e-12, c)))
                       for (o, d, t), c in zip(SEGMENTS, cuts[name])]
        if name in PIXEL_LIGHTS:
            images[name] = dict(zip(("pixels", "air"), (a.tolist() for a in pixels(light))))
    OUT.write_text(json.dumps({"segments": [[list(map(float, o)), list(map(float, d)), float(t)]
                                            for o, d, t in SEGMENTS], "twins": twins, "cuts": cuts,
                               "pixels": images, "shadow": shadow}, indent=1))


if __name__ == "__main__":
    main(sys.argv[1:])
