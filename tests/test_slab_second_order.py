"""The second-order exclusion of the refracted point-light searches (media/slab.py): `edge_breaks`' own
isolation (`_sign_changes`), as `_isolate`'s for the bound (edges), excludes an interval whose ends'
values share a sign and exceed M (hi - lo)^2 / 8 (`_off_band`), M a bound on the edge distance's second
derivative (`fermat_bend`, checked in tests/test_refracted_edge_isolation.py); a spot's cone levels
(`cone_bend`): tests/test_cone_second_order.py.

Where the refraction point slides along an edge's line over a long stretch, the first-order test (the point's speed) excludes only intervals shorter
than the distance over the speed: the search ran out of its MAX_ISOLATE evaluations there. The
tests count the evaluations of both (the first-order search alone: `_off_band` replaced by a refusal,
on the search's Python body) and check that they find the same breaks as a dense scan.
"""
import math

import mpmath as mp
import numpy as np
import pytest

from raytrace.media import slab

mp.mp.dps = 30


class Counted:
    """`_sign_changes`' Python body with its evaluations counted; `first`: with the first-order test alone."""

    def __init__(self, monkeypatch, first):
        self.n = 0
        monkeypatch.setattr(slab, "_edge_newton", self.counting(slab._edge_newton))
        monkeypatch.setattr(slab, "_sign_changes", slab._sign_changes.py_func)
        if first:
            monkeypatch.setattr(slab, "_off_band", lambda *args: False)

    def counting(self, f):
        def call(*args):
            self.n += 1
            return f(*args)
        return call


EDGE = 0.3  # the light's foot and the segment's line lie at y = EDGE: every refraction point does too


def sliding_edge(offset, slope):
    """A face row (plane z = 0, light at height 1 above y = EDGE, the segment at depth 0.4 along x from
    x = -1.5 to 0.5 at y = EDGE: R(x) runs along the line y = EDGE) and the planes (the face's, and an edge
    plane (slope, 1, 0) at y = EDGE + offset at x = 0: R at distance ~offset from its line, crossing it
    once where slope != 0)."""
    n_g = np.array([slope, 1.0, 0.0]) / math.hypot(slope, 1.0)
    planes = np.array([[0.0, 0.0, 1.0, 0.0], [*n_g, n_g[1] * (EDGE + offset)]])
    geo = np.zeros(slab.GEO_COLUMNS)
    geo[:3], geo[3:6], geo[6:9] = (-1.5, EDGE, -0.4), (1.0, 0.0, 0.0), (2.5, EDGE, 1.0)
    geo[12:14] = slab.NO_CONE
    faces = np.empty((2, slab.FACE_COLUMNS))
    m = slab.refracting_faces(geo, planes, 0.0, 0.0, 0.0, 0.0, slab.NO_SPOT, faces)
    assert faces[0, 17] == 0 and m >= 1
    return faces[0], planes


def scanned(f, end, n=20001):
    """The sign changes of f on n samples over [0, end], bisected."""
    xs = np.linspace(0.0, end, n)
    v = np.array([f(x) for x in xs])
    out = []
    for i in np.nonzero(v[:-1] * v[1:] < 0.0)[0]:
        lo, hi = xs[i], xs[i + 1]
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if f(mid) * v[i] > 0.0 else (lo, mid)
        out.append(0.5 * (lo + hi))
    return out


def searched(monkeypatch, search):
    """(evaluations, sorted breaks) of search(out) -> count, with the first-order test alone and with both."""
    counts, found = [], []
    for first in (True, False):
        counter = Counted(monkeypatch, first)
        out = np.empty(16)
        k = search(out)
        counts.append(counter.n)
        found.append(np.sort(out[:k]))
        monkeypatch.undo()
    return counts, found


@pytest.mark.parametrize("slope, crossings", [(0.0, 0), (1e-2, 1)])
def test_an_edge_line_the_point_slides_along(monkeypatch, slope, crossings):
    """The refraction point runs 1e-5 from an edge's line along the whole segment (slope 0) or crosses it
    once (slope 1e-2: 1e-5 off a millimetre's run of R away): without a crossing, the first-order search
    takes its MAX_ISOLATE evaluations and the second-order one under 5 % of them; with one, under half of
    the first order's; both find the scan's breaks to 1e-9."""
    row, planes = sliding_edge(1e-5, slope)
    end = 2.0
    truth = scanned(lambda x: slab._edge_value(x, row, planes, 1, 1.5), end)
    assert len(truth) == crossings
    counts, found = searched(monkeypatch, lambda out: slab.edge_breaks.py_func(row, planes, 1.5, end, out))
    if crossings:
        assert counts[1] < 0.5 * counts[0], counts
    else:
        assert counts[0] >= slab.MAX_ISOLATE and counts[1] < 0.05 * slab.MAX_ISOLATE, counts
    for cuts in found:
        assert len(cuts) == len(truth) and np.all(np.abs(cuts - truth) < 1e-9), (cuts, truth)
