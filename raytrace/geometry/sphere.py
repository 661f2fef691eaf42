"""The exact sphere as a boundary kind: ray intersection in float64 beside Embree's triangles.

A shape `primitive = "sphere"` with `exact = true` (scene/format.py) keeps its mesh of `segments` in
the scene's triangle arrays (its rows carry its shape index, reflectance and corner normals), but
Embree never sees those rows: accel.py intersects the sphere itself with `sphere_roots` and reports a
hit on it as its first row (`Accelerator.hit_normals` gives the exact normal there).

Roots of |f + t d|^2 = r^2, f = o - c (Press et al., Numerical Recipes 5.6; Ericson, Real-Time
Collision Detection 5.3.2): with b = f·d, a = d·d and h = f - (b / a) d the offset of the line from
the centre, the quarter discriminant is b^2 - a (f·f - r^2) = a (r - |h|)(r + |h|), free of the
cancellation of the textbook form for grazing and far rays; q = -(b + sign(b) sqrt(disc)) gives the
roots q / a and (f·f - r^2) / q, neither formed as a difference of nearly equal numbers. Everything
is divided first by s = max(|f|_inf, r), so neither huge (1e200) nor tiny (1e-200) scenes overflow
or underflow; the roots are then s times those of the scaled problem.
"""
from __future__ import annotations

import math

import numpy as np

from .sorting import sort_few
from ..jit import njit

EPS = float(np.finfo(np.float64).eps)

# the stable forms above must be evaluated as written: no reassociation, no approximate reciprocals
exact_njit = njit(fastmath=False)


@exact_njit
def sphere_roots(o, d, c, r):
    """The two roots (t0 <= t1) of |o + t d - c| = r in float64, or (inf, inf) where the line misses
    the sphere (or d = 0)."""
    f0, f1, f2 = o[0] - c[0], o[1] - c[1], o[2] - c[2]
    s = max(abs(f0), abs(f1), abs(f2), r)
    if not s > 0.0 or not math.isfinite(s):
        return np.inf, np.inf
    f0, f1, f2, rr = f0 / s, f1 / s, f2 / s, r / s
    a = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    if not a > 0.0:
        return np.inf, np.inf
    b = f0 * d[0] + f1 * d[1] + f2 * d[2]
    k = b / a
    h0, h1, h2 = f0 - k * d[0], f1 - k * d[1], f2 - k * d[2]
    h = math.sqrt(h0 * h0 + h1 * h1 + h2 * h2)
    if h > rr:
        return np.inf, np.inf
    disc = a * (rr - h) * (rr + h)
    q = -(b + math.copysign(math.sqrt(disc), b))
    nf = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
    c0 = (nf - rr) * (nf + rr)
    t0 = q / a
    t1 = c0 / q if q != 0.0 else -t0  # q = 0: b = 0 and disc = 0, the ray grazes at t = 0
    if t0 > t1:
        t0, t1 = t1, t0
    return t0 * s, t1 * s


@exact_njit
def nearest_sphere_hits(origins, dirs, spheres, rows, t, prim):
    """Where a ray meets a sphere (centres spheres[:, :3], radii spheres[:, 3]) at 0 < t' < t[i],
    t[i] = t' and prim[i] = rows[sphere] (spheres whose row is -1 are skipped): the nearest hit wins."""
    for i in range(origins.shape[0]):
        for k in range(spheres.shape[0]):
            if rows[k] < 0:
                continue
            t0, t1 = sphere_roots(origins[i], dirs[i], spheres[k, :3], spheres[k, 3])
            hit = t0 if t0 > 0.0 else t1
            if hit > 0.0 and hit < t[i]:
                t[i] = hit
                prim[i] = rows[k]


@exact_njit
def sphere_blocks(origins, dirs, tmax, spheres, rows, occ):
    """occ[i] |= a sphere (rows[k] >= 0) meets the ray at 0 < t < tmax[i]."""
    for i in range(origins.shape[0]):
        if occ[i]:
            continue
        for k in range(spheres.shape[0]):
            if rows[k] < 0:
                continue
            t0, t1 = sphere_roots(origins[i], dirs[i], spheres[k, :3], spheres[k, 3])
            if (0.0 < t0 < tmax[i]) or (0.0 < t1 < tmax[i]):
                occ[i] = True
                break


@exact_njit
def quadratic_roots(a, b, c, out, n):
    """out[n:] <- the real roots of a x^2 + 2 b x + c = 0 (Numerical Recipes 5.6's stable form); the new n."""
    if a == 0.0:
        if b != 0.0:
            out[n] = -c / (2.0 * b)
            n += 1
        return n
    disc = b * b - a * c
    if disc < 0.0:
        return n
    q = -(b + math.copysign(math.sqrt(disc), b))
    out[n] = q / a
    n += 1
    if q != 0.0:
        out[n] = c / q
        n += 1
    return n


@exact_njit
def on_surface(light, c, r):
    """Whether the point `light` lies on the sphere (c, r) to the rounding of c + r n (a sphere
    light's own emitter points: lights/sphere.py): |(|light - c| - r)| <= 8 ulp (|c|_inf + r)."""
    d2 = 0.0
    scale = r
    for k in range(3):
        d2 += (light[k] - c[k]) ** 2
        scale = max(scale, abs(c[k]) + r)
    return abs(math.sqrt(d2) - r) <= 8.0 * EPS * scale


@exact_njit
def _blocked(p, light, sun, c, r):
    """Whether the surface of the sphere (c, r) crosses the segment from p to the point light (sun:
    the ray from p toward the directional light, `light` its unit direction toward the light). A
    point on the sphere (`on_surface`: a sphere light's own emitter points) is not shadowed by it:
    its Lambert falloff vanishes wherever the sphere hides it (behind its tangent plane), the
    penumbrae's probes test whole rays as for flat emitters, and rounding would put the point on
    either side of the surface."""
    if sun:
        t0, t1 = sphere_roots(p, light, c, r)
        return t1 >= 0.0 and t1 < np.inf
    if on_surface(light, c, r):
        return False
    v = np.empty(3)
    for k in range(3):
        v[k] = light[k] - p[k]
    t0, t1 = sphere_roots(p, v, c, r)
    return 0.0 <= t0 <= 1.0 or 0.0 <= t1 <= 1.0


@exact_njit
def shadow_breaks(o, w, light, sun, c, r, out):
    """The points x (into out; returns their count, <= 4, unsorted) where p(x) = o + x w may enter or
    leave the shadow of the sphere (c, r): where p crosses the sphere, and where the line from p to
    the light turns tangent to it: on the cone from a point light L tangent to the sphere,
    ((p - L)·e)^2 = cos^2(alpha) |p - L|^2 with e the unit axis toward c and sin(alpha) = r / |c - L|
    (a quadratic in x), or on the cylinder of radius r about the axis through c along a directional
    light's direction. Between consecutive breaks the shadow test is constant (`_blocked`)."""
    t0, t1 = sphere_roots(o, w, c, r)
    n = 0
    if t0 < np.inf:
        out[0], out[1] = t0, t1
        n = 2
    if sun:  # the cylinder: the components across the light's direction
        fl = (o[0] - c[0]) * light[0] + (o[1] - c[1]) * light[1] + (o[2] - c[2]) * light[2]
        wl = w[0] * light[0] + w[1] * light[1] + w[2] * light[2]
        f, v = np.empty(3), np.empty(3)
        for k in range(3):
            f[k] = o[k] - c[k] - fl * light[k]
            v[k] = w[k] - wl * light[k]
        s0, s1 = sphere_roots(f, v, np.zeros(3), r)
        if s0 < np.inf:
            out[n], out[n + 1] = s0, s1
            n += 2
        return n
    e = np.empty(3)
    dist2 = 0.0
    for k in range(3):
        e[k] = c[k] - light[k]
        dist2 += e[k] * e[k]
    dist = math.sqrt(dist2)
    if not dist > r or on_surface(light, c, r):  # the light inside the sphere, or on it (`_blocked`):
        return n                                  # the sphere's surface is the only break
    cos2 = (dist - r) * (dist + r) / dist2
    ae = we = aw = aa = ww = 0.0
    for k in range(3):
        a = o[k] - light[k]
        ae += a * e[k] / dist
        we += w[k] * e[k] / dist
        aw += a * w[k]
        aa += a * a
        ww += w[k] * w[k]
    return quadratic_roots(we * we - cos2 * ww, ae * we - cos2 * aw, ae * ae - cos2 * aa, out, n)


@exact_njit
def lit_parts(o, w, lo, hi, light, sun, spheres, gap, out):
    """The parts of [lo, hi] of the segment o + x w that no sphere (rows of `spheres`: centre,
    radius) shadows from the light (`shadow_breaks`), parts shorter than `gap` dropped: into out
    (K, 2); returns K."""
    n_s = spheres.shape[0]
    breaks = np.empty(4 * n_s + 2)
    nb = 0
    buf = np.empty(4)
    for s in range(n_s):
        k = shadow_breaks(o, w, light, sun, spheres[s, :3], spheres[s, 3], buf)
        for j in range(k):
            if lo < buf[j] < hi:
                breaks[nb] = buf[j]
                nb += 1
    breaks[nb] = lo
    breaks[nb + 1] = hi
    b = breaks[:nb + 2]
    sort_few(b, 0, nb + 2)  # not np.sort: numba's quicksort costs about 1.5 s of compile
    m = 0
    p = np.empty(3)
    for j in range(nb + 1):
        a, z = b[j], b[j + 1]
        if not z > a:
            continue
        mid = 0.5 * (a + z) if z < np.inf else a + max(1.0, abs(a))
        for k in range(3):
            p[k] = o[k] + mid * w[k]
        dark = False
        for s in range(n_s):
            if _blocked(p, light, sun, spheres[s, :3], spheres[s, 3]):
                dark = True
                break
        if dark:
            continue
        if m > 0 and out[m - 1, 1] == a:  # joins the previous lit part
            out[m - 1, 1] = z
        else:
            out[m, 0], out[m, 1] = a, z
            m += 1
    k = 0
    for j in range(m):
        if out[j, 1] - out[j, 0] > gap:
            out[k, 0], out[k, 1] = out[j, 0], out[j, 1]
            k += 1
    return k
