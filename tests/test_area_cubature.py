"""The pilot that chooses each emitter's cubature order per render (raytrace/lights/cubature.py):

- its ladder and pairs (each order against the first of at least 4 x its rows, at most MAX_ROWS);
- `choose` on synthetic pilots whose error is known: it stops at the first pair that agrees to
  SHARE x the precision on the rays that are not near, keeps the coarser order, counts the near rays
  that disagree, and caps (counted) where no pair agrees;
- the near rays are those that pass closest to the emitter (a brute-force distance from geometry);
- an emissive shape's refinement levels split each triangle in 4 and keep its area and normal;
- scenes without area lights render as before (no pilot, no statistics).
"""
from __future__ import annotations

import numpy as np
import pytest

from raytrace import api
from raytrace.lights import cubature, emissive
from raytrace.lights.quad import sample_emitter

from .test_area_lights import QUAD, SMALL, scene


def distances(samples, origins, dirs):
    """((N,) each half-line's distance to the nearest of an emitter's probe points, about its diameter):
    the pilot's measure of every ray, without `cubature.nearest`'s shortcut."""
    points = cubature.probe_points(samples)
    return cubature.half_line_distances(points, origins, dirs), cubature.diameter(points)


def quad_rows(order):
    return order * order


def test_ladder_and_pairs():
    orders = cubature.ladder(cubature.AREA_LADDER, quad_rows)
    assert orders == (2, 3, 4, 6, 8, 12, 16, 24, 32) and quad_rows(orders[-1]) <= cubature.MAX_ROWS
    assert cubature.pairs(orders, quad_rows) == [(2, 4), (3, 6), (4, 8), (6, 12), (8, 16), (12, 24), (16, 32)]
    levels = cubature.ladder(range(cubature.LEVELS), lambda level: 14 * 4 ** level)
    assert levels == (0, 1, 2, 3) and cubature.pairs(levels, lambda level: 14 * 4 ** level) == [(0, 1), (1, 2), (2, 3)]
    assert cubature.ladder(range(cubature.LEVELS), lambda level: 2000 * 4 ** level) == (0,)  # kept, too many rows


def synthetic(exact, rates):
    """A pilot whose ray k's radiance at order n is exact_k (1 + n^-rates_k) (one cubature source)."""
    def shade(orders, rays):
        n = orders[0]
        return (exact * (1.0 + float(n) ** -rates))[rays, None] * np.ones(3)
    return shade


@pytest.mark.parametrize("tol", [1e-3, 1e-6])
def test_choose_stops_at_the_first_pair_that_agrees(tol):
    exact = np.array([1.0, 2.0, 0.5, 3.0])
    rates = np.array([12.0, 9.0, 10.0, 1.0])  # the last ray converges slowly: near the emitter
    near = np.array([False, False, False, True])
    orders = cubature.ladder(cubature.AREA_LADDER, quad_rows)
    chosen, capped, n_near, stray = cubature.choose([orders], [quad_rows], [near], synthetic(exact, rates), tol)
    want = next(c for c, f in cubature.pairs(orders, quad_rows)
                if all(abs(c ** -r - f ** -r) / (1 + f ** -r) <= cubature.SHARE * tol for r in rates[:3]))
    assert chosen == (want,) and capped == 0 and n_near == 1 and stray == 1
    # the same with the slow ray not near: it decides, and no pair agrees: capped at the finest
    chosen, capped, _, stray = cubature.choose([orders], [quad_rows], [np.zeros(4, bool)], synthetic(exact, rates), tol)
    assert chosen == (32,) and capped == 1 and stray == 1


def test_choose_leaves_other_sources_alone():
    calls = []

    def shade(orders, rays):
        calls.append(orders)
        return np.ones((len(rays), 3))

    chosen, capped, _, _ = cubature.choose([None, (2, 4, 8)], [None, quad_rows], [None, np.zeros(2, bool)], shade, 1e-3)
    assert chosen == (None, 2) and capped == 0 and all(c[0] is None for c in calls)


def test_near_rays_are_the_closest_to_the_emitter():
    lt = scene([QUAD]).lights[0]
    rng = np.random.default_rng(5)
    o = rng.uniform(-2.0, 2.0, (200, 3))
    d = rng.normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    dist, diameter = distances(lambda u, v: sample_emitter(lt, u, v), o, d)
    assert abs(diameter - np.sqrt(2.0)) < 1e-9
    g = np.linspace(0.0, 1.0, 201)  # brute force: the half-lines' distances to a fine grid of the quad
    u, v = np.meshgrid(g, g)
    pts = sample_emitter(lt, u.ravel(), v.ravel())[0]
    rel = pts[None] - o[:, None]
    t = np.maximum(np.einsum("nkc,nc->nk", rel, d), 0.0)
    brute = np.linalg.norm(rel - t[..., None] * d[:, None], axis=-1).min(axis=1)
    spacing = np.sqrt(2.0) / (cubature.PROBES - 1)
    # both are grids: each is within its diagonal spacing above the true distance
    assert np.all(dist >= brute - np.sqrt(2.0) / 200) and np.all(dist <= brute + spacing)


def test_emissive_levels_split_each_triangle_in_four():
    tri = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, 0.0]]])
    for level in range(3):
        rows = emissive.rows(tri, [1.0, 1.0, 1.0], False, "x", level)
        assert len(rows.kind) == 7 * 4 ** level == emissive.count(tri, False, level)
        assert abs(rows.intensity[:, 0].sum() - 1.0) <= 1e-14  # the area
        np.testing.assert_array_equal(rows.axis, np.tile([0.0, 0.0, 1.0], (len(rows.kind), 1)))
    fine = emissive.subdivide(tri, 2)
    assert fine.shape == (16, 3, 3)
    np.testing.assert_allclose(0.5 * np.abs(np.cross(fine[:, 1] - fine[:, 0], fine[:, 2] - fine[:, 0])[:, 2]), 1.0 / 16)


def test_scenes_without_area_lights_have_no_pilot():
    sc = scene([{"position": [0.0, 1.5, 0.0], "intensity": 1.0}], camera=SMALL)
    r = api.render(sc, "analytic")
    assert not any(k.startswith("cubature") for k in r.stats)
