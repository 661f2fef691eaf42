"""An exact 0 in `edge_breaks`' isolation of an edge crossing (media/slab.py `_sign_changes`): where the
refraction point crosses the line of another face's plane, the computed edge distance (n_g·R - c_g less
the face test's tolerance) may lie on 0 exactly at the shared end of two of the search's smallest
intervals; neither interval then has a strict sign change, and a search that took only strict ones lost
the crossing (no cut: the integrand's switch inside a piece, which `_isolate` finds for the bound and
calls inf). The search cuts at that end (where a run of 0s begins or ends), as `_cone_crossings` does at a
spot's cone level (tests/test_cone_second_order.py).

The function is `sliding_edge`'s (tests/test_slab_second_order.py: R runs along y = 0.3 and crosses an
edge line of slope 1e-2 once) with its value set to 0 exactly at the node of the smallest intervals
nearest its root, or at a run of three nodes about it; the cuts must lie in the run and within it of the
root of the exact distance (Snell's law by mpmath, 30 digits, on the row's numbers).
"""
import math

import mpmath as mp
import numpy as np
import pytest

from raytrace.media import slab

from .test_refracted_edge_isolation import fermat_point
from .test_slab_second_order import EDGE, scanned, sliding_edge

mp.mp.dps = 30
ETA, END = 1.5, 2.0


def exact_root(planes, guess):
    """The root near guess of the edge distance of `sliding_edge`'s segment (-1.5, EDGE, -0.4) + x (1, 0, 0)
    under its light (2.5, EDGE, 1) with R Fermat's point on z = 0: n_g·R - c_g - EDGE_TOL (|c_g| + |R|_1)."""
    n0, n1, c = (mp.mpf(float(v)) for v in (planes[1, 0], planes[1, 1], planes[1, 3]))

    def distance(x):
        R = fermat_point([mp.mpf(-1.5) + x, mp.mpf(EDGE), mp.mpf(-0.4)], [mp.mpf(2.5), mp.mpf(EDGE), mp.mpf(1.0)],
                         mp.mpf(ETA))
        return n0 * R[0] + n1 * R[1] - c - mp.mpf(slab.EDGE_TOL) * (abs(c) + abs(R[0]) + abs(R[1]))
    return float(mp.findroot(distance, mp.mpf(guess)))


def search_sizes(row, planes):
    """(the size S `edge_breaks` gives plane 1, the width h of the search's smallest intervals: END halved
    until at most 1e-13 S)."""
    size = math.sqrt(row[8] ** 2 + row[9] ** 2 + row[10] ** 2) + END + math.sqrt(row[4]) + abs(planes[1, 3])
    return size, END / 2.0 ** math.ceil(math.log2(END / (1e-13 * size)))


def zeroed(monkeypatch, nodes):
    """`_sign_changes`' and `_bisect`'s Python bodies, with `_edge_value` and `_edge_newton` exactly 0 at nodes."""
    for name in ("_edge_value", "_edge_newton"):
        real = getattr(slab, name)
        monkeypatch.setattr(slab, name, lambda x, *args, f=real: 0.0 if x in nodes else f(x, *args))
    for name in ("_sign_changes", "_bisect"):
        monkeypatch.setattr(slab, name, getattr(slab, name).py_func)


@pytest.mark.parametrize("run", [1, 3])
def test_an_exact_zero_at_a_node_is_a_crossing(monkeypatch, run):
    """A 0 at the node nearest the root (run 1) or at three nodes about it (run 3): `_sign_changes` cuts
    once at the node (run 1) or at the run's ends (once or twice), each within the run and within 2 h of
    mpmath's root; `edge_breaks` keeps them (one: bisected from the segment's ends, within h of the root).
    Without the 0s both find the root to 1e-13."""
    row, planes = sliding_edge(1e-5, 1e-2)
    truth = scanned(lambda x: slab._edge_value(x, row, planes, 1, ETA), END)
    assert len(truth) == 1
    root = exact_root(planes, truth[0])
    size, h = search_sizes(row, planes)
    node = round(root / h) * h
    nodes = [node + k * h for k in range(-(run // 2), run // 2 + 1)]
    assert all(slab._edge_value(x, row, planes, 1, ETA) != 0.0 for x in nodes)  # the 0s are this test's
    out = np.empty(16)
    for zeros in ([], nodes):
        monkeypatch.undo()
        zeroed(monkeypatch, set(zeros))
        m = slab._sign_changes(row, planes, 1, ETA, END, 2e-14 * size, 1e-14 * size, 1e-13 * size, out, 0)
        cuts = out[:m].copy()
        k = slab.edge_breaks.py_func(row, planes, ETA, END, out)
        if not zeros:
            assert m == k == 1 and abs(cuts[0] - root) < 1e-13 and abs(out[0] - root) < 1e-13, (cuts, out[0], root)
            continue
        assert 1 <= m <= 2 and (m == 1 or run > 1), (cuts, nodes)
        assert all(nodes[0] <= c <= nodes[-1] and abs(c - root) < 2.0 * h for c in cuts), (cuts, nodes, root)
        assert k == m and (abs(out[0] - root) < h if k == 1 else np.array_equal(out[:k], cuts)), (out[:k], cuts)
