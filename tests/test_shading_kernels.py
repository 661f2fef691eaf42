"""The surface term's GIL-free kernels (raytrace/shading.py) against the NumPy they replaced, bit for bit."""
from __future__ import annotations

import numpy as np

from raytrace import shading
from raytrace.lights import POINT, SPOT, Light, Lights

RNG = np.random.default_rng(60)


def test_point_irradiance_is_the_lights():
    """shading._point_irradiance (a batch's point lights' I / d^2 in one pass) against Lights.irradiance
    light by light (lights/point.py's NumPy), on distances from 1e-3 to 1e3; a spot light's rows and a light
    that reaches no point are left as they were."""
    lights = Lights.of([Light(np.array([0.0, 2.0, 0.0]), np.array([10.0, 8.0, 6.0])),
                        Light(np.zeros(3), np.array([1.0, 1.0, 1.0]), SPOT, np.array([0.0, -1.0, 0.0]), 0.5, 0.9),
                        Light(np.array([1.0, 0.0, 0.0]), np.array([0.3, 1e5, 7.0])),
                        Light(np.array([1.0, 1.0, 0.0]), np.array([2.0, 2.0, 2.0]))])
    run = [0, 1, 2, 3]
    assert lights.kind[run].tolist() == [POINT, SPOT, POINT, POINT]
    ends = np.array([0, 500, 900, 1400, 1400])
    dist = 10.0 ** RNG.uniform(-3.0, 3.0, ends[-1])
    back = RNG.normal(size=(ends[-1], 3))
    out = np.full((ends[-1], 3), -1.0)
    shading._point_irradiance(lights.kind[run] == POINT, lights.intensity[run], ends, dist, out)
    for j in (0, 2):
        got = slice(ends[j], ends[j + 1])
        assert np.array_equal(out[got], lights.irradiance(run[j], back[got], dist[got]))
    assert np.all(out[ends[1]:ends[2]] == -1.0)
