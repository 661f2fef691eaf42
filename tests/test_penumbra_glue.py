"""The penumbrae's glue kernels (shadows/penumbra_airlight.py `lit_states` and `light_boxes`,
segments.py `pieces`) against the NumPy expressions they replace, written out here: bit for bit, on
segments that end and segments to infinity, directions with zero components, keys without segments."""
import numpy as np

from raytrace.methods import Segments
from raytrace.segments import CONE_STREAM, pieces
from raytrace.shadows.frusta import GAP_REL
from raytrace.shadows.penumbra_airlight import DARK, LIT, MIXED, NONE, light_boxes, lit_states


def _segments(rng, n, scale=3.0):
    dirs = rng.normal(size=(n, 3))
    dirs[::5, 1] = 0.0  # zero components: a segment to infinity stays at its start along them
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    length = rng.uniform(0.0, 4.0, n)
    length[::3] = np.inf
    return Segments(rng.normal(size=(n, 3)), dirs, length, np.arange(n, dtype=np.int64), rng.integers(0, 7, n),
                    rng.uniform(0.0, 2.0, n), rng.integers(0, 2**63, n, dtype=np.uint64), rng.integers(0, 50, n),
                    3, scale)


def _numpy_states(cone, lit, cone_key, lit_key, size):
    far = np.zeros(size)
    np.maximum.at(far, cone_key, cone.t0)
    np.maximum.at(far, lit_key, lit.t0)
    far += cone.scale

    def measure(segs, key):
        return np.where(np.isinf(segs.length), far[key] - segs.t0, segs.length)

    count = np.bincount(cone_key, minlength=size)
    total = np.bincount(cone_key, weights=measure(cone, cone_key), minlength=size)
    covered = np.bincount(lit_key, weights=measure(lit, lit_key), minlength=size)
    tol = 2.0 * GAP_REL * far * count
    return np.where(count == 0, NONE, np.where(covered >= total - tol, LIT, np.where(covered <= tol, DARK, MIXED)))


def _numpy_boxes(points, segs, per_box):
    pts = points.reshape(-1, per_box, 3)
    lo, hi = pts.min(axis=1), pts.max(axis=1)
    b = segs.light // per_box
    finite = np.isfinite(segs.length)
    end = segs.origins + np.where(finite, segs.length, 0.0)[:, None] * segs.dirs
    end = np.where(finite[:, None], end, np.where(segs.dirs > 0.0, np.inf, np.where(segs.dirs < 0.0, -np.inf, end)))
    for p in (segs.origins, end):
        np.minimum.at(lo, b, p)
        np.maximum.at(hi, b, p)
    return lo, hi


def test_lit_states_are_numpys():
    rng = np.random.default_rng(1)
    cone = _segments(rng, 400)
    src = rng.integers(0, len(cone), 700)
    x0 = rng.uniform(0.0, 1.0, len(src))
    lit = cone.take(src)
    lit = Segments(lit.origins, lit.dirs, np.where(rng.random(len(src)) < 0.2, np.inf, x0), lit.light, lit.ray,
                   lit.t0 + x0, lit.keys, lit.stream, lit.seed, lit.scale)
    size = 9  # keys 7 and 8 have no segment: NONE
    got = lit_states(cone, lit, cone.ray, lit.ray, size)
    assert np.array_equal(got, _numpy_states(cone, lit, cone.ray, lit.ray, size))
    # whole keys: every state occurs
    full = lit_states(cone, cone, cone.ray, cone.ray, size)
    assert np.array_equal(full, _numpy_states(cone, cone, cone.ray, cone.ray, size))
    assert set(full[:7]) == {LIT} and set(full[7:]) == {NONE}
    empty = cone.take(np.zeros(0, np.int64))
    assert np.array_equal(lit_states(cone, empty, cone.ray, empty.ray, size),
                          _numpy_states(cone, empty, cone.ray, empty.ray, size))
    assert set(got) >= {MIXED} and DARK in lit_states(cone, empty, cone.ray, empty.ray, size)


def test_light_boxes_are_numpys():
    rng = np.random.default_rng(2)
    per_box, boxes = 8, 12
    points = rng.normal(size=(per_box * boxes, 3))
    segs = _segments(rng, per_box * boxes)
    keep = np.sort(rng.choice(len(segs), 60, replace=False))  # some rows without a segment, some boxes empty
    keep = keep[segs.light[keep] // per_box != 4]
    for s in (segs, segs.take(keep), segs.take(np.zeros(0, np.int64))):
        lo, hi = light_boxes(points, s, per_box)
        want_lo, want_hi = _numpy_boxes(points, s, per_box)
        assert np.array_equal(lo, want_lo) and np.array_equal(hi, want_hi)
        assert np.isinf(hi).any() or not np.isinf(s.length).any()


def test_pieces_are_numpys():
    rng = np.random.default_rng(3)
    segs = _segments(rng, 300)
    src = np.sort(rng.integers(0, len(segs), 500))
    x0 = rng.uniform(0.0, 1.0, len(src))
    x1 = x0 + rng.uniform(0.0, 1.0, len(src))
    piece = rng.integers(0, 2, len(src))
    step = CONE_STREAM * 5
    for got, stream in ((pieces(segs, src, x0, x1, piece, step), segs.stream[src] + step * piece),
                        (pieces(segs, src, x0, x1), segs.stream[src])):
        want = (segs.origins[src] + x0[:, None] * segs.dirs[src], segs.dirs[src], x1 - x0, segs.light[src],
                segs.ray[src], segs.t0[src] + x0, segs.keys[src], stream)
        for a, b in zip((got.origins, got.dirs, got.length, got.light, got.ray, got.t0, got.keys, got.stream), want):
            assert a.dtype == b.dtype and np.array_equal(a, b)
        assert (got.seed, got.scale) == (segs.seed, segs.scale)
