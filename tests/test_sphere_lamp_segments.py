"""The occluder test of a camera ray's segment against a sphere emitter (`sphere_occluders.segments_free`)
against brute force built from the geometry alone (numpy): random segments and small triangles about
the region between them and the lamp; a triangle that a segment from a point of the camera ray's segment
to a point of the sphere crosses, or one with a point in the convex hull of the segment and the ball (by
a scan of that hull's slices), must make the segment "may be hidden"; where neither, the test clears all
but the triangles that graze the hull between the samples. A floor the segments end on hides nothing."""
from __future__ import annotations

import math

import numpy as np

from raytrace.lights import sphere_occluders

C, R = np.array([0.0, 1.0, 0.0]), 0.3
EPS = 1e-5  # the shadow rays' offset given to the test


def sphere_points(count: int) -> np.ndarray:
    k = np.arange(count) + 0.5
    z, phi = 1.0 - 2.0 * k / count, math.pi * (1 + 5 ** 0.5) * k  # a spiral, uniform in area
    s = np.sqrt(1.0 - z * z)
    return C + R * np.stack([s * np.cos(phi), z, s * np.sin(phi)], axis=1)


def crossed(a, b, ys, tri) -> bool:
    """Whether a segment from one of 41 points of [a, b] to one of the points ys of the sphere that it
    sees (in front of the sphere's tangent plane there) meets the triangle (Moller-Trumbore, away from
    its start)."""
    xs = a + np.linspace(0.0, 1.0, 41)[:, None] * (b - a)
    x = np.repeat(xs, len(ys), axis=0)
    y = np.tile(ys, (len(xs), 1))
    seen = np.einsum("ij,ij->i", y - C, x - y) > 0.0
    x, w = x[seen], (y - x)[seen]
    e1, e2 = tri[1] - tri[0], tri[2] - tri[0]
    p = np.cross(w, e2)
    det = p @ e1
    tv = x - tri[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        b1 = np.einsum("ij,ij->i", p, tv) / det
        q = np.cross(tv, e1)
        b2 = np.einsum("ij,ij->i", w, q) / det
        t = (q @ e2) / det
    return bool(np.any((b1 >= 0) & (b2 >= 0) & (b1 + b2 <= 1) & (t > 1e-9) & (t < 1.0)))


def in_hull(a, b, tri, grid: int = 60, slices: int = 300) -> bool:
    """Whether a point of the triangle (a barycentric grid) lies in the convex hull of [a, b] and the
    ball: within lam R of the slice (1 - lam) [a, b] + lam C for some lam in (0, 1] (a scan)."""
    g = np.linspace(0.0, 1.0, grid)
    bary = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
    bary = bary[bary.sum(axis=1) <= 1.0]
    q = tri[0] + bary[:, :1] * (tri[1] - tri[0]) + bary[:, 1:] * (tri[2] - tri[0])
    lam = np.linspace(1.0 / slices, 1.0, slices)
    a_l = (1.0 - lam)[:, None] * a + lam[:, None] * C  # (S, 3)
    ab = (1.0 - lam)[:, None] * (b - a)
    rel = q[:, None, :] - a_l[None]  # (Q, S, 3)
    ab2 = np.maximum(np.einsum("sj,sj->s", ab, ab), 1e-300)
    s = np.clip(np.einsum("qsj,sj->qs", rel, ab) / ab2, 0.0, 1.0)
    dist = np.linalg.norm(rel - s[..., None] * ab[None], axis=2)
    return bool(np.any(dist <= lam * R))


def test_segments_free_against_brute_force():
    """300 random segments with a small triangle each about the hull of the segment and the lamp: where
    brute force finds the triangle crossing a segment to the sphere or inside the hull, the test says
    "may be hidden" (never too seldom); where it finds neither, the test clears all but 10 % (measured:
    145 of 155; the rest graze the hull within about 1e-2)."""
    rng = np.random.default_rng(11)
    ys = sphere_points(400)
    hidden = clear = agree = 0
    for _ in range(300):
        a, b = rng.uniform([-2.0, 0.0, -2.0], [2.0, 2.5, 2.0], size=(2, 3))
        if min(np.linalg.norm(a - C), np.linalg.norm(b - C)) <= R:
            continue
        w = rng.dirichlet([1.0, 1.0, 1.0])
        mid = w[0] * a + w[1] * b + w[2] * C + rng.normal(scale=0.25, size=3)
        tri = mid + rng.normal(scale=0.12, size=(3, 3))
        free = sphere_occluders.segments_free(C, R, a[None], b[None], tri[None], np.array([-1]), np.zeros((0, 4)),
                                              EPS)[0]
        if crossed(a, b, ys, tri):
            hidden += 1
            assert not free, (a, b, tri)
        elif in_hull(a, b, tri):
            assert not free, (a, b, tri)
        else:
            clear += 1
            agree += bool(free)
    assert hidden >= 60 and clear >= 60 and agree >= 0.9 * clear, (hidden, agree, clear)


def test_a_floor_the_segments_end_on_hides_nothing():
    """Segments from a camera to points of a floor under the lamp are clear of the floor's triangles (the
    floor's plane leaves the lamp strictly above it and the segments on its side), also ending a
    rounding below it; a plate under the lamp makes those whose hull it meets "may be hidden" and
    clears all but 5 % of the rest; an exact sphere in the way (not the emitter's own) makes all hidden; a
    segment to infinity is clear only where nothing but the emitter is there (its own mesh left out)."""
    rng = np.random.default_rng(5)
    floor = np.array([[[-20, 0, 20], [20, 0, 20], [20, 0, -20]], [[-20, 0, 20], [20, 0, -20], [-20, 0, -20]]], float)
    plate = np.array([[[0.19, 0.45, 0.09], [0.31, 0.45, 0.09], [0.31, 0.45, 0.21]],
                      [[0.19, 0.45, 0.09], [0.31, 0.45, 0.21], [0.19, 0.45, 0.21]]])
    o = np.tile([0.0, 2.0, 3.0], (120, 1))
    ends = np.c_[rng.uniform(-2, 2, 120), -1e-7 * EPS * rng.uniform(size=120), rng.uniform(-2, 2, 120)]
    none = np.zeros((0, 4))
    assert sphere_occluders.segments_free(C, R, o, ends, floor, np.array([-1, -1]), none, EPS).all()
    both = sphere_occluders.segments_free(C, R, o, ends, np.concatenate([floor, plate]), np.full(4, -1), none, EPS)
    ys = sphere_points(400)
    apart = missed = 0
    for i in range(120):
        if crossed(o[i], ends[i], ys, plate[0]) or crossed(o[i], ends[i], ys, plate[1]) or \
                in_hull(o[i], ends[i], plate[0]) or in_hull(o[i], ends[i], plate[1]):
            assert not both[i]
        else:
            apart += 1
            missed += not both[i]
    assert apart >= 30 and missed <= 0.05 * apart, (apart, missed)
    own_and_other = np.array([[*C, R], [0.0, 1.0, 1.4, 0.2]])
    assert sphere_occluders.segments_free(C, R, o[:5], ends[:5], floor, np.array([-1, -1]), own_and_other[:1],
                                          EPS).all()
    blocked = sphere_occluders.segments_free(C, R, o[:5], np.tile([0.0, 0.0, 0.0], (5, 1)), floor,
                                             np.array([-1, -1]), own_and_other, EPS)
    assert not blocked.any()
    far = ends[:5] + np.array([0.0, np.inf, 0.0])
    assert not sphere_occluders.segments_free(C, R, o[:5], far, floor, np.array([-1, -1]), none, EPS).any()
    assert sphere_occluders.segments_free(C, R, o[:5], far, floor, np.array([0, 0]), own_and_other[:1], EPS).all()
