"""The error bound of the medium inside a convex shape around a point or spot light that it holds (media/slab.py
`point_rounding`: the exit beyond the light, the path inside exactly its distance): finite now (it was inf, and
NaN where a spot's falloff is 0), checked on the index-matched lantern of tests/test_light_inside.py without
volumetric shadows, against that file's twin with the model's unshadowed air-light outside (the light there
not attenuated by the box; the floor, shadow-tested, still is)."""
import inspect

import numpy as np
import pytest

from . import test_light_inside as lantern

SOURCE = inspect.getsource(lantern.twin)
UNSHADOWED = SOURCE.replace("def twin(", "def twin_unshadowed(").replace(
    "def arriving(X):", "def arriving(X, air=False):").replace(
    "k = chord(X, L)", "k = chord(X, L) if not air or np.all((X > LO) & (X < HI)) else 0.0").replace(
    "e, _ = arriving(X)", "e, _ = arriving(X, True)")


def twin_unshadowed(light):
    """test_light_inside.twin with the air-light outside lit straight through the box, unattenuated."""
    space = dict(vars(lantern))
    exec(UNSHADOWED, space)
    return space["twin_unshadowed"](light)


def test_the_twin_changed_where_meant():
    assert all(part in UNSHADOWED for part in ("air=False", "if not air", "arriving(X, True)"))


@pytest.mark.parametrize("light", [lantern.LAMP, lantern.SPOT], ids=["lamp", "spot"])
def test_unshadowed_lantern_within_its_finite_bound(light):
    """quadrature (rtol 1e-10, no volumetric shadows) within 1e-10 of the twin (measured 1.0e-15 lamp, 4.8e-13
    spot) and inside its bound on every pixel, every bound finite (at most 3e-10 of the value)."""
    ref = twin_unshadowed(light)
    res = lantern.image(lantern.scene(light), "quadrature", {"rtol": 1e-10}, shadows=False)
    err = np.abs(res.image - ref)
    assert np.all(np.isfinite(res.error_bound))
    assert np.all(err <= 1e-10 * ref), np.max(err / np.maximum(ref, 1e-300))
    assert np.all(err <= res.error_bound)
    assert np.all(res.error_bound <= 3e-10 * ref)
