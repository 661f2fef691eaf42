"""Camera rays that pass near a flat emitter or end on it (raytrace/rendering/near_emitters.py): the
emitter's rows replaced by a rule about the ray's foot point (raytrace/lights/planar.py).

- The rules against scipy: their weights sum to the emitter's area for foot points inside, outside,
  on an edge's line and at a corner; they integrate 1 / |y - f| (the singularity they are built for)
  to rounding: a rectangle's closed form, a disk's by scipy's quad in polar coordinates about f.
- Images against the exact twin (tests/area_twin.py, `exact=True`: polar about each point's foot on
  the plane, the geometry and scipy alone; stored by tests/make_near_twins.py): a quad seen from below,
  its rays ending on it and passing beside its edges, and a disk the same way; `quadrature` (rtol 1e-6) and `analytic` (precision 1e-6)
  within 1e-6 on every pixel, the near rays counted and converged. The rows alone miss these pixels by
  up to a few per cent (the test fails with the rule switched off).
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
from raytrace.lights.area import frame
from raytrace.rendering import near_emitters

from .test_area_lights import scene

RECT = np.array([[-0.5, 0.0, -0.4], [0.7, 0.0, -0.4], [0.7, 0.0, 0.4], [-0.5, 0.0, 0.4]])
FEET = np.array([[0.1, 0.0, 0.2], [0.69, 0.0, -0.39], [0.75, 0.0, 0.1], [-0.5, 0.0, 0.0], [0.7, 0.0, 0.4],
                 [-0.55, 0.0, 0.45], [0.2, 0.0, 0.4 + 1e-7]])


def _rect_inverse_distance(f):
    """int over RECT of dA / |y - f|: sums of x asinh(z / x) + z asinh(x / z) at the corners."""
    def prim(x, z):
        return (x * math.asinh(z / abs(x)) if x else 0.0) + (z * math.asinh(x / abs(z)) if z else 0.0)
    (x0, z0), (x1, z1) = RECT[0, [0, 2]] - f[[0, 2]], RECT[2, [0, 2]] - f[[0, 2]]
    return prim(x1, z1) - prim(x0, z1) - prim(x1, z0) + prim(x0, z0)


def test_polygon_rule_against_the_closed_form():
    normal = np.cross(RECT[1] - RECT[0], RECT[3] - RECT[0])
    rule = planar.polygon(RECT, normal / np.linalg.norm(normal))
    for order in (6, 12):
        points, weights, owner = rule.rule(FEET, order)
        np.testing.assert_allclose(np.bincount(owner, weights), 0.96, rtol=1e-12 if order == 12 else 1e-6)
        assert np.allclose(points[:, 1], 0.0)
    points, weights, owner = rule.rule(FEET, 8)
    values = np.bincount(owner, weights / np.linalg.norm(points - FEET[owner], axis=1))
    np.testing.assert_allclose(values, [_rect_inverse_distance(f) for f in FEET], rtol=1e-11)
    np.testing.assert_allclose(rule.outside(FEET), [0.0, 0.0, 0.05, 0.0, 0.0, math.hypot(0.05, 0.05), 1e-7],
                               atol=1e-15)


def test_disk_rule_against_polar_quad():
    normal = np.array([0.3, -1.0, 0.2]) / np.linalg.norm([0.3, -1.0, 0.2])
    t1, t2 = frame(normal)
    centre, radius = np.array([0.1, 1.0, -0.2]), 0.5
    rule = planar.disk(centre, normal, t1, t2, radius)
    local = np.array([[0.0, 0.0], [0.2, -0.1], [0.49, 0.0], [0.3, 0.4 - 1e-6], [0.52, 0.1], [0.0, -0.7]])
    feet = centre + local[:, :1] * t1 + local[:, 1:] * t2
    points, weights, owner = rule.rule(feet, 32)
    np.testing.assert_allclose(np.bincount(owner, weights), math.pi * radius**2, rtol=1e-12)
    values = np.bincount(owner, weights / np.linalg.norm(points - feet[owner], axis=1))
    for (px, py), v in zip(local, values):
        dist = math.hypot(px, py)

        def chord(phi):  # the length of the ray from f at angle phi inside the circle
            b = px * math.cos(phi) + py * math.sin(phi)
            disc = b * b - (dist * dist - radius * radius)
            return 0.0 if disc <= 0 else max(0.0, -b + math.sqrt(disc)) - max(0.0, -b - math.sqrt(disc))

        ref = integrate.quad(chord, 0.0, 2 * math.pi, epsabs=0, epsrel=1e-13, limit=400,
                             points=None if dist < radius else [math.atan2(-py, -px) % (2 * math.pi)])[0]
        assert abs(v - ref) <= 1e-9 * ref, (px, py, v, ref)
    np.testing.assert_allclose(rule.outside(feet), np.maximum(np.hypot(*local.T) - radius, 0.0), atol=1e-15)


TWINS = json.loads((Path(__file__).resolve().parent / "data" / "near_emitter_twins.json").read_text())


@pytest.mark.parametrize("kind", sorted(TWINS))
def test_rays_near_an_emitter_against_the_exact_twin(kind, monkeypatch):
    """The twins' scenes (tests/make_near_twins.py): the rays near the emitter (9 of the 12 by the quad, 7 by
    the disk, the others passing within cubature.PASSING of it: their own ladders of its rows' rule, which
    may end on the pilot's rule, the rows' value bit for bit) within 1e-6 of the twin (the rows alone:
    1e-4 or more off on some)."""
    case = TWINS[kind]
    ref = np.array(case["radiance"])
    sc = scene([case["light"]], case["medium"], case["camera"])
    renders = api.render(sc, "quadrature", rtol=1e-6), api.render(sc, "analytic", precision=1e-6)
    monkeypatch.setattr(near_emitters, "applies", lambda *a: False)
    rows = api.render(sc, "quadrature", rtol=1e-6), api.render(sc, "analytic", precision=1e-6)
    for img, alone in zip(renders, rows):
        near = np.any(img.array != alone.array, axis=-1)
        assert img.stats["cubature: rays near an emitter"] >= near.sum() >= 7, img.stats
        assert img.stats["cubature: rays near an emitter not converged"] == 0, img.stats
        rel = np.abs(img.array[..., 0] / ref - 1)
        assert rel.max() <= 1e-6, (img.method, rel)
        assert np.abs(alone.array[..., 0] / ref - 1)[near].max() > 1e-4
