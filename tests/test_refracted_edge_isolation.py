"""The edge isolation of a lamp's refraction point through a face of a convex refractive shape
(media/slab.py `_isolate`): where the refraction point slides along an edge's line, close to it over
a long stretch, the first-order exclusion (the point's speed) cannot close within its budget; the
second-order one (`fermat_bend`, a bound on the point's acceleration) does.

`fermat_bend` is checked against Fermat's principle alone: the refraction point R on the plane z = 0
minimises |L - R| + eta |R - X| (mpmath, 30 digits, findroot on its gradient), differentiated twice in x
along the segment X(x) = p + x w by mpmath; the bound over each interval from its ranges of rho (the
horizontal distance to the light) and depth must hold at every sampled point.

The pixels whose bound was infinite (a lamp into the 512-plane glass UV ball, 32x24) are rendered alone
and compared with tests/test_refracted_mesh_faces.py's Fermat/triangle twin: bound finite, above the
error, not vacuous. Slow (the twin's Fermat paths over the ball's triangles, ~1 min a pixel): `python -m
pytest -m slow tests/test_refracted_edge_isolation.py`.
"""
import math

import mpmath as mp
import numpy as np
import pytest

from raytrace.media import slab
from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text

from .conftest import to_toml
from .test_refracted_mesh_faces import twin_pixel
from .test_refracted_uv_ball_sun import uv_ball, uv_triangles

mp.mp.dps = 30


def fermat_point(X, L, eta):
    """R (x, y) on the plane z = 0 minimising |L - R| + eta |R - X| (L above, X below)."""
    def grad(rx, ry):
        o = mp.sqrt((L[0] - rx) ** 2 + (L[1] - ry) ** 2 + L[2] ** 2)
        k = mp.sqrt((X[0] - rx) ** 2 + (X[1] - ry) ** 2 + X[2] ** 2)
        return [(rx - L[0]) / o + eta * (rx - X[0]) / k, (ry - L[1]) / o + eta * (ry - X[1]) / k]
    return mp.findroot(grad, (X[0] + 0.5 * (L[0] - X[0]), X[1] + 0.5 * (L[1] - X[1])))


def acceleration(p, w, L, eta, x):
    """|R''(x)| by mpmath's differentiation of Fermat's point along p + x w."""
    def coord(i):
        return lambda t: fermat_point([p[j] + t * w[j] for j in range(3)], L, eta)[i]
    return float(mp.sqrt(mp.diff(coord(0), x, 2) ** 2 + mp.diff(coord(1), x, 2) ** 2))


def test_the_bend_bound_holds():
    """Random segments below the plane z = 0 and lights above it (heights 1e-3 to 2, eta 1.33 to 2):
    |R''| at 5 points of each of 3 sub-intervals never exceeds the interval's `fermat_bend` (and is not
    far below it somewhere: the bound is within 30x of the largest sampled value)."""
    rng = np.random.default_rng(3)
    ratios = []
    for case in range(12):
        eta = float(rng.uniform(1.33, 2.0))
        hl = float(10.0 ** rng.uniform(-3.0, 0.3))
        L = [mp.mpf(float(v)) for v in rng.uniform(-1.0, 1.0, 2)] + [mp.mpf(hl)]
        z0 = float(rng.uniform(0.05, 1.0))
        w = rng.normal(size=3)
        w[2] = -abs(w[2])  # downwards: deeper along the segment
        w /= np.linalg.norm(w)
        p = np.array([*rng.uniform(-2.0, 2.0, 2), -z0])
        a = -float(w[2])  # -w.n, n = +z
        ends = np.linspace(0.0, 1.5, 4)
        for lo, hi in zip(ends[:-1], ends[1:]):
            xs = np.linspace(lo, hi, 5)
            rho = [math.hypot(p[0] + x * w[0] - float(L[0]), p[1] + x * w[1] - float(L[1])) for x in
                   np.linspace(lo, hi, 2001)]
            z = (z0 + a * lo, z0 + a * hi)
            bound = slab.fermat_bend(min(rho), max(rho), min(z), max(z), a, hl, eta, 0.0)
            acc = [acceleration([mp.mpf(float(v)) for v in p], [mp.mpf(float(v)) for v in w], L, eta, mp.mpf(float(x)))
                   for x in xs]
            assert max(acc) <= bound, (case, lo, max(acc), bound)
            ratios.append(bound / max(acc))
    assert min(ratios) < 30.0, min(ratios)


LAMP_BALL = {"medium": {"sigma_a": 0.02}, "light": [{"type": "point", "position": [2.0, 2.0, 1.0], "intensity": 5.0}]}


@pytest.mark.slow
@pytest.mark.parametrize("i, j", [(16, 1), (21, 7), (7, 12)])
def test_a_refraction_point_along_an_edge_is_bounded(i, j):
    """The three pixels of a lamp into the 512-plane glass UV ball at 32x24 whose bound was infinite (one
    face's edge isolation each ran out of evaluations): finite, above the error against the twin, at most
    10 rtol of the value; the value within 1e-6 of it (rtol 1e-6)."""
    scene = uv_ball(32, 32, 24) | LAMP_BALL
    geometry = uv_triangles(scene)[:3]
    ref = twin_pixel(scene, geometry, i, j)[0]
    res = render(prepare(scene_from_text(to_toml(scene), scene["name"])), "quadrature", {"rtol": 1e-6},
                 RenderOptions(threads=1, crop=(i, j, i + 1, j + 1)))
    value, bound = res.image.reshape(-1, 3)[-1], res.error_bound.reshape(-1, 3)[-1]
    err = np.abs(value - ref)
    assert np.all(ref > 0.0)
    assert np.all(np.isfinite(bound)) and np.all(err <= bound), (err, bound)
    assert np.all(bound <= 1e-5 * ref), bound / ref
    assert np.all(err <= 1e-6 * ref), err / ref
