"""`quadrature`'s error bound inside shapes holding a medium (issue 35, docs/error_bounds.md) against
30-digit twins written from the geometry alone (tests/make_inside_bound_twins.py, stored in
tests/data/inside_bound_twins.json): inside segments of a box lit by a point light and a spot
(convex: media/slab.py convex_bounded), of an icosahedron (a convex mesh of 20 faces), of an
icosphere (80 faces: its paths on the facet walk's planes, interiors/paths.py) and of a
U-shaped prism (non-convex: Embree-traced paths, interiors/paths.py, whose float32 crossings are in
the bound) and of an exact sphere (media/slab.py's kernel on its closed-form chords, sphere_rounding)
lit by a point light and a spot. On every segment |value - twin| <= bound at rtol 1e-6
and 1e-10, and the bound is not vacuous: its median is at most 10 rtol of the value; a value 3 rtol
off its twin fails. The bound is finite on every segment (the U's walks settle their hits on the
triangle that holds them, so none is repeated from a moved end). Renders of the convex shapes have no
pixel with an infinite bound.
"""
import json
from pathlib import Path

import mpmath as mp
import numpy as np
import pytest

from raytrace import error_bounds
from raytrace.interiors import crossing, rows
from raytrace.methods import registry
from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_dict

DATA = json.loads((Path(__file__).parent / "data" / "inside_bound_twins.json").read_text())
CASES = sorted({r["case"] for r in DATA["rays"]})


def _scene(case, width=1, height=1):
    shape = DATA["shapes"][case.rsplit("_", 1)[0]] | {"interior": DATA["media"]["interior"]}
    return scene_from_dict({"camera": {"position": [0.0, 1.2, 2.8], "look_at": [0.0, 0.0, 0.0], "width": width,
                                       "height": height, "spp": 1},
                            "medium": DATA["media"]["outside"], "shape": [shape], "light": [DATA["lights"][case]]},
                           case)


def _evaluate(case, rtol):
    """(value, bound, twin) of the stored segments of a case, channel 0 (the medium is grey), the
    inside rows as the boundary crossing makes them, integrated as a render does."""
    rays = [r for r in DATA["rays"] if r["case"] == case]
    prep = prepare(_scene(case))
    n = len(rays)
    segs = crossing._rows(prep, 0, np.array([r["origin"] for r in rays]), np.array([r["normal"] for r in rays]),
                          np.array([r["dir"] for r in rays]), np.array([r["length"] for r in rays]),
                          np.zeros(n, np.uint64))
    value, _, bound, _ = rows.integrate(prep, registry()["quadrature"], {"rtol": rtol}, segs, 0, 0, False)
    twin = np.array([float(mp.mpf(r["twin"])) for r in rays])
    assert np.all(value[:, 1:] == value[:, :1])
    return value[:, 0], bound[:, 0], twin


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("rtol", [1e-6, 1e-10])
def test_bound_holds_and_is_not_vacuous(case, rtol):
    value, bound, twin = _evaluate(case, rtol)
    assert len(value) >= 15 and np.all(twin > 0.0) and np.all(np.isfinite(bound))
    over = np.abs(value - twin) > bound
    assert not over.any(), (np.abs(value - twin) / bound)[over]
    assert np.median(bound / value) <= 10.0 * rtol


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("rtol", [1e-6, 1e-10])
def test_an_error_beyond_the_bound_fails(case, rtol):
    """The check can fail: a value 3 rtol off its twin is outside its (finite) bound."""
    value, bound, twin = _evaluate(case, rtol)
    finite = np.isfinite(bound)
    assert np.all(np.abs(value * (1.0 + 3.0 * rtol) - twin)[finite] > bound[finite])


@pytest.mark.parametrize("case", ["box_spot", "icosahedron_lamp", "icosphere_lamp", "sphere_spot"])
def test_renders_with_interiors_are_bounded(case):
    """Every pixel of a quadrature render of a convex shape (its boundary crossed, the inside rows, what
    lies behind) has a finite bound; it was infinite on every pixel that sees the shape."""
    res = render(prepare(_scene(case, 12, 8)), "quadrature", {}, RenderOptions(threads=1))
    assert res.stats[error_bounds.INFINITE_STAT] == 0 and np.all(np.isfinite(res.error_bound))
    assert np.count_nonzero(res.image > 0.0) > 20
