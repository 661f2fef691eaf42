"""`quadrature`'s error bound in height fog and atmospheres (issue 35, docs/error_bounds.md) against
30-digit twins written from the formulas alone (tests/make_bound_twins.py, stored in
tests/data/bound_twins.json): on every ray of the grids (height fog of both profiles under a lamp
and the sun: rays up, down, horizontal, grazing, near the lamp; small and Earth-sized atmospheres
under the sun: from the ground, from space, grazing the limb) |value - twin| <= bound at rtol 1e-6
and 1e-10 (and 1e-13, where the rounding terms dominate), and the bound is not vacuous: its median
is at most 10 rtol of the value. Chapman's remainder bound holds against mpmath and its table
against a grid; renders of the bundled height fog and atmospheres are bounded wherever finite.
"""
import json
import math
from pathlib import Path

import mpmath as mp
import numpy as np
import pytest

import raytrace
from raytrace import error_bounds
from raytrace.lights import Lights
from raytrace.media import chapman
from raytrace.methods import Segments, registry
from raytrace.scene.format import scene_from_dict

DATA = json.loads((Path(__file__).parent / "data" / "bound_twins.json").read_text())["rays"]


def _evaluate(rays, rtol):
    """(value, bound, twin) arrays of the stored rays, each ray one segment of its own scene."""
    out = []
    for ray in rays:
        scene = scene_from_dict({"camera": {"position": [0.0, 0.0, 0.0], "look_at": [0.0, 0.0, -1.0], "width": 1,
                                            "height": 1}, "light": [ray["light"]], "medium": ray["medium"]}, "twin")
        length = math.inf if ray["length"] is None else ray["length"]
        segs = Segments(np.array([ray["origin"]], float), np.array([ray["dir"]], float), np.array([length]),
                        np.zeros(1, np.int64), np.zeros(1, np.int64), np.zeros(1), np.zeros(1, np.uint64),
                        np.zeros(1, np.int64), scale=10.0)
        radiance, _, bound = registry()["quadrature"].airlight(segs, scene.medium, Lights.of(scene.lights),
                                                               {"rtol": rtol})
        out.append((radiance[0, 0], bound[0, 0], float(mp.mpf(ray["twin"]))))
    return np.array(out).T


@pytest.mark.parametrize("kind", ["fog", "atmosphere"])
@pytest.mark.parametrize("rtol", [1e-6, 1e-10])
def test_bound_holds_and_is_not_vacuous(kind, rtol):
    rays = [r for r in DATA if r["case"].startswith(kind)]
    value, bound, twin = _evaluate(rays, rtol)
    assert len(rays) >= 14 and np.all(twin > 0.0) and np.all(np.isfinite(bound))
    over = np.abs(value - twin) > bound
    assert not over.any(), [r["case"] for r, o in zip(rays, over) if o]
    assert np.median(bound / value) <= 10.0 * rtol


@pytest.mark.parametrize("kind", ["fog", "atmosphere"])
def test_bound_holds_where_rounding_dominates(kind):
    rays = [r for r in DATA if r["case"].startswith(kind)]
    value, bound, twin = _evaluate(rays, 1e-13)
    over = np.abs(value - twin) > bound
    assert not over.any(), [r["case"] for r, o in zip(rays, over) if o]


def test_an_error_beyond_the_bound_fails():
    """The check can fail: a value 3 rtol off its twin is outside its bound at rtol 1e-6."""
    value, bound, twin = _evaluate(DATA, 1e-6)
    assert np.all(np.abs(value * (1.0 + 3e-6) - twin) > bound)


@pytest.mark.parametrize("a, beta, u", [(0.0, 3.0, math.inf), (0.0, 3.0, 12.0), (0.5, 2.8, math.inf),
                                        (28.0, 10.0, math.inf), (2500.0, 10.0, 25.0), (0.0, 1e6, math.inf),
                                        (1.7, 0.1, 50.0), (3.0, 800.0, 0.3)])
def test_chapman_remainder_bound_holds(a, beta, u):
    """rise_integral against an mpmath quad of its integral (30 digits): within the remainder bound
    plus the rule's rounding, and within `relative_error` of its z = a^2 + beta."""
    mp.mp.dps = 30
    y = lambda uu: uu / (mp.sqrt(a * a + uu) + a)
    g = lambda t: 2 * mp.exp(-t * (2 * a + t)) * (beta + (a + t) ** 2) / mp.sqrt(2 * beta + (a + t) ** 2)
    end = mp.inf if u == math.inf else y(mp.mpf(u))
    exact = mp.quad(g, [0, y(mp.mpf(min(u, 10.0))), end])
    err = abs(chapman.rise_integral(a, beta, u) / float(exact) - 1.0)
    assert err <= chapman.remainder_bound(a, beta, u) + chapman.RULE_ROUNDING
    assert err <= chapman.relative_error(a * a + beta)


def test_chapman_remainder_table_holds_on_a_grid():
    """`REMAINDER` is at least the remainder bound over a grid of the domain (z >= 3)."""
    for z in np.geomspace(3.0, 1e9, 10):
        bound = chapman.relative_error(z) - chapman.RULE_ROUNDING
        for a in [0.0, *np.geomspace(1e-3, math.sqrt(z), 7)]:
            for u in (1e-3, 0.5, 10.0, 30.0, math.inf):
                assert chapman.remainder_bound(a, max(z - a * a, 0.0), u) <= bound


@pytest.mark.parametrize("scene, crop", [("valley_fog", (150, 60, 172, 76)), ("sunrise", (100, 60, 116, 72)),
                                         ("planet_from_space", (60, 60, 76, 72))])
def test_bundled_fog_and_atmospheres_are_bounded(scene, crop):
    img = raytrace.render(scene, "quadrature", crop=crop, threads=1)
    finite = np.isfinite(img.array)
    assert finite.all() and np.all(np.isfinite(img.error_bound))
    assert img.stats[error_bounds.INFINITE_STAT] == 0
