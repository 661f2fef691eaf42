"""Camera rays that pass near a flat emitter without crossing its plane near it
(raytrace/rendering/near_emitters.py, `_passing`; lights/cubature.py, PASSING): within PASSING of the
emitter's diameter they do not choose its cubature order in the pilot and take their own ladder of the
emitter's Gauss rule in the render.

Against the exact twin (tests/area_twin.py, `exact=True`, stored by tests/make_passing_twins.py): the
quad light of tests/test_area_lights.py in its fog, 12 rays 0.09 to 0.4 of its diameter under it, 6
within PASSING: `analytic` at precisions 1e-2, 1e-4, 1e-6 and `quadrature` at rtol 1e-6 within their
tolerance of the twin, those 6 counted near the emitter. Without their own ladders (`_passing` finds
none) they keep the rows that the rays beyond PASSING choose, more than 1e-3 off.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from raytrace import api
from raytrace.rendering import near_emitters

from .test_area_lights import FOG, QUAD, scene

CASE = json.loads((Path(__file__).resolve().parent / "data" / "passing_twins.json").read_text())


def render(method, **params):
    return api.render(scene([QUAD], FOG, CASE["camera"]), method, **params)


@pytest.mark.parametrize("method, params", [("analytic", {"precision": 1e-2}), ("analytic", {"precision": 1e-4}),
                                            ("analytic", {"precision": 1e-6}), ("quadrature", {"rtol": 1e-6})])
def test_passing_rays_against_the_exact_twin(method, params):
    ref = np.array(CASE["radiance"])
    img = render(method, **params)
    assert img.stats["cubature: rays near an emitter"] == 6, img.stats
    tol = next(iter(params.values()))
    np.testing.assert_allclose(img.array[..., 0], ref, rtol=tol, atol=0)


def test_without_their_ladders_the_rows_miss(monkeypatch):
    ref = np.array(CASE["radiance"])
    monkeypatch.setattr(near_emitters, "_passing", lambda lights, method, tol, o, d, near: np.zeros(near.shape, bool))
    img = render("analytic", precision=1e-4)
    assert img.stats["cubature: rays near an emitter"] == 0, img.stats
    assert np.abs(img.array[..., 0] / ref - 1).max() > 1e-3
