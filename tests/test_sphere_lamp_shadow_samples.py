"""`montecarlo` with a shadow ray per medium sample (`shadow_test = "samples"`) near sphere lamps: its own
estimate of the lamp (a distance along the ray, a direction uniform in the cone the sphere subtends from
there, a shadow ray along it where the occluders' geometry does not clear the segment), as with the lit
intervals, not the lamp's rows shadow-tested point by point. The rows missed the cap a segment beside
the lamp sees (z about 230 at 64 samples). The scenes are test_sphere_lamp_montecarlo's (the twin's
lamp beside a floor; the lamp above a floor against quadrature at 1e-8), the latter with a shelf that
shadows part of the floor and of the fog; z-scores over seeds as there."""
from __future__ import annotations

import functools

import numpy as np
import pytest

from raytrace import api

from .test_area_lights import SMALL, SPHERE, scene as area_scene
from .test_sphere_lamp_montecarlo import FLOOR, SEEDS, _z_ok
from .test_sphere_lamp_unfaced import CEILING_Y, FLOOR_Y, UP, _plane, scene, twin

SHELF = {"primitive": "box", "min": [-1.0, 0.95, -0.4], "max": [0.05, 1.0, 0.4]}  # under half the lamp


def test_beside_the_lamp_over_a_floor_against_the_twin():
    """Up beside the lamp to a black ceiling over a floor through its lower half (it meets the hull of
    each segment and the ball: a shadow ray per sample), 64 samples, 4 seeds: unbiased against the twin."""
    ref = twin(UP)
    z = []
    for seed in SEEDS:
        img = api.render(scene(UP, [_plane(CEILING_Y), _plane(FLOOR_Y)]), "montecarlo", samples=64, seed=seed,
                         volumetric_shadows=True, shadow_test="samples")
        z.append((img.array[..., 0] - ref) / np.sqrt(img.variance[..., 0]))
        assert np.all(img.variance[..., 0] > 0.0)
    _z_ok(z)


@pytest.mark.parametrize("sampling", ["equiangular", "mis"])
def test_lamp_over_a_shelf_against_quadrature(sampling):
    """The lamp above a floor and a shelf under half of it, 16 x 12, HG g = 0.6, 64 samples, two seeds:
    unbiased against quadrature at 1e-8 (its sampled penumbrae's variance added)."""
    ref = _quadrature()
    z = []
    for seed in SEEDS[:2]:
        img = api.render(_shelf(), "montecarlo", volumetric_shadows=True, samples=64, seed=seed, sampling=sampling,
                         shadow_test="samples")
        z.append((img.array - ref.array) / np.sqrt(img.variance + ref.variance))
    _z_ok(z)


def _shelf():
    medium = {"sigma_a": 0.05, "sigma_s": 0.1, "phase": {"type": "hg", "g": 0.6}}
    return area_scene([SPHERE], medium=medium, camera={**SMALL, "width": 16, "height": 12}, shapes=[FLOOR, SHELF])


@functools.cache
def _quadrature():
    return api.render(_shelf(), "quadrature", volumetric_shadows=True, rtol=1e-8)
