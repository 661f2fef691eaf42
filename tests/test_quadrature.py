"""The `quadrature` kernel against scipy `quad` of eq. 4 (tests/oracle.py) to a relative 1e-9.

Geometries cover what a renderer meets: lights ahead of, beside and behind the camera, far along
the ray, very close to the ray line, thick and thin media, rays that hit nothing (ell = inf).
"""
import math

import numpy as np
import pytest

from raytrace.methods.geometry import POINT_ROW
from raytrace.methods import quadrature as q
from raytrace.media.phase import HG, ISOTROPIC, RAYLEIGH

from . import oracle

PHASES = [(ISOTROPIC, "isotropic", 0.0), (RAYLEIGH, "rayleigh", 0.0), (HG, "hg", 0.9), (HG, "hg", -0.5)]


def kernel(xh, h, ell, kt, ks, code, g, rtol=1e-10):
    stats = np.zeros(3)
    return q.airlight_one(xh, h, ell, kt, ks, code, g, POINT_ROW, rtol, q.N10, q.W10, q.N20, q.W20, stats), stats


def reference(xh, h, ell, kt, ks, name, g):
    o, d = np.zeros(3), np.array([1.0, 0.0, 0.0])
    return oracle.airlight(o, d, ell, [xh, h, 0.0], 1.0, kt, ks, name, g)


GEOMETRIES = [  # (xh, h, ell, kt)
    (2.0, 1.0, 5.0, 0.2),        # light beside the segment
    (2.0, 1.0, math.inf, 0.2),   # ray to infinity
    (-3.0, 0.5, 4.0, 0.3),       # light behind the camera
    (-300.0, 2.0, math.inf, 0.01),  # far behind, ray to infinity
    (50.0, 0.01, 20.0, 0.05),    # far ahead, close to the line, segment ends before it
    (3.0, 1e-4, 6.0, 0.1),       # ray grazing the light
    (1.0, 0.3, 10.0, 3.0),       # thick: optical depth 30 along the view
    (8.0, 2.0, 12.0, 1.5),       # thick, light optically far
    (0.5, 0.5, 0.1, 0.2),        # very short segment
]


@pytest.mark.parametrize("code,name,g", PHASES)
@pytest.mark.parametrize("xh,h,ell,kt", GEOMETRIES)
def test_quadrature_matches_scipy(xh, h, ell, kt, code, name, g):
    ks = 0.7 * kt
    got, stats = kernel(xh, h, ell, kt, ks, code, g)
    ref = reference(xh, h, ell, kt, ks, name, g)
    assert ref > 0
    assert abs(got - ref) <= 1e-9 * ref, (got, ref)
    assert stats[q.CAPPED] == 0


def test_vacuum_limit_is_the_geometric_integral():
    """kt -> 0 with ks fixed: isotropic Lm = ks/(4 pi h) (theta_b - theta_a) (METHODS.md §11.1)."""
    xh, h, ell, ks = 2.0, 0.7, 5.0, 0.3
    got, _ = kernel(xh, h, ell, 1e-15, ks, ISOTROPIC, 0.0)
    exact = ks / (4 * math.pi * h) * (math.atan((ell - xh) / h) - math.atan(-xh / h))
    assert got == pytest.approx(exact, rel=1e-12)


def test_zero_scattering_is_zero_and_ray_through_light_is_finite():
    assert kernel(1.0, 0.5, 3.0, 0.5, 0.0, ISOTROPIC, 0.0)[0] == 0.0
    val, _ = kernel(1.0, 1e-9, 3.0, 0.5, 0.4, ISOTROPIC, 0.0)
    assert np.isfinite(val) and val > 0
    # integrand ~ ks exp(-kt (x + |x - xh|)) / (4 pi d^2) peaks at x_h: ~ ks e^{-kt xh} / (4 h)
    assert val == pytest.approx(0.4 * math.exp(-0.5) / (4.0 * 1e-9), rel=1e-6)
