"""The environment's error is its directions' alone: a render of the height-fog twin (tests/test_environment.py
`fog_twin`) equals, seed by seed, the closed form of the air-light of the very directions it drew
(`fog_by_directions`), so every departure from the twin is the directions' sampling error (benchmarks/environment.py
`sampling_errors` measures it over thousands of seeds from the same closed form: unbiased, e^2 / variance 1)."""
from __future__ import annotations

import numpy as np
import pytest

from raytrace import api
from raytrace.camera import generate_rays
from raytrace.lights import environment

from .test_environment import ENV, FOG, UP_CAMERA, fog_by_directions, scene


@pytest.mark.parametrize("seed", [0, 5])
def test_a_render_is_the_closed_form_of_its_directions(seed):
    """quadrature (rtol 1e-10), 64 directions, 2 x 2 rays up through the fog: within 1e-13 relative of the closed
    form over the rows `environment.rows` gives the pixel sample (the render's own)."""
    sc = scene([{**ENV, "directions": 64}], medium=FOG, camera=UP_CAMERA)
    rows = environment.rows(sc.lights[0], 64, seed, 0)
    origins, dirs = generate_rays(sc.camera)
    exact = np.array([fog_by_directions(o, d, ENV["radiance"], rows.axis, rows.intensity, 0.02, 0.1, 2.0)
                      for o, d in zip(origins, dirs)]).reshape(2, 2, 3)
    img = api.render(sc, "quadrature", rtol=1e-10, seed=seed)
    np.testing.assert_allclose(img.array, exact, rtol=1e-13, atol=0.0)
