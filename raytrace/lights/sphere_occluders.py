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
tried are a triangle's own (either way) and the directions of Frank-Wolfe's iterates toward the point
of the difference of the two hulls nearest the origin (FW_STEPS), each checked exactly as it comes;
where none separates, the segment may be hidden. Segments to infinity are cleared only where the
scene holds nothing but the emitter.
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import njit

MARGIN = 1e-6  # the cone's half-angle (radians) and its depth (of it) widened by this
FW_STEPS = 256  # Frank-Wolfe steps toward a separating plane per occluder and segment (`_apart`)
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


def segments_free(centre, radius: float, origins, ends, triangles, sphere_of, spheres, epsilon: float) -> np.ndarray:
    """(P,) whether nothing of `triangles` (as `free`'s) nor of the exact spheres other than the emitter
    can hide any part of the emitter from any point of the segments from `origins` (P, 3) to `ends`
    (P, 3) (module docstring, "Along a segment"); False where an end is not finite, unless the scene
    holds nothing but the emitter. `epsilon`: the
    shadow rays' offset."""
    centre = np.asarray(centre, float)
    others = ~(np.all(spheres[:, :3] == centre, axis=1) & (spheres[:, 3] == radius))
    if not (np.any(sphere_of < 0) or others.any()):  # nothing but the emitter: every segment is clear
        return np.ones(len(origins), dtype=np.bool_)
    out = np.zeros(len(origins), dtype=np.bool_)
    ok = np.all(np.isfinite(origins), axis=1) & np.all(np.isfinite(ends), axis=1)
    if not ok.any():
        return out
    lo = np.minimum(np.minimum(origins[ok], ends[ok]).min(axis=0), centre - radius)
    hi = np.maximum(np.maximum(origins[ok], ends[ok]).max(axis=0), centre + radius)
    near = (sphere_of < 0) & np.all(triangles.max(axis=1) >= lo, axis=1) & np.all(triangles.min(axis=1) <= hi, axis=1)
    _segments_free(centre, float(radius), np.ascontiguousarray(origins, float), np.ascontiguousarray(ends, float),
                   ok, np.ascontiguousarray(triangles[near], float), np.ascontiguousarray(spheres[others], float),
                   HEIGHT * epsilon, out)
    return out


@njit
def _segments_free(c, R, origins, ends, ok, tris, spheres, height, out):
    """`segments_free` into out (P,): each triangle, then each other sphere, as the hull of its balls
    (radius 0 at a triangle's vertices) against the hull of the segment's ends and the emitter."""
    hull = np.empty((3, 3))
    hull_r = np.array([0.0, 0.0, R])
    ball_r = np.zeros(3)
    one_r = np.zeros(1)
    for i in range(origins.shape[0]):
        if not ok[i]:
            continue
        for e in range(3):
            hull[0, e], hull[1, e], hull[2, e] = origins[i, e], ends[i, e], c[e]
        lo0 = min(origins[i, 0], ends[i, 0], c[0] - R)
        lo1 = min(origins[i, 1], ends[i, 1], c[1] - R)
        lo2 = min(origins[i, 2], ends[i, 2], c[2] - R)
        hi0 = max(origins[i, 0], ends[i, 0], c[0] + R)
        hi1 = max(origins[i, 1], ends[i, 1], c[1] + R)
        hi2 = max(origins[i, 2], ends[i, 2], c[2] + R)
        clear = True
        for t in range(tris.shape[0]):
            tri = tris[t]
            if (min(tri[0, 0], tri[1, 0], tri[2, 0]) > hi0 or max(tri[0, 0], tri[1, 0], tri[2, 0]) < lo0 or
                    min(tri[0, 1], tri[1, 1], tri[2, 1]) > hi1 or max(tri[0, 1], tri[1, 1], tri[2, 1]) < lo1 or
                    min(tri[0, 2], tri[1, 2], tri[2, 2]) > hi2 or max(tri[0, 2], tri[1, 2], tri[2, 2]) < lo2):
                continue
            if not _apart(tri, ball_r, hull, hull_r, height):
                clear = False
                break
        for s in range(spheres.shape[0]):
            if not clear:
                break
            clear = _apart(spheres[s:s + 1, :3], one_r + spheres[s, 3], hull, hull_r, height)
        out[i] = clear


@njit
def _apart(p, pr, h, hr, height):
    """Whether the hull of the balls (p[k], pr[k]) (an occluder) provably hides nothing: a plane of unit
    normal u with the occluder on its far side by more than the emitter's margin, the emitter (h[2],
    hr[2]) strictly on the near side and the segment (h[0], h[1]) on it within `height` (an open segment
    from a point on the plane to a point of the emitter meets the occluder nowhere). The normals tried: a
    triangle's own (either way), then Frank-Wolfe's iterates toward the point of the difference of the two
    hulls nearest the origin (FW_STEPS), each direction a certificate checked exactly as it comes."""
    if p.shape[0] == 3:
        n = _cross(_sub(_pt(p, 1), _pt(p, 0)), _sub(_pt(p, 2), _pt(p, 0)))
        nl = math.sqrt(_dot(n, n))
        if nl > 0.0:
            n = (n[0] / nl, n[1] / nl, n[2] / nl)
            if _separates(n, p, pr, h, hr, height) or _separates((-n[0], -n[1], -n[2]), p, pr, h, hr, height):
                return True
    x = _sub(_pt(p, 0), _pt(h, 2))  # a point of the difference
    tiny = 1e-12 * (math.sqrt(_dot(x, x)) + hr[2])  # the hulls touch or overlap: no plane
    for _ in range(FW_STEPS):
        xl = math.sqrt(_dot(x, x))
        if not xl > tiny:
            return False
        u = (x[0] / xl, x[1] / xl, x[2] / xl)
        if _separates(u, p, pr, h, hr, height):
            return True
        # the difference's point farthest along -u: the occluder's lowest minus the hull's highest along u
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
        s = (p[k, 0] - pr[k] * u[0] - h[m, 0] - hr[m] * u[0], p[k, 1] - pr[k] * u[1] - h[m, 1] - hr[m] * u[1],
             p[k, 2] - pr[k] * u[2] - h[m, 2] - hr[m] * u[2])
        g = _sub(x, s)
        gg = _dot(g, g)
        if not gg > 0.0:
            return False
        w = min(1.0, max(0.0, _dot(x, g) / gg))
        if w == 0.0:
            return False
        x = (x[0] - w * g[0], x[1] - w * g[1], x[2] - w * g[2])
    return False


@njit
def _separates(u, p, pr, h, hr, height):
    """Whether the plane of normal u (any length: its own is measured here) through the occluder's
    lowest point along u certifies it (`_apart`): the emitter below it by more than MARGIN of the
    distances involved, the segment's ends below it or above by at most `height`."""
    ul = math.sqrt(_dot(u, u))
    if not ul > 0.0:
        return False
    low = _dot(_pt(p, 0), u) - pr[0] * ul
    for j in range(1, p.shape[0]):
        low = min(low, _dot(_pt(p, j), u) - pr[j] * ul)
    centre = _dot(_pt(h, 2), u)
    if not low - (centre + hr[2] * ul) > MARGIN * (hr[2] * ul + abs(low - centre)):
        return False
    return _dot(_pt(h, 0), u) <= low + height * ul and _dot(_pt(h, 1), u) <= low + height * ul


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
