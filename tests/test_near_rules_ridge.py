"""The rule of a flat emitter about camera rays that pass near it grazing its plane (raytrace/lights/planar.py,
`ridge_about`; lights/near_rules.py, `passing_rule`): such a ray crosses the plane beyond the emitter (or not
at all), and its nodes' air-light is a ridge along the ray's projection on the plane, about g(a) = s |a| wide
(s the ray's sine to the plane, a the distance along the projection from where its line meets the plane).

- Against scipy, from the geometry alone: over a rectangle, 1 / rho and g / rho^2 (rho the distance to the
  ray's line: the 1 / rho of a node's air-light and its Lorentzian form with the emission's cosine) for
  lines at sines 0.3, 0.05 and 0.01, headed along the rectangle's axes and obliquely, crossing the plane
  0.5 to 2 beyond it, level with it and from the other side (the inner integrals in closed form, asinh and
  atan; the outer by scipy quad split at the corners): within 1e-3 at order 3 (the ladder's first pair),
  1e-4 at order 4 and 1e-8 at order 8, where the emitter's tensor rule is off by more than 1e-2 at order 8
  on the grazing lines.
- `passing_rule`: rays that do not graze take the emitter's rows, the same nodes as before; owners index
  the rays asked about.
- Images: tests/test_passing_rays.py (its 6 passing rays graze, sine 0.11, against the exact twin).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from raytrace.lights import near_rules, planar

RECT = np.array([[-0.5, 0.0, -0.4], [0.7, 0.0, -0.4], [0.7, 0.0, 0.4], [-0.5, 0.0, 0.4]])
NORMAL = np.array([0.0, -1.0, 0.0])  # of RECT's corners' order
AREA = 1.2 * 0.8


def lines():
    """[(point on the plane where the line meets it, unit direction, sine, heading)]: grazing lines that pass over
    RECT and meet the plane beyond it (the crossing point outside RECT by 0.5 to 2 of its width)."""
    out = []
    for sine in (0.3, 0.05, 0.01):
        for heading in (0.0, math.pi / 2, 0.35, 2.6):
            p = np.array([math.cos(heading), 0.0, math.sin(heading)])
            d = math.sqrt(1.0 - sine * sine) * p + sine * NORMAL
            for beyond in (0.5, 2.0):
                far = max(np.abs(RECT @ p).max(), 0.0) + beyond
                out.append((far * p + np.array([0.1, 0.0, 0.05]), d, sine, heading))
    return out


def chord(x, p, q, f):
    """(lo, hi): RECT's chord along q at distance x along p from f (from the geometry: the rectangle's x and z
    bounds along the line f + x p + t q), or None where the line misses it."""
    point = f + x * p
    lo, hi = -math.inf, math.inf
    for axis, (a, b) in ((0, (-0.5, 0.7)), (2, (-0.4, 0.4))):
        if abs(q[axis]) < 1e-15:
            if not a <= point[axis] <= b:
                return None
            continue
        t1, t2 = (a - point[axis]) / q[axis], (b - point[axis]) / q[axis]
        lo, hi = max(lo, min(t1, t2)), min(hi, max(t1, t2))
    return (lo, hi) if hi > lo else None


def reference(f, d, sine, kernel):
    """int over RECT of 1 / rho (kernel 'inverse') or g / rho^2 ('lorentz') dA, rho^2 = (s x)^2 + t^2 the squared
    distance from f + x p + t q to the line through f along d, g = s |x|: inner in closed form, outer scipy."""
    p = d - (d @ NORMAL) * NORMAL
    p /= np.linalg.norm(p)
    q = np.cross(NORMAL, p)
    xs = sorted(float((c - f) @ p) for c in RECT)

    def inner(x):
        c = chord(x, p, q, f)
        if c is None:
            return 0.0
        g = sine * abs(x)
        if kernel == "inverse":
            return math.asinh(c[1] / g) - math.asinh(c[0] / g)
        return math.atan(c[1] / g) - math.atan(c[0] / g)
    return sum(integrate.quad(inner, a, b, epsabs=0.0, epsrel=1e-13, limit=200)[0] for a, b in zip(xs, xs[1:]))


def integrated(points, weights, owner, f, d, sine, kernel, n):
    """Per line, the rule's sum of weights times the kernel."""
    rel = points - f[owner]
    along = np.einsum("ij,ij->i", rel, d[owner])
    rho = np.sqrt(np.maximum(np.einsum("ij,ij->i", rel, rel) - along * along, 0.0))
    p = d[owner] - (d[owner] @ NORMAL)[:, None] * NORMAL
    x = np.einsum("ij,ij->i", rel, p) / np.linalg.norm(p, axis=1)
    value = 1.0 / rho if kernel == "inverse" else sine[owner] * np.abs(x) / (rho * rho)
    out = np.zeros(n)
    np.add.at(out, owner, weights * value)
    return out


@pytest.mark.parametrize("kernel", ["inverse", "lorentz"])
def test_the_ridge_rule_against_scipy(kernel):
    cases = lines()
    f = np.array([c[0] for c in cases])
    d = np.array([c[1] for c in cases])
    sine = np.array([c[2] for c in cases])
    origins = f - 3.0 * d  # the ray's origin 3 before the plane: its line crosses there
    ref = np.array([reference(c[0], c[1], c[2], kernel) for c in cases])
    assert ref.min() > 0.0
    nodes = planar.polygon(RECT, NORMAL).ridge(origins, d)
    errors = {}
    for order in (3, 4, 8):
        points, weights, owner = nodes(np.arange(len(cases)), order)
        errors[order] = np.abs(integrated(points, weights, owner, f, d, sine, kernel, len(cases)) / ref - 1.0)
    assert errors[3].max() < 1e-3 and errors[4].max() < 1e-4 and errors[8].max() < 1e-8, {
        k: v.max() for k, v in errors.items()}
    u, w = np.polynomial.legendre.leggauss(8)  # the emitter's tensor rule at order 8, for contrast
    uu, vv = np.meshgrid(0.5 * (u + 1.0), 0.5 * (u + 1.0), indexing="ij")
    grid = RECT[0] + uu.reshape(-1, 1) * (RECT[1] - RECT[0]) + vv.reshape(-1, 1) * (RECT[3] - RECT[0])
    k = len(cases)
    tensor = integrated(np.tile(grid, (k, 1)), np.tile(np.outer(w, w).ravel() / 4.0 * AREA, k),
                        np.repeat(np.arange(k), len(grid)), f, d, sine, kernel, k)
    grazing = sine <= 0.05
    assert np.abs(tensor / ref - 1.0)[grazing].max() > 1e-2


def test_the_ridge_rule_from_either_side_and_level():
    """Lines along RECT's x axis 0.1 from its plane that meet the plane beyond it, behind their origin, from the
    other side, or run level with it: 1 / rho within 1e-6 of scipy at order 6 (inner integral in closed form,
    rho^2 = g(x)^2 + (z - z0)^2 with g(x) the distance from (x, 0, z0) to the line)."""
    p = np.array([1.0, 0.0, 0.0])
    z0 = 0.05
    cases = []
    for height, sine in ((0.1, -0.02), (0.1, 0.02), (-0.1, 0.02), (0.1, 0.0)):
        d = math.sqrt(1.0 - sine * sine) * p + sine * NORMAL
        cases.append((np.array([-2.0, 0.0, z0]) + height * NORMAL, d))
    origins, d = np.array([c[0] for c in cases]), np.array([c[1] for c in cases])
    points, weights, owner = planar.polygon(RECT, NORMAL).ridge(origins, d)(np.arange(len(cases)), 6)
    rel = points - origins[owner]
    along = np.einsum("ij,ij->i", rel, d[owner])
    got = np.zeros(len(cases))
    np.add.at(got, owner, weights / np.sqrt(np.einsum("ij,ij->i", rel, rel) - along * along))
    for (o, dd), value in zip(cases, got):
        def inner(x):
            v = np.array([x, 0.0, z0]) - o
            g = np.linalg.norm(v - (v @ dd) * dd)
            return math.asinh((0.4 - z0) / g) - math.asinh((-0.4 - z0) / g)
        ref = integrate.quad(inner, -0.5, 0.7, epsabs=0.0, epsrel=1e-13, limit=200)[0]
        assert abs(value / ref - 1.0) < 1e-6, (o, dd, value, ref)


class _Emitter:
    """What passing_rule reads of an `area.Emitter`: its `planar` and its rows' `rule(order)`."""

    def __init__(self):
        self.planar = planar.polygon(RECT, NORMAL)

    @staticmethod
    def rule(order):
        u, w = np.polynomial.legendre.leggauss(order)
        uu, vv = np.meshgrid(0.5 * (u + 1.0), 0.5 * (u + 1.0), indexing="ij")
        grid = RECT[0] + uu.reshape(-1, 1) * (RECT[1] - RECT[0]) + vv.reshape(-1, 1) * (RECT[3] - RECT[0])
        return grid, np.tile(NORMAL, (len(grid), 1)), np.outer(w, w).ravel() / 4.0 * AREA


def test_passing_rule_keeps_the_rows_where_a_ray_does_not_graze():
    em = _Emitter()
    steep = np.array([0.6, -0.8, 0.0])  # sine 0.8: above planar.GRAZE
    flat = np.array([math.sqrt(1.0 - 0.01), -0.1, 0.0])
    dirs = np.array([steep, flat, steep, flat])
    origins = np.array([[0.0, 0.5, 0.0], [-2.0, 0.3, 0.0], [0.2, 0.6, 0.1], [-2.0, 0.25, 0.1]])
    rule = near_rules.passing_rule(em, (origins, dirs), np.arange(4))
    at = np.array([0, 1, 3])
    points, normals, weights, owner = rule(at, 4)
    rows = em.rule(4)
    np.testing.assert_array_equal(points[owner == 0], rows[0])
    np.testing.assert_array_equal(weights[owner == 0], rows[2])
    ridge = planar.polygon(RECT, NORMAL).ridge(origins[[1, 3]], dirs[[1, 3]])(np.arange(2), 4)
    for k, ray in ((1, 0), (2, 1)):  # the index into `at`, the grazing ray's among those
        np.testing.assert_array_equal(points[owner == k], ridge[0][ridge[2] == ray])
        np.testing.assert_array_equal(weights[owner == k], ridge[1][ridge[2] == ray])
        assert abs(weights[owner == k].sum() / AREA - 1.0) < 1e-3
    np.testing.assert_array_equal(normals[owner == 0], rows[1])
    assert np.all(normals[owner > 0] == NORMAL)
