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
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import njit

MARGIN = 1e-6  # the cone's half-angle (radians) and its depth (of it) widened by this
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
    u = np.empty((5, 3))
    f = np.empty(5)
    for i in range(points.shape[0]):
        x, n = points[i], normals[i]
        a = c - x
        d = _norm(a)
        if not d > R:
            continue
        a = a / d
        sin_a = R / d
        cos_a = math.sqrt((d - R) * (d + R)) / d
        depth = (d - R * sin_a) * (1.0 + MARGIN)  # the tangent circle's plane along a, d - R^2 / d
        cos_lim = cos_a * math.cos(MARGIN) - sin_a * math.sin(MARGIN)  # cos(alpha + MARGIN)
        clear = True
        for s in range(spheres.shape[0]):
            if _sphere_meets(x, n, a, sin_a, depth, height, spheres[s]):
                clear = False
                break
        for t in range(tris.shape[0]):
            if not clear:
                break
            if not _sphere_meets(x, n, a, sin_a, depth, height, bound[t]):
                continue
            for k in range(3):
                poly[k] = tris[t, k]
                f[k] = _dot(tris[t, k] - x, n) - height  # above the tangent plane by more than `height`
            m = _clip(poly, f, 3, clipped)
            for k in range(m):
                f[k] = depth - _dot(clipped[k] - x, a)  # before the tangent circle's plane
            m = _clip(clipped, f, m, poly)
            clear = not (m > 0 and _meets_cone(x, a, cos_lim, poly, m, u))
        out[i] = clear


@njit
def _sphere_meets(x, n, a, sin_a, depth, height, ball):
    """Whether the ball (centre, radius) may meet the region (above `height` over the tangent plane of
    normal n, before `depth` along a, within alpha + MARGIN of a seen from x): by its bounding cone."""
    q = ball[:3] - x
    r = ball[3]
    if _dot(q, a) - r > depth or _dot(q, n) + r <= height:
        return False
    dq = _norm(q)
    return dq <= r or _dot(q, a) / dq >= math.cos(min(math.pi, math.asin(sin_a) + math.asin(r / dq) + MARGIN))


@njit
def _clip(poly, f, m, out):
    """The part of the convex polygon poly[:m] where f >= 0 (f its vertices' values of an affine
    function) into out; returns its vertex count (0: none of it)."""
    count = 0
    for k in range(m):
        j = (k + 1) % m
        if f[k] >= 0.0:
            out[count] = poly[k]
            count += 1
        if (f[k] >= 0.0) != (f[j] >= 0.0):
            out[count] = poly[k] + f[k] / (f[k] - f[j]) * (poly[j] - poly[k])
            count += 1
    return count


@njit
def _meets_cone(x, a, cos_lim, poly, m, u):
    """Whether the convex polygon poly[:m] meets the cone of apex x, unit axis a, cos(half-angle) cos_lim
    (a vertex at the apex counts as meeting it)."""
    for k in range(m):
        v = poly[k] - x
        length = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        if not length > 0.0:
            return True
        u[k] = v / length
        if u[k, 0] * a[0] + u[k, 1] * a[1] + u[k, 2] * a[2] >= cos_lim:
            return True
    pos = neg = 0
    for k in range(m):
        g = np.cross(u[k], u[(k + 1) % m])
        side = g[0] * a[0] + g[1] * a[1] + g[2] * a[2]
        pos += side > 0.0
        neg += side < 0.0
        gl = math.sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2])
        if not gl > 0.0:
            continue
        g = g / gl
        ag = a[0] * g[0] + a[1] * g[1] + a[2] * g[2]
        p = a - ag * g  # a projected on the edge's great circle
        pl = math.sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2])
        if not pl > 0.0:
            continue
        within = _dot(np.cross(u[k], p), g) >= 0.0 and _dot(np.cross(p, u[(k + 1) % m]), g) >= 0.0
        if within and pl >= cos_lim:  # cos of the angle from a to the arc's nearest point: |p|
            return True
    if m < 3 or not (pos == m or neg == m):  # a, or -a, within the directions of the polygon
        return False
    normal = np.cross(poly[1] - poly[0], poly[2] - poly[0])
    return _dot(poly[0] - x, normal) * _dot(a, normal) > 0.0  # a's ray, not -a's, meets its plane


@njit
def _norm(v):
    return math.sqrt(_dot(v, v))


@njit
def _dot(p, q):
    return p[0] * q[0] + p[1] * q[1] + p[2] * q[2]
