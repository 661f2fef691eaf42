"""montecarlo in an occluded quad light's penumbra: each medium point's shadow ray goes to its own drawn point of
the emitter (methods/montecarlo.py `drawn_points`, shadows/shadow_rays.py, shadows/penumbra_airlight.py `drawn`),
so the estimate is unbiased where the plate cuts the emitter, not the cubature rows' rule.

The reference: tests/make_montecarlo_penumbra_twins.py (a plate between the quad and a fog, black surfaces; the
plate's shadow exact per emitter point, Gauss–Legendre over the emitter and the ray), stored in
tests/data/montecarlo_penumbra_twins.json; one penumbra pixel is recomputed here. Both shadow tests (the lit
intervals, whose cut pairs take the drawn points' shadow rays, and samples), each by z-scores over 2 seeds:
the mean square within 4 of its standard deviations of 1, no |z| above 4.5 (false alarm below 1e-3). The
rows' estimate (what montecarlo drew in penumbrae before) fails the same test.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from raytrace import api

from . import make_montecarlo_penumbra_twins as twin
from .test_area_lights import scene

SAMPLES = 16
LIVE = (7, 9)  # a pixel whose ray crosses the penumbra, recomputed from the geometry each run


@pytest.fixture(scope="module")
def case():
    ref = np.array(json.loads(twin.OUT.read_text())["image"])
    o, dirs = twin.rays()
    assert abs(twin.pixel(o, dirs[LIVE]) / ref[LIVE] - 1.0) < 1e-12
    return scene([twin.LIGHT], medium=twin.MEDIUM, camera=twin.CAMERA, shapes=twin.SHAPES), ref


def _z(sc, ref, shadow_test, seeds):
    out = []
    for seed in seeds:
        img = api.render(sc, "montecarlo", volumetric_shadows=True, samples=SAMPLES, seed=seed,
                         shadow_test=shadow_test)
        out.append((img.array - ref[..., None]) / np.sqrt(img.variance))
    return np.array(out)


@pytest.mark.parametrize("shadow_test", ["intervals", "samples"])
def test_the_penumbra_against_the_twin(case, shadow_test):
    sc, ref = case
    z = _z(sc, ref, shadow_test, range(2))[..., 0]  # a grey medium: the channels are one estimate
    sd = math.sqrt(2.0 / z.size)
    assert abs(np.mean(z ** 2) - 1.0) < 4.0 * sd and np.abs(z).max() < 4.5, (np.mean(z ** 2), np.abs(z).max())


def test_the_rows_fail_it(case, monkeypatch):
    """The rows at their nodes (flat emitters not drawn: montecarlo before) are off in the penumbra."""
    sc, ref = case
    for where in ("raytrace.methods.montecarlo", "raytrace.shadows.penumbra_airlight"):
        monkeypatch.setattr(f"{where}.flat_rows", lambda lights: np.zeros(len(lights), bool))
    z = _z(sc, ref, "intervals", range(2))[..., 0]
    assert np.mean(z ** 2) > 5.0, np.mean(z ** 2)
