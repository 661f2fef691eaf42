"""Whether anything may hide part of a sphere emitter from a surface point: an exact test against the
occluders' geometry, the same for every cubature order (shading.py's penumbra test; docs/area_lights.md,
"Surfaces lit by a sphere").

From a point x outside the sphere (centre c, radius R, d = |c - x|, sin alpha = R / d) the light
arrives along segments from x to the points of the sphere it sees: every such segment lies in the cone
of apex x, axis a = (c - x) / d and half-angle alpha, before the plane of the tangent circle ((p - x).a
<= d - R^2 / d: no point x sees lies beyond it), and above x's tangent plane where it counts (the
surface term's max(0, n.w)). So an occluder that meets none of that region (`free`) hides nothing; one
that meets it may. A triangle is tested exactly: clipped to the part above the tangent plane and before
the tangent circle's plane, it must not come within alpha of a, seen from x (a vertex's direction,
the nearest point of an edge's great-circle arc, or a itself passing through it). The angle and the
depth are widened by MARGIN (the triangles cross into Embree in float32) and the part of a triangle
within HEIGHT of the tangent plane (the surface x lies on, a coplanar floor) is left out: shadow rays
leave the surface twice that far up (accel.py), and the sliver of the sphere lower than that is of
that width. Exact spheres other than the emitter are tested by their bounding cone (conservative).
The test says "may be hidden" too often, never too seldom: where it does, the surface term falls back
on the rows, the probes and the penumbra's samples (shading.py).

Along a segment (`segments_free`: the air-light's rule about a camera ray's segment, rendering/
near_emitters.py): the light reaches the points x of a segment from o to e along segments from x to
points of the sphere, all inside the convex hull of the segment and the ball (the hull of the balls o
and e of radius 0 and c of radius R). An occluder (a triangle, the hull of its vertices; an exact
sphere) hides nothing if a plane separates it from that hull: the occluder on its far side, the emitter
strictly on the near side by more than MARGIN of the distances involved, the segment's ends on the near
side or beyond the plane by at most HEIGHT of the shadow rays' offset (an open segment from a point on
the plane to a point of the emitter meets the occluder nowhere: a floor the ray ends on). The planes
tried are a triangle's own (either way) and the directions of GJK's iterates toward the point of the
difference of the two hulls nearest the origin (GJK_STEPS), each checked exactly as it comes;
where none separates, the segment may be hidden. A segment to infinity (a ray that leaves the scene)
is a half-line from o along d: the hull of it and the ball is unbounded but convex, and a plane
separates it from an occluder iff the occluder is on its far side and the ball and o on its near side
(as above) and d does not head across it (n.d <= 0, n toward the occluder).
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import njit

MARGIN = 1e-6  # the cone's half-angle (radians) and its depth (of it) widened by this
GJK_STEPS = 64  # GJK's steps toward a separating plane per occluder and segment (`_gjk`)
GJK_GAP = 1e-9  # ... stopped where the iterate is within this (relative, of its square) of the distance
GJK_TILT = 1e-9  # a direction nearly along a half-line's plane is also tried tilted this far below it (`_gjk`)
HEIGHT = 0.5  # triangles' parts lower than this x the shadow rays' offset over the tangent plane are left out


def free(centre, radius: float, points, normals, triangles, sphere_of, spheres, epsilon: float) -> np.ndarray:
    """(M,) whether nothing of `triangles` (T, 3, 3; rows with `sphere_of` >= 0 are exact spheres'
    meshes, tested as the spheres (S, 4) instead) nor of the exact spheres other than the emitter
    (`centre`, `radius`) meets the region through which each point (M, 3) of unit normal (M, 3) sees
    the emitter (module docstring); False at points on or inside it. `epsilon`: the shadow rays' offset."""
    centre = np.asarray(centre, float)
    out = np.zeros(len(points), dtype=np.bool_)
    if not len(points):
        return out
    lo = np.minimum(points.min(axis=0), centre - radius)
    hi = np.maximum(points.max(axis=0), centre + radius)
    near = (sphere_of < 0) & np.all(triangles.max(axis=1) >= lo, axis=1) & np.all(triangles.min(axis=1) <= hi, axis=1)
    others = ~(np.all(spheres[:, :3] == centre, axis=1) & (spheres[:, 3] == radius))
    tris = np.ascontiguousarray(triangles[near])
    mid = tris.mean(axis=1)
    bound = np.append(mid, np.linalg.norm(tris - mid[:, None, :], axis=2).max(axis=1, initial=0.0)[:, None], axis=1)
    _free(centre, float(radius), np.ascontiguousarray(points, float), np.ascontiguousarray(normals, float), tris,
          bound, np.ascontiguousarray(spheres[others]), HEIGHT * epsilon, out)
    return out


@njit
def _free(c, R, points, normals, tris, bound, spheres, height, out):
    """`free` into out (M,); `bound` (T, 4) a sphere about each triangle (centre, radius): those that
    miss the region are passed over before the exact test."""
    poly, clipped = np.empty((5, 3)), np.empty((5, 3))
    f = np.empty(5)
    for i in range(points.shape[0]):
        x = (points[i, 0], points[i, 1], points[i, 2])
        n = (normals[i, 0], normals[i, 1], normals[i, 2])
        a = _sub((c[0], c[1], c[2]), x)
        d = math.sqrt(_dot(a, a))
        if not d > R:
            continue
        a = (a[0] / d, a[1] / d, a[2] / d)
        sin_a = R / d
        cos_a = math.sqrt((d - R) * (d + R)) / d
        depth = (d - R * sin_a) * (1.0 + MARGIN)  # the tangent circle's plane along a, d - R^2 / d
        cos_lim = cos_a * math.cos(MARGIN) - sin_a * math.sin(MARGIN)  # cos(alpha + MARGIN)
        clear = True
        for s in range(spheres.shape[0]):
            if _ball_meets(x, n, a, sin_a, depth, height, spheres[s]):
                clear = False
                break
        for t in range(tris.shape[0]):
            if not clear:
                break
            if not _ball_meets(x, n, a, sin_a, depth, height, bound[t]):
                continue
            for k in range(3):
                for j in range(3):
                    poly[k, j] = tris[t, k, j]
                f[k] = _dot(_row(poly, k, x), n) - height  # above the tangent plane by more than `height`
            m = _clip(poly, f, 3, clipped)
            for k in range(m):
                f[k] = depth - _dot(_row(clipped, k, x), a)  # before the tangent circle's plane
            m = _clip(clipped, f, m, poly)
            clear = not (m > 0 and _meets_cone(x, a, cos_lim, poly, m))
        out[i] = clear


def segments_free(centre, radius: float, origins, dirs, lengths, triangles, sphere_of, spheres,
                  epsilon: float) -> np.ndarray:
    """(P,) whether nothing of `triangles` (as `free`'s) nor of the exact spheres other than the emitter
    can hide any part of the emitter from any point of the segments from `origins` (P, 3) along `dirs`
    (P, 3) for `lengths` (P,) (module docstring, "Along a segment"; an infinite length: a half-line, a
    NaN: nothing cleared). `epsilon`: the shadow rays' offset."""
    centre = np.asarray(centre, float)
    others = ~(np.all(spheres[:, :3] == centre, axis=1) & (spheres[:, 3] == radius))
    if not (np.any(sphere_of < 0) or others.any()):  # nothing but the emitter: every segment is clear
        return np.ones(len(origins), dtype=np.bool_)
    origins, dirs = np.asarray(origins, float), np.asarray(dirs, float)
    lengths = np.asarray(lengths, float)
    out = np.zeros(len(origins), dtype=np.bool_)
    ray = lengths == np.inf
    norm = np.linalg.norm(dirs, axis=1)
    ok = np.all(np.isfinite(origins), axis=1) & np.all(np.isfinite(dirs), axis=1) & (np.isfinite(lengths) | ray)
    ok &= ~ray | (norm > 0.0)
    if not ok.any():
        return out
    ends = np.where(ray[:, None], origins, origins + np.where(ray, 0.0, lengths)[:, None] * dirs)
    ahead = np.where(ray[:, None] & ok[:, None], dirs / np.where(norm > 0.0, norm, 1.0)[:, None], 0.0)
    lo = np.minimum(np.minimum(origins[ok], ends[ok]).min(axis=0), centre - radius)
    hi = np.maximum(np.maximum(origins[ok], ends[ok]).max(axis=0), centre + radius)
    lo = np.where((ahead[ok] < 0.0).any(axis=0), -np.inf, lo)  # a half-line's box: unbounded where it heads
    hi = np.where((ahead[ok] > 0.0).any(axis=0), np.inf, hi)
    near = (sphere_of < 0) & np.all(triangles.max(axis=1) >= lo, axis=1) & np.all(triangles.min(axis=1) <= hi, axis=1)
    _segments_free(centre, float(radius), np.ascontiguousarray(origins), np.ascontiguousarray(ends),
                   np.ascontiguousarray(ahead), ok, np.ascontiguousarray(triangles[near], float),
                   np.ascontiguousarray(spheres[others], float), HEIGHT * epsilon, out)
    return out


@njit
def _segments_free(c, R, origins, ends, ahead, ok, tris, spheres, height, out):
    """`segments_free` into out (P,): each triangle, then each other sphere, as the hull of its balls
    (radius 0 at a triangle's vertices) against the hull of the segment's ends and the emitter, and of
    its half-line ahead[i] on (a unit direction; zero: none)."""
    hull = np.empty((3, 3))
    hull_r = np.array([0.0, 0.0, R])
    ball_r = np.zeros(3)
    one_r = np.zeros(1)
    for i in range(origins.shape[0]):
        if not ok[i]:
            continue
        for e in range(3):
            hull[0, e], hull[1, e], hull[2, e] = origins[i, e], ends[i, e], c[e]
        d = (ahead[i, 0], ahead[i, 1], ahead[i, 2])
        lo, hi = np.empty(3), np.empty(3)
        for e in range(3):
            lo[e] = -math.inf if d[e] < 0.0 else min(origins[i, e], ends[i, e], c[e] - R)
            hi[e] = math.inf if d[e] > 0.0 else max(origins[i, e], ends[i, e], c[e] + R)
        clear = True
        for t in range(tris.shape[0]):
            tri = tris[t]
            if (min(tri[0, 0], tri[1, 0], tri[2, 0]) > hi[0] or max(tri[0, 0], tri[1, 0], tri[2, 0]) < lo[0] or
                    min(tri[0, 1], tri[1, 1], tri[2, 1]) > hi[1] or max(tri[0, 1], tri[1, 1], tri[2, 1]) < lo[1] or
                    min(tri[0, 2], tri[1, 2], tri[2, 2]) > hi[2] or max(tri[0, 2], tri[1, 2], tri[2, 2]) < lo[2]):
                continue
            if not _apart(tri, ball_r, hull, hull_r, d, height):
                clear = False
                break
        for s in range(spheres.shape[0]):
            if not clear:
                break
            clear = _apart(spheres[s:s + 1, :3], one_r + spheres[s, 3], hull, hull_r, d, height)
        out[i] = clear


@njit
def _apart(p, pr, h, hr, d, height):
    """Whether the hull of the balls (p[k], pr[k]) (an occluder) provably hides nothing: a plane of unit
    normal u with the occluder on its far side by more than the emitter's margin, the emitter (h[2],
    hr[2]) strictly on the near side and the segment (h[0], h[1]) on it within `height` (an open segment
    from a point on the plane to a point of the emitter meets the occluder nowhere), and the half-line
    along d (unit; zero: none) not toward it (u.d <= 0). The normals tried: a triangle's own (either
    way), then the directions of GJK's iterates toward the point of the difference of the two hulls
    nearest the origin (`_gjk`), each a certificate checked exactly as it comes."""
    if p.shape[0] == 3:
        n = _cross(_sub(_pt(p, 1), _pt(p, 0)), _sub(_pt(p, 2), _pt(p, 0)))
        nl = math.sqrt(_dot(n, n))
        if nl > 0.0:
            n = (n[0] / nl, n[1] / nl, n[2] / nl)
            if _separates(n, p, pr, h, hr, d, height) or _separates((-n[0], -n[1], -n[2]), p, pr, h, hr, d, height):
                return True
    return _gjk(p, pr, h, hr, d, height)


@njit
def _gjk(p, pr, h, hr, d, height):
    """Whether GJK's iterates x toward the point of the difference D of the occluder's hull and the
    segment's (`_apart`) nearest the origin give a separating direction u = x / |x| (`_separates`; where
    u.d > -GJK_TILT, u less (u.d + GJK_TILT) d too: where the half-line lies in the nearest plane, u.d
    = 0 there, which an iterate meets only to rounding). D's support point along -u is the occluder's lowest minus the
    hull's highest along u (`_support`); a half-line's hull is cut at o + T d, T twice a bound on |D|'s
    points: D's nearest point is that of D less the half-line's steps t d, whose t <= |D| (the same
    point). The simplex (up to 4 points) is reduced to the face nearest the origin (`_nearest`);
    GJK_STEPS steps at most, fewer where x is within GJK_GAP of the distance (|x|^2 - x.s <= GJK_GAP
    |x|^2) or the hulls touch (no plane)."""
    reach = 0.0
    for k in range(p.shape[0]):
        reach = max(reach, math.sqrt(_dot(_sub(_pt(p, k), _pt(h, 2)), _sub(_pt(p, k), _pt(h, 2)))) + pr[k])
    reach += math.sqrt(max(_dot(_sub(_pt(h, 0), _pt(h, 2)), _sub(_pt(h, 0), _pt(h, 2))),
                           _dot(_sub(_pt(h, 1), _pt(h, 2)), _sub(_pt(h, 1), _pt(h, 2))))) + hr[2]
    cut = h.copy()
    for e in range(3):
        cut[1, e] += 2.0 * reach * d[e]
    simplex = np.empty((4, 3))
    x = _sub(_pt(p, 0), _pt(h, 2))
    size = 0
    for _ in range(GJK_STEPS):
        xl = math.sqrt(_dot(x, x))
        if not xl > 1e-12 * reach:
            return False
        u = (x[0] / xl, x[1] / xl, x[2] / xl)
        if _separates(u, p, pr, h, hr, d, height):
            return True
        ud = _dot(u, d) + GJK_TILT
        if ud > 0.0 and _separates((u[0] - ud * d[0], u[1] - ud * d[1], u[2] - ud * d[2]), p, pr, h, hr, d, height):
            return True
        s = _support(p, pr, cut, hr, u)
        if _dot(x, x) - _dot(x, s) <= GJK_GAP * _dot(x, x):
            return False
        for e in range(3):
            simplex[size, e] = s[e]
        size += 1
        x, size = _nearest(simplex, size)
    return False


@njit
def _support(p, pr, h, hr, u):
    """The point of the difference of the hulls of the balls (p, pr) and (h, hr) farthest along -u
    (unit): the first's lowest along u minus the second's highest."""
    k, best = 0, _dot(_pt(p, 0), u) - pr[0]
    for j in range(1, p.shape[0]):
        v = _dot(_pt(p, j), u) - pr[j]
        if v < best:
            k, best = j, v
    m, top = 0, _dot(_pt(h, 0), u) + hr[0]
    for j in range(1, h.shape[0]):
        v = _dot(_pt(h, j), u) + hr[j]
        if v > top:
            m, top = j, v
    return (p[k, 0] - pr[k] * u[0] - h[m, 0] - hr[m] * u[0], p[k, 1] - pr[k] * u[1] - h[m, 1] - hr[m] * u[1],
            p[k, 2] - pr[k] * u[2] - h[m, 2] - hr[m] * u[2])


@njit
def _nearest(simplex, size):
    """(the point of the hull of simplex[:size] nearest the origin, the size of the face it lies in,
    whose points are moved to simplex[:that size]): over the faces (subsets), the nearest point of each
    one's affine hull whose barycentric coordinates are all positive (a 4-point face: the origin
    inside, size 4)."""
    best, bx, bmask = math.inf, (0.0, 0.0, 0.0), 0
    lam = np.empty(4)
    for mask in range(1, 1 << size):
        x, ok = _affine_nearest(simplex, mask, size, lam)
        xx = _dot(x, x)
        if ok and xx < best:
            best, bx, bmask = xx, x, mask
    count = 0
    for j in range(size):
        if bmask >> j & 1:
            for e in range(3):
                simplex[count, e] = simplex[j, e]
            count += 1
    return bx, count


@njit
def _affine_nearest(simplex, mask, size, lam):
    """(the point of the affine hull of the points simplex[j] (bit j of mask) nearest the origin, whether
    its barycentric coordinates are all positive): with w0 the first and E the others less w0, the
    normal equations (E^T E) mu = -E^T w0 (Gaussian elimination), lam = (1 - sum mu, mu)."""
    idx = np.empty(4, np.int64)
    k = 0
    for j in range(size):
        if mask >> j & 1:
            idx[k] = j
            k += 1
    w0 = _pt(simplex, idx[0])
    if k == 1:
        return w0, True
    m = k - 1
    a = np.zeros((3, 4))
    for r in range(m):
        er = _sub(_pt(simplex, idx[r + 1]), w0)
        for q in range(m):
            a[r, q] = _dot(er, _sub(_pt(simplex, idx[q + 1]), w0))
        a[r, m] = -_dot(er, w0)
    for col in range(m):  # elimination with partial pivoting
        piv = col
        for r in range(col + 1, m):
            if abs(a[r, col]) > abs(a[piv, col]):
                piv = r
        if not abs(a[piv, col]) > 0.0:
            return w0, False
        for q in range(m + 1):
            a[col, q], a[piv, q] = a[piv, q], a[col, q]
        for r in range(m):
            if r != col:
                f = a[r, col] / a[col, col]
                for q in range(col, m + 1):
                    a[r, q] -= f * a[col, q]
    lam[0] = 1.0
    x = w0
    for r in range(m):
        mu = a[r, m] / a[r, r]
        lam[r + 1] = mu
        lam[0] -= mu
        er = _sub(_pt(simplex, idx[r + 1]), w0)
        x = (x[0] + mu * er[0], x[1] + mu * er[1], x[2] + mu * er[2])
    for r in range(k):
        if not lam[r] > 0.0:
            return x, False
    return x, True


@njit
def _separates(u, p, pr, h, hr, d, height):
    """Whether the plane of normal u (any length: its own is measured here) through the occluder's
    lowest point along u certifies it (`_apart`): the emitter below it by more than MARGIN of the
    distances involved, the segment's ends below it or above by at most `height`, the half-line along d
    not rising (u.d <= 0)."""
    ul = math.sqrt(_dot(u, u))
    if not ul > 0.0:
        return False
    low = _dot(_pt(p, 0), u) - pr[0] * ul
    for j in range(1, p.shape[0]):
        low = min(low, _dot(_pt(p, j), u) - pr[j] * ul)
    centre = _dot(_pt(h, 2), u)
    if not low - (centre + hr[2] * ul) > MARGIN * (hr[2] * ul + abs(low - centre)):
        return False
    return _dot(d, u) <= 0.0 and _dot(_pt(h, 0), u) <= low + height * ul and _dot(_pt(h, 1), u) <= low + height * ul


@njit
def _ball_meets(x, n, a, sin_a, depth, height, ball):
    """Whether the ball (centre, radius) may meet the region (above `height` over the tangent plane of
    normal n, before `depth` along a, within alpha + MARGIN of a seen from x): by its bounding cone."""
    q = (ball[0] - x[0], ball[1] - x[1], ball[2] - x[2])
    r = ball[3]
    if _dot(q, a) - r > depth or _dot(q, n) + r <= height:
        return False
    dq = math.sqrt(_dot(q, q))
    return dq <= r or _dot(q, a) / dq >= math.cos(min(math.pi, math.asin(sin_a) + math.asin(r / dq) + MARGIN))


@njit
def _clip(poly, f, m, out):
    """The part of the convex polygon poly[:m] where f >= 0 (f its vertices' values of an affine
    function) into out; returns its vertex count (0: none of it)."""
    count = 0
    for k in range(m):
        j = (k + 1) % m
        if f[k] >= 0.0:
            for e in range(3):
                out[count, e] = poly[k, e]
            count += 1
        if (f[k] >= 0.0) != (f[j] >= 0.0):
            w = f[k] / (f[k] - f[j])
            for e in range(3):
                out[count, e] = poly[k, e] + w * (poly[j, e] - poly[k, e])
            count += 1
    return count


@njit
def _meets_cone(x, a, cos_lim, poly, m):
    """Whether the convex polygon poly[:m] meets the cone of apex x, unit axis a, cos(half-angle) cos_lim
    (a vertex at the apex counts as meeting it)."""
    pos = neg = 0
    for k in range(m):
        u, v = _row(poly, k, x), _row(poly, (k + 1) % m, x)
        lu, lv = math.sqrt(_dot(u, u)), math.sqrt(_dot(v, v))
        if not (lu > 0.0 and lv > 0.0):
            return True
        if _dot(u, a) >= cos_lim * lu:
            return True
        g = _cross(u, v)
        side = _dot(g, a)
        pos += side > 0.0
        neg += side < 0.0
        gl = math.sqrt(_dot(g, g))
        if not gl > 0.0:
            continue
        ag = side / gl
        p = (a[0] - ag * g[0] / gl, a[1] - ag * g[1] / gl, a[2] - ag * g[2] / gl)  # a on the edge's great circle
        pl = math.sqrt(_dot(p, p))
        # the arc's nearest point to a is p's direction where it lies between u and v; cos of the angle: |p|
        if pl >= cos_lim and _dot(_cross(u, p), g) >= 0.0 and _dot(_cross(p, v), g) >= 0.0:
            return True
    if m < 3 or not (pos == m or neg == m):  # a, or -a, within the directions of the polygon
        return False
    origin = _row(poly, 0, x)
    normal = _cross(_sub(_row(poly, 1, x), origin), _sub(_row(poly, 2, x), origin))
    return _dot(origin, normal) * _dot(a, normal) > 0.0  # a's ray, not -a's, meets its plane


@njit
def _pt(p, k):
    """p[k] as a tuple."""
    return (p[k, 0], p[k, 1], p[k, 2])


@njit
def _row(poly, k, x):
    """poly[k] - x as a tuple."""
    return (poly[k, 0] - x[0], poly[k, 1] - x[1], poly[k, 2] - x[2])


@njit
def _sub(p, q):
    return (p[0] - q[0], p[1] - q[1], p[2] - q[2])


@njit
def _cross(p, q):
    return (p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2], p[0] * q[1] - p[1] * q[0])


@njit
def _dot(p, q):
    return p[0] * q[0] + p[1] * q[1] + p[2] * q[2]
