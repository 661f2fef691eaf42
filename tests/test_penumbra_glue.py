"""The penumbrae's glue kernels (shadows/penumbra_airlight.py `lit_states` and `light_boxes`,
segments.py `pieces`) against the NumPy expressions they replace, written out here: bit for bit, on
segments that end and segments to infinity, directions with zero components, keys without segments.
The emitter samples' lit pieces (frusta.point_lit_pieces, each triangle's frustum clipped to the
segment directly) against the walk they replace, written out here around frusta's own `_frusta` and
`_lit` kernels (a cube map of one texel a face listing every candidate): bit for bit."""
import numpy as np

from raytrace.methods import Segments
from raytrace.segments import CONE_STREAM, pieces
from raytrace.shadows import frusta
from raytrace.shadows.frusta import GAP_REL, point_lit_pieces
from raytrace.shadows.penumbra_airlight import DARK, LIT, MIXED, NONE, light_boxes, lit_states

from .test_exact_shadows import BARS, SLIT, room_scene, segments


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


def _walked(accel, segs, points, group, box):
    """The lit pieces (segment, x0, x1) as `point_lit_pieces` found them before its direct clip: per
    segment the triangles whose bounding boxes meet its group's box and that meet the plane through
    its point and its line (within GAP_REL), their frusta (`_frusta`), listed in ascending depth
    lower bound in each face of a cube map of one texel a face, no cover, walked by `_lit`."""
    frusta_, _, lit_ = frusta._kernels(frusta.POINTS)
    tris = accel.triangles[accel.sphere_of < 0]
    t_lo, t_hi = tris.min(axis=1), tris.max(axis=1)
    gap, slack = GAP_REL * accel.scale, frusta.REL * accel.scale
    grid = np.array([-1.0, -1.0, 2.0, 2.0, 1.0, 1.0])
    out = [[], [], []]
    for s in range(len(segs)):
        g = group[s]
        cand = tris[np.all((t_hi >= box[0][g]) & (t_lo <= box[1][g]), axis=1)]
        L, w = points[s], segs.dirs[s]
        q = segs.origins[s] - L
        n = np.array([q[1] * w[2] - q[2] * w[1], q[2] * w[0] - q[0] * w[2], q[0] * w[1] - q[1] * w[0]])
        tol = gap * np.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
        side = n[0] * (cand[..., 0] - L[0]) + n[1] * (cand[..., 1] - L[1]) + n[2] * (cand[..., 2] - L[2])
        straddle = np.ascontiguousarray(cand[np.any(side > -tol, axis=1) & np.any(side < tol, axis=1)])
        ns = len(straddle)
        planes, signs, lb, keep = np.zeros((ns, 4, 4)), np.zeros((ns, 4)), np.zeros(ns), np.zeros(ns, bool)
        frusta_(straddle, L, np.zeros(3), accel.epsilon, planes, signs, lb, keep, False)
        nk = int(keep.sum())
        order = np.argsort(lb[keep], kind="stable")
        frame = np.vstack([L, np.eye(3)])
        src, x0, x1 = lit_(segs.origins[s:s + 1], segs.dirs[s:s + 1], segs.length[s:s + 1], grid, frame,
                           np.arange(7, dtype=np.int64) * nk, np.tile(order, 6).astype(np.int64),
                           np.tile(lb[keep][order], 6), np.full(6, -1, np.int64), np.full(6, np.inf),
                           np.ascontiguousarray(planes[keep]), np.ascontiguousarray(signs[keep]), slack, gap,
                           np.zeros(len(frusta.STATS_NAMES)), False)
        for a, b in zip(out, (src + s, x0, x1)):
            a.append(b)
    return tuple(np.concatenate(a) for a in out)


def test_point_lit_pieces_are_the_walks():
    """Camera rays of a room with a slit and bars (segments that end on the walls) and random segments
    (some to infinity, some of length 0), each under its own point, four segments a group: the same
    pieces bit for bit, some segments cut into several. No segment's line passes through its point:
    there the normal of the plane through them is 0 in NumPy's rounding but not always in the kernel's
    (the package's fastmath subset contracts a product and a difference), so `_walked`'s candidates
    could differ from the kernel's for reasons of its own."""
    prep, cam, _ = segments(room_scene(SLIT + BARS))
    rng = np.random.default_rng(4)
    n = 3 * len(cam)
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    length = rng.uniform(0.0, 6.0, n)
    length[::7], length[1::11] = np.inf, 0.0
    origins = rng.uniform(-2.5, 2.5, (n, 3))
    both = Segments(np.concatenate([cam.origins, origins]), np.concatenate([cam.dirs, dirs]),
                    np.concatenate([cam.length, length]), np.arange(len(cam) + n, dtype=np.int64),
                    np.arange(len(cam) + n, dtype=np.int64), np.zeros(len(cam) + n), np.zeros(len(cam) + n, np.uint64),
                    np.zeros(len(cam) + n, np.int64), 0, prep.accel.scale)
    points = np.array([0.0, 1.5, -1.0]) + rng.uniform(-0.4, 0.4, (len(both), 3))
    group = both.light // 4
    box = light_boxes(points, both, 4)
    got = point_lit_pieces(prep.accel, both, points, group, box, None)
    want = _walked(prep.accel, both, points, group, box)
    for a, b in zip(got, want):
        assert a.dtype == b.dtype and np.array_equal(a, b)
    counts = np.bincount(got[0], minlength=len(both))
    assert (counts == 0).any() and (counts == 1).any() and (counts >= 3).any()
