"""`montecarlo` and sphere lamps: its own estimate of the lamp along each camera ray (distances along the
ray, then a direction in the cone the sphere subtends: methods/montecarlo.py), not the sphere's rows,
which no order makes unbiased and which miss the cap a segment near the lamp sees (between the rows)
altogether: 1.1 radii above the pole the rows left out the air-light (z -600 at 64 samples), beside
it 77 % of it. The twins are test_sphere_lamp_unfaced's (scipy); z-scores over seeds: the mean of z^2
below 2 and no |z| beyond 5."""
from __future__ import annotations

import functools

import numpy as np
import pytest

from raytrace import api

from .test_area_lights import SMALL, SPHERE, scene as area_scene
from .test_sphere_lamp_unfaced import CEILING_Y, DOWN, FLOOR_Y, UP, _plane, scene, twin

SEEDS = (0, 1, 2, 3)
FLOOR = {"primitive": "box", "min": [-1.0, -1.0, -1.0], "max": [1.0, -0.9, 1.0]}


def _z_ok(z):
    z = np.asarray(z)
    assert np.mean(z ** 2) < 2.0 and np.abs(z).max() < 5.0, (np.mean(z ** 2), np.abs(z).max())


@pytest.mark.parametrize("case", ["down", "beside", "beside, the floor"])
def test_near_the_lamp_against_the_twin(case):
    """Looking down at the pole from 1.1 radii (no volumetric shadows; the lamp's own radiance the rest
    of the pixel), up beside it to a black ceiling with shadows (the ceiling clears every segment: no
    shadow rays), and the same over a floor through the lamp's lower half (it meets the hull of each
    segment and the ball: a shadow ray per sample), 64 samples, 4 seeds: unbiased against the twin."""
    cam, shapes, shadows = {"down": (DOWN, [], False), "beside": (UP, [_plane(CEILING_Y)], True),
                            "beside, the floor": (UP, [_plane(CEILING_Y), _plane(FLOOR_Y)], True)}[case]
    ref = twin(cam)
    z = []
    for seed in SEEDS:
        img = api.render(scene(cam, shapes), "montecarlo", samples=64, seed=seed, volumetric_shadows=shadows)
        z.append((img.array[..., 0] - ref) / np.sqrt(img.variance[..., 0]))
        assert np.all(img.variance[..., 0] > 0.0)
    _z_ok(z)


@pytest.mark.parametrize("sampling", ["equiangular", "freepath", "mis"])
def test_lamp_above_a_floor_against_quadrature(sampling):
    """The lamp above a floor, 32 x 24, HG g = 0.6 (the phase function between the ray and the sampled
    direction), with and without volumetric shadows, 64 samples: unbiased against quadrature at 1e-8
    (the rule about each segment; with shadows its sampled pairs' variance added). The rows were up to
    9.9 standard errors off at 64 samples."""
    sc = _plate()
    z = []
    for shadows in (False, True):
        ref = _quadrature(shadows)
        img = api.render(sc, "montecarlo", volumetric_shadows=shadows, samples=64, seed=3, sampling=sampling)
        z.append((img.array - ref.array) / np.sqrt(img.variance + ref.variance))
    _z_ok(z)


def _plate():
    medium = {"sigma_a": 0.05, "sigma_s": 0.1, "phase": {"type": "hg", "g": 0.6}}
    return area_scene([SPHERE], medium=medium, camera={**SMALL, "width": 32, "height": 24}, shapes=[FLOOR])


@functools.cache
def _quadrature(shadows: bool):
    return api.render(_plate(), "quadrature", volumetric_shadows=shadows, rtol=1e-8)
