"""A camera inside a refractive exact sphere of fog (interiors/crossing.py `start_inside`): the camera
rays' inside rows take the light's exact refracted paths into the sphere (media/sphere_refraction.py)
as rows entering from outside do. The twin is tests/test_refracted_sphere.py's, from the geometry alone
(Fermat's paths bracketed and solved by brentq, the ray tube's irradiance by the complex step, scipy quad
between the points where the number of paths changes); the camera's rays start at the camera and end on
the sphere, which they leave into a black vacuum (what they meet beyond is nothing)."""
import math

import numpy as np
import pytest
from scipy import integrate

from . import oracle
from .test_refracted_sphere import CASES, INTERIOR, Twin, ball, image

CAMERA = {"position": [0.25, -0.3, 0.45], "look_at": [-0.3, 0.1, -0.6], "fov": 60.0, "width": 4, "height": 3,
          "spp": 1}


def inside(case):
    scene = ball(*CASES[case])
    return {**scene, "camera": CAMERA}


def twin_image(scene):
    """The twin's image (H, W, 3): along each camera ray from the camera to the sphere, the light's
    paths to each point (their count's changes as the quad's points)."""
    twin = Twin(scene)
    kt = np.array(INTERIOR["sigma_a"], float) + np.array(INTERIOR["sigma_s"], float)
    img = np.zeros((CAMERA["height"], CAMERA["width"], 3))
    for j in range(CAMERA["height"]):
        for i in range(CAMERA["width"]):
            p, d = oracle.camera_ray(CAMERA, i, j)
            b = float(p @ d)
            ell = -b + math.sqrt(b * b - (float(p @ p) - 1.0))
            points = sorted(x for x, _ in twin.cuts(p, d, ell)) or None
            for c in range(3):
                img[j, i, c] = twin.power[c] * integrate.quad(
                    lambda x: twin.radiance(p + x * d, d)[c] * math.exp(-kt[c] * x), 0.0, ell, points=points,
                    epsabs=0.0, epsrel=1e-9, limit=400)[0]
    return img


@pytest.mark.parametrize("case", [pytest.param("water_lamp", marks=pytest.mark.slow), "glass_sun"])  # slow: ~25 s
# python -m pytest -q -m slow tests/test_camera_inside_sphere.py
def test_quadrature_from_inside_an_exact_sphere(case):
    """quadrature (rtol 1e-8) within 1e-7 of the twin on every pixel, inside its bound, every integral
    converged."""
    scene = inside(case)
    ref = twin_image(scene)
    res = image(scene, "quadrature", {"rtol": 1e-8})
    assert np.all(ref[..., 1] > 0.0)
    err = np.abs(res.image - ref)
    assert np.max(err / ref) < 1e-7
    assert np.all(err <= res.error_bound)
    assert res.stats["inside: integrals not converged"] == 0


def test_analytic_from_inside_an_exact_sphere_under_the_sun():
    """analytic takes the camera inside too: the sphere's refracted paths by its declared adaptive
    quadrature (counted): within the two renders' rtol of quadrature's image."""
    scene = inside("glass_sun")
    res, ref = image(scene, "analytic", {"precision": 1e-8}), image(scene, "quadrature", {"rtol": 1e-8})
    assert res.stats["inside: segments handed to quadrature"] == CAMERA["width"] * CAMERA["height"]
    assert np.max(np.abs(res.image - ref.image) / ref.image) < 2e-8
