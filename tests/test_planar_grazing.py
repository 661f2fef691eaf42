"""The polygon's rule about a foot point graded toward a grazing ray (raytrace/lights/planar.py,
`grazing`, `peaks`): a ray nearly parallel to the emitter's plane puts its nodes' 1 / rho (rho the
distance to the ray's line) in a peak along the ray's projection, about the sine of its angle wide.

- Against scipy: 1 / rho over a rectangle for rays along either of its axes at sines 0.3, 0.05 and 0.01
  (the inner integral in closed form, asinh; the outer by scipy quad split at the foot), feet inside,
  just outside an edge, at a corner and beyond one: graded within 1e-5 at order 4, 1e-10 at 8 and 1e-12
  at 12, where the ungraded rule (no directions) is off by more than 1e-2 at order 8 at the grazing
  sines; the graded weights sum to the area to 1e-3, 1e-7 and 1e-11 (the grading's price: the
  ungraded's sum is exact sooner, 3e-8 at order 4).
- Rays that do not graze (sine above planar.GRAZE) and calls without directions: the same rule bit for bit.
- An image against the exact twin (tests/area_twin.py, `exact=True`, stored by tests/make_grazing_twins.py):
  the quad light of tests/test_area_lights.py in its fog, 6 rays grazing its plane (sine about 0.012)
  that cross it on the quad and beside its edge: `analytic` (precision 1e-6) and `quadrature` (rtol
  1e-6) within 1e-6 of the twin, every ray near the emitter and converged; ungraded (GRAZE 0) the
  ladder does not converge on most of them and misses the twin by more than 1e-3.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy import integrate

from raytrace import api
from raytrace.lights import planar

from .test_area_lights import FOG, QUAD, scene

RECT = np.array([[-0.5, 0.0, -0.4], [0.7, 0.0, -0.4], [0.7, 0.0, 0.4], [-0.5, 0.0, 0.4]])
NORMAL = np.array([0.0, -1.0, 0.0])  # of RECT's corners' order
FEET = np.array([[0.1, 0.0, 0.2], [0.71, 0.0, 0.1], [-0.51, 0.0, -0.3], [0.7, 0.0, 0.4], [0.2, 0.0, 0.41],
                 [-0.2, 0.0, -0.45]])


def inverse_line_distance(f, sine: float, axis: int) -> float:
    """int over RECT of dA / rho, rho the distance from y to the line through f along (its projection
    on the plane along x (axis 0) or z (axis 2), sine to the plane): rho^2 = a^2 + (b sine)^2, a across
    and b along the projection; the integral over a in closed form (asinh), over b by scipy."""
    lo, hi = RECT[0, [0, 2]] - f[[0, 2]], RECT[2, [0, 2]] - f[[0, 2]]
    across = 0 if axis == 2 else 1  # RECT's coordinates (x, z) across the projection, then along it
    a0, a1, b0, b1 = lo[across], hi[across], lo[1 - across], hi[1 - across]

    def inner(b):
        return math.asinh(a1 / (abs(b) * sine)) - math.asinh(a0 / (abs(b) * sine))
    return integrate.quad(inner, b0, b1, points=[0.0] if b0 < 0.0 < b1 else None, epsabs=0.0, epsrel=1e-13,
                          limit=500)[0]


def integrate_rule(rule, order, d, dirs):
    points, weights, owner = rule.rule(FEET, order, dirs)
    rel = points - FEET[owner]
    along = rel @ d
    rho = np.sqrt(np.maximum(np.einsum("ij,ij->i", rel, rel) - along * along, 0.0))
    return np.bincount(owner, weights / rho, minlength=len(FEET)), np.bincount(owner, weights, minlength=len(FEET))


@pytest.mark.parametrize("sine", [0.3, 0.05, 0.01])
@pytest.mark.parametrize("axis", [0, 2])
def test_grazing_rays_against_scipy(sine, axis):
    rule = planar.polygon(RECT, NORMAL)
    d = np.zeros(3)
    d[1], d[axis] = sine, math.sqrt(1.0 - sine * sine)
    dirs = np.tile(d, (len(FEET), 1))
    ref = np.array([inverse_line_distance(f, sine, axis) for f in FEET])
    for order, rtol, area_rtol in ((4, 1e-5, 1e-3), (8, 1e-10, 1e-7), (12, 1e-12, 1e-11)):
        value, area = integrate_rule(rule, order, d, dirs)
        np.testing.assert_allclose(value, ref, rtol=rtol, atol=0)
        np.testing.assert_allclose(area, 0.96, rtol=area_rtol)
    plain = integrate_rule(rule, 8, d, None)[0]
    if sine < 0.1:
        assert np.abs(plain / ref - 1).max() > 1e-2


def test_steep_rays_and_no_directions_keep_the_rule():
    rule = planar.polygon(RECT, NORMAL)
    steep = np.tile([0.3, -0.9, 0.3], (len(FEET), 1)) / np.linalg.norm([0.3, -0.9, 0.3])
    assert abs(steep[0] @ NORMAL) > planar.GRAZE
    for order in (3, 12):
        plain = rule.rule(FEET, order)
        for got in (rule.rule(FEET, order, steep), rule.rule(FEET, order, None)):
            for a, b in zip(got, plain):
                np.testing.assert_array_equal(a, b)


def test_grazing_rays_against_the_exact_twin(monkeypatch):
    case = json.loads((Path(__file__).resolve().parent / "data" / "grazing_twins.json").read_text())
    ref = np.array(case["radiance"])
    sc = scene([QUAD], FOG, case["camera"])

    def renders():
        return api.render(sc, "analytic", precision=1e-6), api.render(sc, "quadrature", rtol=1e-6)
    for img in renders():
        assert img.stats["cubature: rays near an emitter"] == ref.size, img.stats
        assert img.stats["cubature: rays near an emitter not converged"] == 0, img.stats
        np.testing.assert_allclose(img.array[..., 0], ref, rtol=1e-6, atol=0)
    monkeypatch.setattr(planar, "GRAZE", 0.0)
    for img in renders():
        assert img.stats["cubature: rays near an emitter not converged"] > ref.size // 2, img.stats
        assert np.abs(img.array[..., 0] / ref - 1).max() > 1e-3
