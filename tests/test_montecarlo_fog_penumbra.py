"""montecarlo in an occluded quad light's penumbra in a height fog and an atmosphere: each medium point's shadow
ray goes to its own drawn point of the emitter (methods/montecarlo.py `drawn_points` over the medium's record,
`_fog_points`, `_atmosphere_points`), with the medium's own distance sampling and transmittance.

The fog's reference: tests/make_montecarlo_fog_twins.py (the scene of tests/make_montecarlo_penumbra_twins.py in an
exponential fog; the plate's shadow exact per emitter point, the fog's closed-form columns, Gauss–Legendre over the
emitter and the ray), stored in tests/data/montecarlo_fog_twins.json; one penumbra pixel is recomputed here. The
z-test of tests/test_montecarlo_penumbra.py over 2 seeds; the rows' estimate (what montecarlo drew in a fog's
penumbrae before) fails it. The atmosphere's: tests/make_montecarlo_atmosphere_twins.py (the same scene in 8 x 6
pixels in a planet's two-layer coloured air, one layer Henyey–Greenstein; its columns integrated from the density's
definition, not the project's Chapman code), channels 0 and 2 (each its own test), one seed (about 12 CPU s):
mean z^2 0.69 and 0.71, largest |z| 2.7 and 2.8; with the drawn points' rows at their nodes' light (a scratch
copy of montecarlo `_atm_row`) 2.19 and 1.58, 3.9 and 5.4, which fails. In an atmosphere
(and the fog) the drawn points' weights are those `drawn_segments` averages, draw for draw, where nothing occludes.
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from raytrace import api
from raytrace.lights.planar import flat_rows
from raytrace.methods import Segments, get_method, resolve_params
from raytrace.methods.montecarlo import _draws, _points
from raytrace.rendering.renderer import prepare
from raytrace.segments import whole_rays

from . import make_montecarlo_atmosphere_twins as air, make_montecarlo_fog_twins as fog
from . import make_montecarlo_penumbra_twins as twin
from .test_area_lights import scene
from .test_montecarlo_penumbra import _passes

LIVE = (7, 9)  # a pixel whose ray crosses the penumbra, recomputed from the geometry each run
SAMPLES = 256  # seeds 0-1: the drawn points mean z^2 0.955, largest |z| 3.96; the rows (main) 1.664 and 6.70


@pytest.fixture(scope="module")
def case():
    ref = np.array(json.loads(fog.OUT.read_text())["image"])
    o, dirs = twin.rays()
    assert abs(twin.pixel(o, dirs[LIVE], medium=fog.fog) / ref[LIVE] - 1.0) < 1e-12
    return scene([twin.LIGHT], medium=fog.MEDIUM, camera=twin.CAMERA, shapes=twin.SHAPES), ref


def _z(sc, ref, seeds, channels=(0,)):
    """(channels, seeds, H, W) z-scores of `channels` against ref (channels, H, W) (a grey fog: channel 0, the
    channels are one estimate)."""
    out = []
    for seed in seeds:
        img = api.render(sc, "montecarlo", volumetric_shadows=True, samples=SAMPLES, seed=seed)
        out.append((img.array[..., channels] - np.moveaxis(ref, 0, -1)) / np.sqrt(img.variance[..., channels]))
    return np.moveaxis(np.array(out), -1, 0)


def test_the_fog_penumbra_against_the_twin(case):
    z = _z(case[0], case[1][None], range(2))
    assert _passes(z), (np.mean(z ** 2), np.abs(z).max())


def test_the_rows_fail_it(case, monkeypatch):
    """With the cut pairs not routed to the drawn points, so that their rows stay at their nodes (montecarlo in a
    fog before), the same test fails."""
    monkeypatch.setattr("raytrace.shadows.penumbra_airlight.draws", lambda lights, method, shadows: False)
    z = _z(case[0], case[1][None], range(2))
    assert not _passes(z), (np.mean(z ** 2), np.abs(z).max())


AIR_LIVE = (3, 4)  # a pixel recomputed from the geometry each run


@pytest.fixture(scope="module")
def air_case():
    ref = np.array(json.loads(air.OUT.read_text())["image"])  # (channels, H, W)
    o, dirs = air.rays()
    assert abs(air.pixel(o, dirs[AIR_LIVE], air.CHANNELS[0]) / ref[0][AIR_LIVE] - 1.0) < 1e-12
    return scene([twin.LIGHT], medium=air.MEDIUM, camera=air.CAMERA, shapes=twin.SHAPES), ref


def test_the_atmosphere_penumbra_against_the_twin(air_case):
    for c, z in zip(air.CHANNELS, _z(*air_case, range(1), air.CHANNELS)):
        assert _passes(z), (c, np.mean(z ** 2), np.abs(z).max())


@pytest.mark.parametrize("medium", [fog.MEDIUM, air.MEDIUM], ids=["fog", "atmosphere"])
@pytest.mark.parametrize("sampling", ["equiangular", "mis"])
def test_the_points_weigh_what_the_segments_average(medium, sampling):
    """Unoccluded, each iteration's drawn points (`_points`, shadow_test = samples) weigh per channel what
    `drawn_segments` estimates with the same random numbers: their mean over the iterations is its mean."""
    prep = prepare(scene([twin.LIGHT], medium=medium, camera={**twin.CAMERA, "width": 6, "height": 4}))
    lights, o, dirs = prep.lights, np.array(twin.CAMERA["position"], float), twin.rays()[1][::3, ::3].reshape(-1, 3)
    segs = whole_rays(np.repeat(o[None], len(dirs), 0), dirs, np.full(len(dirs), 6.0),
                      np.arange(len(dirs), dtype=np.uint64), len(lights), 7, prep.accel.scale)
    segs = segs.take(np.nonzero(flat_rows(lights)[segs.light])[0])
    assert isinstance(segs, Segments) and len(segs)
    params = resolve_params(get_method("montecarlo"), {"samples": 8, "sampling": sampling, "shadow_test": "samples"},
                            "test")
    mean, _, _ = _draws(segs, prep.scene.medium, lights, params)
    pos, weight, targets = _points(segs, prep.scene.medium, lights, params)
    assert np.any(mean > 0.0) and np.all(np.isfinite(weight))
    np.testing.assert_allclose(weight.sum(axis=2).mean(axis=1), mean, rtol=1e-13, atol=0.0)
    assert not np.allclose(targets, lights.position[segs.light][:, None, :])  # each iteration's drawn point
