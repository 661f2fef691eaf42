"""Straight light paths through index-matched shapes of any form, measured with Embree.

A shape whose interior is index-matched (ior = 1) does not bend light: the light reaching a point
travels the straight segment between them, and only the lengths of that segment inside each
shape's medium change its transmittance (seed 002 eq. 6-7 with k(x) measured on the real
boundary instead of the entry plane). For a non-convex shape (a U, a torus, a scanned mesh) the
segment may leave and re-enter it: `inside_lengths` finds every crossing with Embree, walking the
segment from the light's end (outside every shape, where the parity is known) to the point.

`segment_quadrature`, `segment_march` and `segment_samples` integrate the inside single
scattering of camera-ray segments with these lengths (quadrature, raymarch and montecarlo of
interiors/crossing.py for non-convex index-matched shapes; convex ones use the exact numba kernel of
media/slab.py instead, and so does an exact sphere here: its light paths are the closed-form chords of
media/convex_chords.py, `sphere_radiance`). `through_quadrature` integrates the outside medium where
its light crosses index-matched shapes (media/convex_chords.py's kernel when they are all convex or
exact spheres: `boundary`). The shadow rays of
surfaces use `inside_lengths` too (shapes.shadow_through): through an index-matched interior they are
attenuated, not blocked.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..geometry import facet_walk, sections
from ..error_bounds import spot_allowance
from ..jit import njit
from ..lights import NO_CONE, SMOOTHSTEP, falloff_array
from ..media.adaptive import CAPPED
from ..media.convex_chords import PLANES, SPHERE, boundary_chords, through_pieces
from ..media.phase import phase_value
from ..media.gauss import N10, N20, W10, W20
from ..media.nonconvex_refraction import (CLUSTER, LIT, PATH_COLUMNS, RESOLUTION, candidates, cluster_jumps, every,
                                          face_breaks, face_paths, face_planes, face_tree, lit_scan, path_rounding,
                                          plane_errors, scan_status)
from ..media.slab import U, light_span, phase_condition, sphere_radiance, straight_cuts
from ..rng import uniform
from ..shadows.through_others import point_chord_rounding

MAX_CROSSINGS = 64  # boundary crossings followed along one segment (more: the rest counts as outside)
FAR = 3.5  # x the scene's scale: from any scene point this far toward a directional light is outside every shape
MAX_LEVELS = 40  # halvings of a quadrature panel
# open panels one level of `segment_quadrature` may hold: an integrand that never settles (float32
# crossings jitter inside lengths by ~1e-7 of the scene) would otherwise double them every level
# (the slow fuzz run reached 23 GB); beyond it the open panels keep their 20-point values, counted
MAX_OPEN_PER_SEGMENT, MAX_OPEN = 4, 1 << 16
FLOAT32_SLACK = 1e-6  # relative: how far Embree's float32 distance may be from the exact one


def inside_lengths(prep, points, dirs, dist, sids, block=False, margin=0.0, end_inside=None, errors=None,
                   far_inside=None):
    """`walk`, and again from a far end moved sideways by RETRY_SHIFT x the scene's scale for the
    segments whose parity at the point contradicts `end_inside` (N, len(sids)) where given: Embree's
    float32 decisions for two rays near a shape's edge can disagree and lose one crossing of a short
    chord (a path grazing a corner), which would count the rest of the path on the wrong side.
    `errors` (N, len(sids)), where given, receives a bound on each length's error (`walk`'s; inf for a
    walk moved sideways: another path). `far_inside`: `walk`'s."""
    lengths, blocked, inside = walk(prep, points, dirs, dist, sids, block, margin, errors, far_inside)
    if end_inside is None:
        return lengths, blocked
    for attempt in range(1, RETRIES + 1):
        bad = np.nonzero(np.any(inside != end_inside, axis=1) & ~blocked)[0]
        if not len(bad):
            break
        far = np.where(np.isinf(dist[bad]), FAR * prep.accel.scale + np.linalg.norm(points[bad], axis=1), dist[bad])
        side = np.cross(dirs[bad], SIDEWAYS[attempt % 3])
        side /= np.maximum(np.linalg.norm(side, axis=1), 1e-300)[:, None]
        end = points[bad] + far[:, None] * dirs[bad] + RETRY_SHIFT * attempt * prep.accel.scale * side
        rel = end - points[bad]
        d2 = np.linalg.norm(rel, axis=1)
        lengths[bad], blocked[bad], inside[bad] = walk(prep, points[bad], rel / d2[:, None], d2, sids, block, margin)
        if errors is not None:
            errors[bad] = np.inf
    return lengths, blocked


RETRIES = 3
RETRY_SHIFT = 1e-5
SIDEWAYS = np.array([[0.6, 0.0, 0.8], [0.0, 0.8, 0.6], [0.8, 0.6, 0.0]])


def walk(prep, points, dirs, dist, sids, block=False, margin=0.0, errors=None, far_inside=None):
    """Lengths (N, len(sids)) inside each shape of `sids` of the segments from `points` along the
    unit `dirs` over `dist` (inf: toward a directional light), and (N,) whether another shape lies on
    the segment (only looked for with `block`; then the walk stops there). The segment is walked from
    its far end, which lies outside every shape of `sids` but where `far_inside` (N, len(sids)) says it
    lies inside (a light inside a shape), back to the point (crossings closer to it
    than `margin` are not counted: a surface point's own face); and
    (N, len(sids)) whether the walk ends inside each shape. `errors` (N, len(sids)), where given, is
    set to a bound on each length's error: the sum of its crossings' `crossing_errors`, plus, where the
    last skip passes the point and the look back from its end meets a crossing beyond the point, the
    distance from the last crossing to the point (a crossing between them would be hidden; where the
    look back meets the last crossing itself, there is none)."""
    accel = prep.accel
    n = len(points)
    sids = np.asarray(sids, dtype=np.int64)
    lengths = np.zeros((n, len(sids)))
    blocked = np.zeros(n, dtype=bool)
    far = np.where(np.isinf(dist), FAR * accel.scale + np.linalg.norm(points, axis=1), dist)
    start = points + far[:, None] * dirs
    back = -dirs
    stop = far - margin
    inside = np.zeros((n, len(sids)), dtype=bool) if far_inside is None else np.array(far_inside, dtype=bool)
    since = np.zeros((n, len(sids)))
    s = np.where(np.isinf(dist), 0.0, accel.epsilon)  # a point light on a surface: not that surface
    active = np.nonzero(stop > 0.0)[0]
    lookup = np.full(len(prep.scene.shapes), -1, dtype=np.int64)
    lookup[sids] = np.arange(len(sids))
    if errors is not None:
        errors[:] = 0.0
    neighbours = prep.memo("edge neighbours", lambda: sections.edge_neighbours(accel.triangles))
    for _ in range(MAX_CROSSINGS):
        if not len(active):
            break
        o = start[active] + s[active, None] * back[active]
        t, prim = accel.first_hit(o, back[active])
        held = np.zeros(len(t), dtype=bool)
        _settle(accel.triangles, accel.normals, neighbours, accel.sphere_of, o, back[active], t, prim, held)
        t32 = accel.hit_distance32(o, back[active])
        with np.errstate(invalid="ignore"):  # inf - inf on a miss
            off = (prim >= 0) & ~held & (np.abs(t - t32) > FLOAT32_SLACK * (t32 + accel.scale))
        t[off] = t32[off]  # no triangle holds the refined point (an edge not shared): keep Embree's
        at = s[active] + t
        done = (prim < 0) | (at >= stop[active])
        j = np.where(done, -1, lookup[prep.shape_ids[np.maximum(prim, 0)]])
        if block:
            stopped = ~done & (j < 0)
            blocked[active[stopped]] = True
            done |= stopped
        fin = active[done]
        lengths[fin] += np.where(inside[fin], far[fin, None] - since[fin], 0.0)
        cross = np.nonzero(~done & (j >= 0))[0]
        r, c = active[cross], j[cross]
        lengths[r, c] += np.where(inside[r, c], at[cross] - since[r, c], 0.0)
        since[r, c] = at[cross]
        inside[r, c] = ~inside[r, c]
        if errors is not None:
            errors[r, c] += crossing_errors(accel, o[cross], back[r], t[cross], prim[cross], off[cross], far[r],
                                            held[cross])
        go = np.nonzero(~done)[0]
        r = active[go]
        cos = np.abs(np.einsum("ij,ij->i", accel.hit_normals(prim[go], start[r] + at[go, None] * back[r]), back[r]))
        skip = accel.epsilon / np.maximum(cos, 1e-2)
        s[r] = at[go] + skip
        # a second crossing within the skip (a corner clipped): found looking back from the new start
        ob = start[r] + s[r, None] * back[r]
        tb, pb = accel.first_hit(ob, dirs[r])
        held_b = np.zeros(len(r), dtype=bool)
        _settle(accel.triangles, accel.normals, neighbours, accel.sphere_of, ob, dirs[r], tb, pb, held_b)
        other = (pb >= 0) & (pb != prim[go]) & (tb < (1.0 - 1e-9) * skip)
        extra = other & (s[r] - tb < stop[r])
        if errors is not None:  # a crossing past the point's end, within the skip, hides any between: all of it
            hidden = other & ~extra
            errors[r[hidden]] += (far[r[hidden]] - at[go][hidden])[:, None]
        jb = np.where(extra, lookup[prep.shape_ids[np.maximum(pb, 0)]], -1)
        if block:
            stopped = extra & (jb < 0)
            blocked[r[stopped]] = True
            s[r[stopped]] = np.inf
        extra &= jb >= 0
        q, c = r[extra], jb[extra]
        atb = s[q] - tb[extra]
        lengths[q, c] += np.where(inside[q, c], atb - since[q, c], 0.0)
        since[q, c] = atb
        inside[q, c] = ~inside[q, c]
        if errors is not None:
            errors[q, c] += crossing_errors(accel, ob[extra], dirs[q], tb[extra], pb[extra], ~held_b[extra], far[q],
                                            held_b[extra])
        active = r[s[r] < stop[r]]
        fin = r[s[r] >= stop[r]]
        lengths[fin] += np.where(inside[fin] & np.isfinite(s[fin, None]), far[fin, None] - since[fin], 0.0)
    return lengths, blocked, inside


@njit
def _settle(triangles, normals, neighbours, sphere_of, origins, dirs, t, prim, held):
    """Move each hit (t, prim) to the triangle that holds it in float64: Embree decides in float32
    which triangle a ray grazing an edge meets, and its neighbour's plane puts the crossing up to
    ~1e-7 of the scene's size off the surface (a kink of the inside length smeared over that reach,
    which no adaptive rule resolves at rtol 1e-10). From the reported triangle, step across the edge
    the refined point lies farthest beyond (`sections.edge_neighbours`), solving each plane again,
    until the point lies inside a triangle (at most 8 steps: `held`); if none, the hit stays as reported.
    A held hit is the plane solve of a triangle that holds its point in float64, however grazing the
    ray (Embree's float32 distance is then off by ~1e-7 / cos)."""
    for i in range(prim.shape[0]):
        k = prim[i]
        if k < 0 or sphere_of[k] >= 0:
            continue
        for _ in range(8):
            num, den = 0.0, 0.0
            for a in range(3):
                num += normals[k, a] * (triangles[k, 0, a] - origins[i, a])
                den += normals[k, a] * dirs[i, a]
            if den == 0.0 or not num / den > 0.0:
                break
            tk = num / den
            q = origins[i] + tk * dirs[i]
            e1, e2 = triangles[k, 1] - triangles[k, 0], triangles[k, 2] - triangles[k, 0]
            nx, ny, nz = e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]
            worst, side = 0.0, -1
            for e in range(3):
                a, b = triangles[k, e], triangles[k, (e + 1) % 3]
                ex, ey, ez = b[0] - a[0], b[1] - a[1], b[2] - a[2]
                qx, qy, qz = q[0] - a[0], q[1] - a[1], q[2] - a[2]
                d = (ey * qz - ez * qy) * nx + (ez * qx - ex * qz) * ny + (ex * qy - ey * qx) * nz
                if d < worst:
                    worst, side = d, e
            if side < 0:
                t[i], prim[i], held[i] = tk, k, True
                break
            k = neighbours[k, side]
            if k < 0:
                break


def crossing_errors(accel, origins, dirs, t, prim, off, far, held):
    """A bound on the error of each crossing distance t that a walk adds up (origins + t dirs on
    triangle prim; `off`: Embree's float32 distance kept): where the refined point lies inside its
    triangle by more than Embree's float32 reach FLOAT32_SLACK (t + scale) from every edge (`held`: the
    walk settled it on that triangle in float64, `_settle`: by more than 4 times the point's own error),
    the ray crosses that triangle there, and t is its plane's float64 solve, off by
    e = 16u (|o| + t + |A|) / cos (A a vertex, cos the ray's cosine to the normal) plus 8u far for the
    walk's sums; elsewhere (near
    an edge Embree may report a neighbour's plane, or its float32 distance was kept; an exact sphere)
    2 FLOAT32_SLACK (t + scale): the refined and Embree's distances agree to FLOAT32_SLACK (t + scale)
    (the walk's guard) and Embree's is taken to be that close to the exact one."""
    out = np.empty(len(t))
    _crossing_errors(accel.triangles, accel.normals, accel.sphere_of, origins, dirs, t, prim, off, far,
                     float(accel.scale), held, out)
    return out


@njit
def _crossing_errors(triangles, normals, sphere_of, origins, dirs, t, prim, off, far, scale, held, out):
    for i in range(t.shape[0]):
        k = prim[i]
        reach = FLOAT32_SLACK * (t[i] + scale)
        out[i] = 2.0 * reach
        if off[i] or sphere_of[k] >= 0:
            continue
        q = origins[i] + t[i] * dirs[i]
        n = normals[k]
        inner = math.inf
        for e in range(3):
            a, b = triangles[k, e], triangles[k, (e + 1) % 3]
            ex, ey, ez = b[0] - a[0], b[1] - a[1], b[2] - a[2]
            qx, qy, qz = q[0] - a[0], q[1] - a[1], q[2] - a[2]
            side = (ey * qz - ez * qy) * n[0] + (ez * qx - ex * qz) * n[1] + (ex * qy - ey * qx) * n[2]
            inner = min(inner, side / max(math.sqrt(ex * ex + ey * ey + ez * ez), 1e-300))
        o, v = origins[i], triangles[k, 0]
        cos = abs(n[0] * dirs[i, 0] + n[1] * dirs[i, 1] + n[2] * dirs[i, 2])
        e = 16.0 * U * (math.sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]) + t[i]
                        + math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])) / max(cos, 1e-300)
        if inner > (4.0 * e if held[i] else reach):
            out[i] = e + 8.0 * U * far[i]


def convex_exits(prep, sid, points, dirs, dist):
    """Lengths inside the convex shape sid of the segments from `points` inside it along the unit
    `dirs` over `dist` (inf: toward a directional light): min(exit distance, dist), the exit met by
    Embree on the shape's own triangles (one batched query, whatever the triangle count) and refined
    on the hit triangle's plane in float64, or Embree's float32 distance where the refinement took a
    neighbour's plane (a ray grazing an edge); a ray that slips between triangles is walked."""
    own = prep.accel.subset(("shape", sid), lambda: np.nonzero(prep.shape_ids == sid)[0])
    t, prim = own.first_hit(points, dirs)
    t32 = own.hit_distance32(points, dirs)
    with np.errstate(invalid="ignore"):  # inf - inf on a miss
        off = (prim >= 0) & (np.abs(t - t32) > FLOAT32_SLACK * (t32 + own.scale))
    t[off] = t32[off]
    miss = np.nonzero(prim < 0)[0]
    if len(miss):
        t[miss] = inside_lengths(prep, points[miss], dirs[miss], dist[miss], [sid],
                                 end_inside=np.ones((len(miss), 1), dtype=bool))[0][:, 0]
    return np.minimum(t, dist)


def _geometry(prep, sid, geo, directional, seg, x, facets=None, dk=None):
    """At the points x along segments `seg` (geo rows of media/slab.py's inside_radiance: entry point,
    direction w, the light's position or minus its direction of travel, a spot's axis and cone): the
    light's distance d (inf for a directional light), its path's length k inside shape sid (on the
    exit facets of `exit_facets` where the walk holds them), the scattering cosine mu and a spot's
    falloff toward the direction it leaves in (1 for other lights). `dk` (M,), where given, receives a
    bound on k's error (`walk`'s, or the exit facets' `exit_lengths`; inf for Embree's exits; 0 outside
    a spot's cone, where k is not measured)."""
    p = geo[seg, :3] + x[:, None] * geo[seg, 3:6]
    if directional:
        to = np.ascontiguousarray(geo[seg, 6:9])
        d = np.full(len(x), np.inf)
        f = np.ones(len(x))
    else:
        rel = geo[seg, 6:9] - p
        d = np.maximum(np.linalg.norm(rel, axis=1), 1e-125)
        to = rel / d[:, None]
        cone = geo[seg[0], [12, 13, 17]] if len(seg) else (*NO_CONE, SMOOTHSTEP)  # one light per call
        f = falloff_array(np.ascontiguousarray(-np.einsum("ij,ij->i", to, geo[seg, 9:12])), *cone)
    lit = np.nonzero(f > 0.0)[0]  # no rays traced outside a spot's cone
    k = np.zeros(len(x))
    if dk is not None:
        dk[:] = 0.0
    if facets is not None:
        walked = lit[facets.counts[seg[lit]] >= 0]
        col, err = np.empty(len(walked)), np.empty(len(walked))
        facet_walk.exit_lengths(seg[walked], x[walked], p[walked], np.ascontiguousarray(to[walked]), d[walked],
                                facets.offsets, facets.counts, facets.bt, facets.bf, facets.planes, facets.reach,
                                col, err)
        k[walked] = col
        if dk is not None:
            dk[walked] = err
        lit = lit[facets.counts[seg[lit]] < 0]
    if prep.interior_planes.get(sid) is not None:  # convex (shapes.hull_planes, filled before integrating)
        k[lit] = convex_exits(prep, sid, p[lit], to[lit], d[lit])
        if dk is not None:
            dk[lit] = np.inf  # Embree's exits: their float32 reach is not analysed
    else:
        err = np.zeros((len(lit), 1)) if dk is not None else None
        holds = np.zeros((len(lit), 1), dtype=bool) if directional or not len(lit) else \
            np.broadcast_to(holding(prep, geo[seg[lit[0]], 6:9], [sid]), (len(lit), 1))  # one light per call
        k[lit] = inside_lengths(prep, p[lit], to[lit], d[lit], [sid], end_inside=np.ones((len(lit), 1), dtype=bool),
                                errors=err, far_inside=holds)[0][:, 0]
        if dk is not None:
            dk[lit] = err[:, 0]
    if dk is not None:
        dk[f == 0.0] = 0.0  # outside a spot's cone: exactly 0
    mu = np.einsum("ij,ij->i", to, geo[seg, 3:6])  # the light travels along -to; the eye is along -w
    return d, np.minimum(k, d), mu, f


@njit
def _values(x, d, k, mu, kt, ks, code, g, kt_out, out):
    """The single-scattering integrand (per unit light) at x for one channel: ks Phi(mu)
    exp(-kt (x + k) - kt_out (d - k)) / d^2 for a point light, ks Phi(mu) exp(-kt (x + k)) for a
    directional one (d = inf)."""
    for i in range(x.shape[0]):
        tau = kt * (x[i] + k[i])
        if d[i] < math.inf:
            out[i] = ks * phase_value(code, g, mu[i]) * math.exp(-tau - kt_out * (d[i] - k[i])) / (d[i] * d[i])
        else:
            out[i] = ks * phase_value(code, g, mu[i]) * math.exp(-tau)


@njit
def _uniforms(keys, seg, dims, seed, out):
    for i in range(seg.shape[0]):
        out[i] = uniform(keys[seg[i]], dims[i], seed)


def _channels(prep, sid, geo, directional, seg, x, kts, kss, code, g, kt_outs, facets=None, bounded=False):
    """The integrand at (seg, x) for the channels (M, C); with `bounded`, also its value times a bound
    on its relative rounding (M, C) (`_rounding`)."""
    dk = np.empty(len(x)) if bounded else None
    d, k, mu, f = _geometry(prep, sid, geo, directional, seg, x, facets, dk)
    out = np.empty((len(x), len(kts)))
    col = np.empty(len(x))
    for c in range(len(kts)):
        _values(x, d, k, mu, float(kts[c]), float(kss[c]), code, g, float(kt_outs[c]), col)
        out[:, c] = col * f
    if not bounded:
        return out
    eps = _rounding(geo, seg, x, d, k, dk, kts, kt_outs, code, g)
    with np.errstate(invalid="ignore"):
        return out, np.where(out == 0.0, 0.0, out * eps)


def _rounding(geo, seg, x, d, k, dk, kts, kt_outs, code, g):
    """(M, C) bounds on the integrand's relative rounding at (seg, x) (first order in u = 2^-53, doubled
    and more for the second-order terms; media/slab.py point_rounding's terms, with k's error dk (M,)
    from the walk): the exponent kt (x + k) + kt_out (d - k) rounded to 32u of its size and moved by
    (kt + kt_out) dk, kt 16u |X| (the node's rounding along the ray) and kt_out dd, dd = 8u (|p| + |X|)
    d's rounding, which moves 1 / d^2 and the scattering cosine by dd / d times 2 + the phase's
    condition; a directional light's phase value 8u times its condition."""
    X = np.linalg.norm(geo[seg, :3] + x[:, None] * geo[seg, 3:6], axis=1)
    cond = phase_condition(code, g)
    point = np.isfinite(d)
    dd = np.where(point, 8.0 * U * (np.linalg.norm(geo[seg, 6:9], axis=1) + X), 0.0)
    dist = np.where(point, d, 0.0)
    shape = np.where(point, (2.0 + cond) * dd / np.where(point, d, 1.0), 8.0 * U * cond)
    kt, kt_out = kts[None, :], np.where(point[:, None], kt_outs[None, :], 0.0)
    with np.errstate(invalid="ignore"):
        eps = (32.0 * U * (1.0 + kt * (x + k)[:, None] + kt_out * dist[:, None]) + (kt + kt_out) * dk[:, None]
               + kt * 16.0 * U * X[:, None] + kt_out * dd[:, None] + shape[:, None])
    return np.where(np.isnan(eps), np.inf, eps)




def segment_quadrature(prep, sid, geo, directional, ell, kts, kss, code, g, kt_outs, rule, stats):
    """∫_0^ell of the integrand per segment and channel (N, C) and a bound on its error (N, C), by `adaptive` at the
    QUAD `rule`'s rtol (media/inside_rule.py); the first panels end at a spot's cone crossings (media/slab.py
    straight_cuts) and, in a convex shape, where the light's exit facet changes (`exit_facets`): the integrand is
    smooth on each panel. The bound is the rule's and the integrand's rounding with the length errors of the walks
    or, in a convex shape (here: more than MAX_FACES planes), of the exit facets' planes (`facet_walk.exit_lengths`;
    inf for a segment the facet walk could not follow, measured by Embree's exits) (`_rounding`), inf where a panel
    was left open. An exact sphere: media/slab.py's kernel (`_on_sphere`), bounded."""
    sphere = exact_sphere(prep, sid)
    if sphere is not None:
        val, _, err = _on_sphere(sphere, geo, directional, ell, kts, kss, code, g, kt_outs, rule, stats)
        return val, err
    end = np.minimum(ell, 745.0 / max(float(np.min(kts)), 1e-300))
    convex = prep.interior_planes.get(sid) is not None
    facets = exit_facets(prep, sid, geo, directional, end) if convex else None
    kinks = None if convex else section_kinks(prep, sid, geo, directional, end)
    seg, a, b = _first_panels(geo, directional, end, facets, kinks)
    integrand = lambda ss, xs: _channels(prep, sid, geo, directional, ss, xs, kts, kss, code, g, kt_outs, facets,
                                         True)
    return adaptive(integrand, end, len(kts), seg, a, b, rule.rtol, stats, bounded=True)


class Facets(NamedTuple):
    """facet_walk.walk's pieces of each segment: breakpoints bt from offsets[s] (counts[s] of them; -1:
    not walked), the facets bf of the pieces from offsets[s] + s, the facets' planes (T, 4) and the
    largest norm of the mesh's vertices (`facet_walk.exit_lengths`' rounding)."""
    offsets: np.ndarray
    counts: np.ndarray
    bt: np.ndarray
    bf: np.ndarray
    planes: np.ndarray
    reach: float


def exit_facets(prep, sid, geo, directional, end):
    """The exit facets of the light paths along each segment of the convex shape sid (geometry/facet_walk.py),
    walked from the facet Embree finds at the segment's middle; None if its mesh is not a closed
    2-manifold."""
    own = prep.accel.subset(("shape", sid), lambda: np.nonzero(prep.shape_ids == sid)[0])
    links = prep.memo(("facet links", sid), lambda: facet_walk.mesh_links(own.triangles, own.normals))
    if links is None:
        return None
    tm = 0.5 * end
    p = geo[:, :3] + tm[:, None] * geo[:, 3:6]
    if directional:
        to = np.ascontiguousarray(geo[:, 6:9])
    else:
        rel = geo[:, 6:9] - p
        to = rel / np.maximum(np.linalg.norm(rel, axis=1), 1e-125)[:, None]
    start = own.first_hit(p, to)[1] if len(end) else np.zeros(0, dtype=np.int64)
    offsets, counts, bt, bf = facet_walk.pieces(links, geo, directional, end, start)
    return Facets(offsets, counts, bt, bf, links[0], float(np.max(np.linalg.norm(links[1], axis=1))))


def adaptive(integrand, end, nc, seg, a, b, rtol, stats, bounded=False, narrow=0.0, by_panel=False):
    """∫ over [0, end] of `integrand(seg, x)` (M, nc) per segment and channel (N, nc) from the first
    panels (seg, a, b; ascending in seg), adaptive: panels are halved until their 10- and 20-point
    Gauss-Legendre values agree to rtol, or to rtol/10 of a first estimate of the whole per unit
    length (media/slab.py's rule, vectorised over segments because every evaluation traces rays);
    panels still open after MAX_LEVELS halvings, or beyond the MAX_OPEN bound, count in stats[0].
    The first panels go in groups of whole segments of about MAX_OPEN panels (the facet walk gives
    a segment of a fine mesh hundreds), so that memory stays bounded whatever their number.
    `bounded`: the integrand returns (values, values x their relative rounding bound), and the result
    is (integral, bound): the rule's contract, each accepted panel's 20-point value within |G20 - G10|
    of its integral, which the test keeps below rtol |G20| or the floor times its width, so rtol
    (sum |G20| + estimate / 10) (adaptive.bounded_piecewise's), plus the rounding of the 20-point sums
    (twice: their own and the test's) and of the 10-point sums, and u per panel for the sums; inf for a
    segment with a panel left open. `narrow` > 0: a panel narrower than narrow x rtol x its segment's end is
    accepted as it is, counted in stats[0] (an integrand whose jumps are not located: each adds at most
    its size times that width). `by_panel`: the integrand takes a third argument, (seg, a, b, the panel of
    each point) of the panels it is evaluated on."""
    total = np.zeros((len(end), nc))
    bound = np.zeros((len(end), nc)) if bounded else None
    bounds = np.flatnonzero(np.diff(seg)) + 1  # where a segment's first panels begin
    lo = 0
    while lo < len(seg):
        k = np.searchsorted(bounds, lo + MAX_OPEN)
        hi = bounds[k] if k < len(bounds) else len(seg)
        total += _adaptive(integrand, end, nc, seg[lo:hi], a[lo:hi], b[lo:hi], rtol, stats, bound, narrow, by_panel)
        lo = hi
    return (total, bound) if bounded else total


def _adaptive(integrand, end, nc, seg, a, b, rtol, stats, bound=None, narrow=0.0, by_panel=False):
    """`adaptive` from one group of first panels (`bound` += their bounds, where given); the first
    panels end at every kink of the integrand (`_first_panels`)."""
    n = len(end)
    total = np.zeros((n, nc))
    floor = None
    if bound is not None:
        absum, rounding, panels = np.zeros((n, nc)), np.zeros((n, nc)), np.zeros(n)
        live = np.unique(seg)
    for _ in range(MAX_LEVELS):
        if not len(seg):
            break
        half, mid = 0.5 * (b - a), 0.5 * (a + b)
        xs = np.concatenate([(mid[:, None] + half[:, None] * N10).ravel(), (mid[:, None] + half[:, None] * N20).ravel()])
        ss = np.concatenate([np.repeat(seg, 10), np.repeat(seg, 20)])
        if by_panel:
            pid = np.arange(len(seg))
            f = integrand(ss, xs, (seg, a, b, np.concatenate([np.repeat(pid, 10), np.repeat(pid, 20)])))
        else:
            f = integrand(ss, xs)
        if bound is not None:
            f, fe = f
        m = len(seg)
        g10 = np.einsum("pkc,k->pc", f[:10 * m].reshape(m, 10, nc), W10) * half[:, None]
        g20 = np.einsum("pkc,k->pc", f[10 * m:30 * m].reshape(m, 20, nc), W20) * half[:, None]
        if floor is None:
            floor = np.zeros((n, nc))
            np.add.at(floor, seg, np.abs(g20))
            estimate = floor.copy()
            floor *= 0.1 * rtol / np.where(end > 0.0, end, 1.0)[:, None]
        ok = np.all(np.abs(g20 - g10) <= np.maximum(rtol * np.abs(g20), floor[seg] * (b - a)[:, None]), axis=1)
        if narrow > 0.0:
            small = ~ok & (b - a <= narrow * rtol * end[seg])
            stats[0] += np.count_nonzero(small)
            ok |= small
        if 2 * np.count_nonzero(~ok) > max(MAX_OPEN_PER_SEGMENT * n, MAX_OPEN):  # a memory bound, not a tolerance
            np.add.at(total, seg, g20)
            stats[0] += np.count_nonzero(~ok)
            if bound is not None:
                bound[np.unique(seg[~ok])] = np.inf
                ok[:] = True
                _accepted(absum, rounding, panels, seg, ok, g20, fe, m, half, nc)
                seg = seg[:0]
            break
        np.add.at(total, seg[ok], g20[ok])
        if bound is not None:
            _accepted(absum, rounding, panels, seg, ok, g20, fe, m, half, nc)
        seg, a, b, mid = seg[~ok], a[~ok], b[~ok], mid[~ok]
        seg, a, b = np.concatenate([seg, seg]), np.concatenate([a, mid]), np.concatenate([mid, b])
    else:
        stats[0] += len(seg) // 2
    if bound is not None and floor is not None:
        rule = rtol * (absum + 0.1 * estimate) + rounding + U * panels[:, None] * absum
        rule[np.unique(seg)] = np.inf  # panels left open at MAX_LEVELS
        bound[live] += rule[live]
    return total


def _accepted(absum, rounding, panels, seg, ok, g20, fe, m, half, nc):
    """Add the accepted panels' |G20|, the rounding of their 10- and 20-point sums (2 G20 + G10 of the
    values' rounding bounds fe: the sum's own and the test's) and their count to their segments."""
    r10 = np.einsum("pkc,k->pc", fe[:10 * m].reshape(m, 10, nc), W10) * half[:, None]
    r20 = np.einsum("pkc,k->pc", fe[10 * m:30 * m].reshape(m, 20, nc), W20) * half[:, None]
    np.add.at(absum, seg[ok], np.abs(g20[ok]))
    np.add.at(rounding, seg[ok], 2.0 * r20[ok] + r10[ok])
    np.add.at(panels, seg[ok], 1.0)


def through_quadrature(prep, segs, medium, sids, kt_in, rtol, stats, dplanes=None, balls=None):
    """The outside medium's single scattering (N, 3) over segments `segs` (point and spot lights)
    whose light crosses the index-matched shapes `sids` (interior sigma_t `kt_in`, (S, 3)) on its
    straight path, and its bound (N, 3): the integrand ks Phi(mu) F exp(-kt (x + d)) / d^2 of the
    unshadowed air-light times exp(-(kt_in - kt) . k) over the lengths k inside each shape
    (`chords`), by `adaptive` from the whole segments (cone crossings were cut before:
    segments.cone_segments), bound inf; when every shape is convex or an exact sphere (`boundary`),
    by media/convex_chords.py's kernel of the same rule, chords and integrand, bounded
    (`piece_errors`: dplanes (S, 2) the face planes' errors, balls (S, 4) a ball holding each shape;
    without them, the bound of pieces through face planes is inf)."""
    lights = prep.lights
    kt, ks = medium.sigma_t, medium.sigma_s
    end = np.minimum(segs.length, 745.0 / max(float(np.min(kt)), 1e-300))
    dk = kt_in - kt[None, :]
    bounds = [boundary(prep, sid) for sid in sids]
    if all(b is not None for b in bounds):  # the whole rule in one kernel (media/convex_chords.py)
        out, bound = np.empty((len(end), 3)), np.empty((len(end), 3))
        rows = np.concatenate([np.zeros((0, 4))] + [b[1] for b in bounds])
        offsets = np.cumsum([0] + [len(b[1]) for b in bounds])
        kinds = np.array([b[0] for b in bounds], np.int64)
        node_eps, moves, chord_err = np.empty((len(end), 3)), np.empty((len(end), 3)), np.empty((len(end), len(sids)))
        if dplanes is None:
            dplanes, balls = np.full((len(sids), 2), np.inf), np.zeros((len(sids), 4))
        piece_errors(segs.origins, segs.dirs, end, segs.light, lights.position, lights.cone, rows, offsets, kinds,
                     np.ascontiguousarray(dplanes, dtype=np.float64), np.ascontiguousarray(balls, dtype=np.float64),
                     kt, medium.phase, medium.g, node_eps, moves, chord_err)
        through_pieces(segs.origins, segs.dirs, end, segs.light, lights.position, lights.axis, lights.cone,
                       lights.intensity, rows, offsets, kinds, np.ascontiguousarray(dk), kt, ks, medium.phase,
                       medium.g, rtol, MAX_LEVELS, MAX_OPEN, N10, W10, N20, W20, node_eps, moves, chord_err, out,
                       bound, stats)
        return out, bound
    seg = np.nonzero(end > 0.0)[0]
    return (adaptive(through_integrand(prep, segs, medium, sids, dk), end, 3, seg, np.zeros(len(seg)), end[seg], rtol,
                     stats), np.full((len(end), 3), np.inf))


@njit
def piece_errors(origins, dirs, end, light, positions, cones, rows, offsets, kinds, dplanes, balls, kt, code, g,
                 node_eps, moves, chord_err):
    """The rounding that media/convex_chords.py `through_pieces` bounds per piece i (o + x w, x in
    [0, end[i]], its light at L; R = |o| + end, D and d_min the light's largest and least distance
    from the piece, media/slab.py `light_span`): moves[i] = (dx, du, dd), the point's rounding 16u R,
    the unit direction's to the light 64u (|L| + R) / d_min + 4u, the distance's 8u (|L| + R);
    node_eps[i, c] the relative rounding of the integrand without its chords, as media/slab.py
    `point_rounding`'s with the light's path d (exp(-kt (x + d)): 32u (1 + kt (end + D)) + kt (dd +
    16u R), 1 / d^2 and the scattering cosine (2 + the phase's condition) dd / d_min), + a spot's
    falloff's (error_bounds.spot_allowance) + the exponent sum's exp, 4u; chord_err[i, j] a bound on
    the chord's rounding through shape j's face planes (shadows/through_others.py
    `point_chord_rounding`, the planes dplanes[j] off the faces, inside the ball balls[j]), 0 for an
    exact sphere (its error per evaluation: convex_chords.py `sphere_chord_error`)."""
    geo = np.empty(9)
    for i in range(origins.shape[0]):
        geo[0:3], geo[3:6], geo[6:9] = origins[i], dirs[i], positions[light[i]]
        p, dmax, dmin = light_span(geo, end[i])
        r = math.sqrt(geo[0] * geo[0] + geo[1] * geo[1] + geo[2] * geo[2]) + end[i]
        dd = 8.0 * U * (p + r)
        moves[i, 0], moves[i, 1], moves[i, 2] = 16.0 * U * r, 64.0 * U * (p + r) / dmin + 4.0 * U, dd
        rel = (2.0 + phase_condition(code, g)) * dd / dmin + spot_allowance(cones[light[i], 0]) + 4.0 * U
        for c in range(3):
            node_eps[i, c] = 32.0 * U * (1.0 + kt[c] * (end[i] + dmax)) + kt[c] * (dd + 16.0 * U * r) + rel
        for j in range(kinds.shape[0]):
            chord_err[i, j] = 0.0 if kinds[j] == SPHERE else point_chord_rounding(
                rows, offsets[j], offsets[j + 1], geo[6:9], balls[j], r, dmax, dmin, dplanes[j])[0]


def through_integrand(prep, segs, medium, sids, dk):
    """`through_quadrature`'s integrand for `adaptive`, in NumPy (`chords` for the lengths; dk (S, 3): the
    shapes' sigma_t minus the medium's)."""
    lights = prep.lights
    kt, ks = medium.sigma_t, medium.sigma_s

    def integrand(ss, x):
        li = segs.light[ss]
        p = segs.origins[ss] + x[:, None] * segs.dirs[ss]
        rel = lights.position[li] - p
        d = np.maximum(np.linalg.norm(rel, axis=1), 1e-125)
        to = rel / d[:, None]
        f = np.ones(len(x))
        for l in np.unique(li):  # a spot's falloff toward the direction the light leaves in
            at = np.nonzero(li == l)[0]
            f[at] = falloff_array(np.ascontiguousarray(-to[at] @ lights.axis[l]), *lights.cone[l])
        mu = np.einsum("ij,ij->i", to, segs.dirs[ss])
        att = f[:, None] * np.exp(-chords(prep, sids, p, to, d, lights_holding(prep, li, sids)) @ dk) \
            * lights.intensity[li]
        out = np.empty((len(x), 3))
        col = np.empty(len(x))
        zero = np.zeros(len(x))
        for c in range(3):
            _values(x, d, zero, mu, float(kt[c]), float(ks[c]), medium.phase, medium.g, float(kt[c]), col)
            out[:, c] = col * att[:, c]
        return out

    return integrand


def chords(prep, sids, points, dirs, dist, far_inside=None):
    """Lengths (M, len(sids)) inside each index-matched shape of the segments from `points` outside
    every shape along the unit `dirs` over `dist`: a convex shape's by its face planes, an exact
    sphere's by its roots, in float64 (`boundary`), another's walked with Embree (`inside_lengths`;
    `far_inside` (M, len(sids)): whether each segment's far end, its light, lies inside each shape)."""
    out = np.zeros((len(points), len(sids)))
    walked = []
    for j, sid in enumerate(sids):
        b = boundary(prep, sid)
        if b is None:
            walked.append(j)
            continue
        col = np.empty(len(points))
        boundary_chords(np.ascontiguousarray(points), np.ascontiguousarray(dirs), np.ascontiguousarray(dist), *b, col)
        out[:, j] = col
    if walked:
        out[:, walked] = inside_lengths(prep, points, dirs, dist, [sids[j] for j in walked],
                                        end_inside=np.zeros((len(points), len(walked)), dtype=bool),
                                        far_inside=None if far_inside is None else far_inside[:, walked])[0]
    return out


def section_kinks(prep, sid, geo, directional, end):
    """geometry/sections.py's breaks (offsets, breaks) of the segments in shape sid, a closed mesh."""
    sel = prep.shape_ids == sid
    edges = prep.memo(("section edges", sid), lambda: sections.mesh_edges(prep.accel.triangles[sel]))
    return sections.section_breaks(edges, np.ascontiguousarray(geo), directional, end)


def _first_panels(geo, directional, end, facets=None, kinks=None):
    """(segment, start, end) of the first panels of `segment_quadrature`: [0, end] of every segment
    with end > 0, cut at its spot's cone crossings, at the breakpoints of `facets` (a convex shape) and
    at `kinks` (`section_kinks`: a shape that is not convex)."""
    live = np.nonzero(end > 0.0)[0]
    seg, at = [live, live], [np.zeros(len(live)), end[live]]
    cuts = np.empty(4)
    for s in ([] if directional else live):
        m = straight_cuts(geo[s], end[s], cuts)
        seg.append(np.full(m, s))
        at.append(cuts[:m].copy())
    if facets is not None:
        m = np.maximum(facets.counts, 0)
        seg.append(np.repeat(np.arange(len(end)), m))
        at.append(facets.bt)
    if kinks is not None:
        seg.append(np.repeat(np.arange(len(end)), np.diff(kinks[0])))
        at.append(kinks[1])
    seg, at = np.concatenate(seg).astype(np.int64), np.concatenate(at)
    order = np.lexsort((at, seg))
    seg, at = seg[order], at[order]
    keep = (seg[1:] == seg[:-1]) & (at[1:] > at[:-1])
    return seg[:-1][keep], at[:-1][keep], at[1:][keep]


def segment_march(prep, sid, geo, directional, ell, kts, kss, code, g, kt_outs, rule, channel=None):
    """The midpoint rule with the MARCH `rule`'s steps per segment and channel, the segment cut where its
    optical depth reaches tau_max (media/inside_rule.py; an exact sphere's in its kernel, `_on_sphere`).
    `channel(seg, x, c)`, where given, is the integrand of channel c (`refracted_integrand`), else the
    straight paths' (`_channels`)."""
    sphere = exact_sphere(prep, sid)
    if sphere is not None:
        return _on_sphere(sphere, geo, directional, ell, kts, kss, code, g, kt_outs, rule)[0]
    steps, tau_max = rule.steps, rule.tau_max
    out = np.zeros((len(ell), len(kts)))
    seg = np.repeat(np.arange(len(ell)), steps)
    j = np.tile(np.arange(steps) + 0.5, len(ell))
    channel = channel or _straight(prep, sid, geo, directional, kts, kss, code, g, kt_outs)
    for c in range(len(kts)):
        dx = np.minimum(ell, tau_max / kts[c]) / steps
        out[:, c] = channel(seg, j * dx[seg], c).reshape(len(ell), steps).sum(axis=1) * dx
    return out


def segment_samples(prep, sid, geo, directional, ell, kts, kss, code, g, kt_outs, rule, keys, dim0, seed,
                    channel=None):
    """Free-path sampling (media/inside_rule.py's SAMPLE): the `rule`'s steps samples per segment and
    channel, the same random numbers for every channel (an exact sphere's in media/slab.py's kernel,
    `_on_sphere`); the mean and the variance of the mean (N, C) each. `channel`: `segment_march`'s."""
    sphere = exact_sphere(prep, sid)
    if sphere is not None:
        return _on_sphere(sphere, geo, directional, ell, kts, kss, code, g, kt_outs, rule, keys=keys, dim0=dim0,
                          seed=seed)[:2]
    n, steps = len(ell), rule.steps
    out, var = np.zeros((n, len(kts))), np.zeros((n, len(kts)))
    seg = np.repeat(np.arange(n), steps)
    u = np.empty(len(seg))
    _uniforms(keys, seg, np.tile(np.arange(steps, dtype=np.uint64), n) + np.uint64(dim0), np.uint64(seed), u)
    channel = channel or _straight(prep, sid, geo, directional, kts, kss, code, g, kt_outs)
    for c in range(len(kts)):
        kt = float(kts[c])
        mass = -np.expm1(-kt * np.minimum(ell, rule.tau_max / kt)) / kt
        x = -np.log1p(-u * kt * mass[seg]) / kt
        f = (channel(seg, x, c) * mass[seg] * np.exp(kt * x)).reshape(n, steps)
        out[:, c] = f.mean(axis=1)
        var[:, c] = np.maximum((f * f).mean(axis=1) - out[:, c] ** 2, 0.0) / max(steps - 1, 1)
    return out, var


def _straight(prep, sid, geo, directional, kts, kss, code, g, kt_outs):
    """`segment_march`'s default `channel`: `_channels` of one channel, the light's straight paths."""
    return lambda seg, x, c: _channels(prep, sid, geo, directional, seg, x, kts[c:c + 1], kss[c:c + 1], code, g,
                                       kt_outs[c:c + 1])[:, 0]


PATH_CHUNK = 1 << 19  # candidate (point, face) pairs per call of `face_paths`
LEG_SKIP = 1e-6  # x the scene's scale: how far a leg's test starts from its ends (Embree's float32 crossings)


def refracted_integrand(prep, sid, geo, ell, kts, kss, code, g, kt_outs):
    """The single-scattering integrand (per unit light) of a point or spot light (geo rows of media/slab.py
    GEO_COLUMNS) into the refractive shape sid that is not convex, along its segments (over [0, ell]), as a
    function `values(seg, x, cs, panels=None)` (M, len(cs)) of the channels cs: media/nonconvex_refraction.py's
    Fermat path through every face whose refraction point lies on it (`face_paths`; the faces culled per
    segment, or with `panels` = (seg, a, b, panel of each point) per panel, by `candidates`) and whose legs
    are clear (`clear_legs`), each ks Phi E F exp(-kt (x + k) - kt_out o), summed."""
    return _summed(refracted_paths(prep, sid, geo, ell, code, g), kts, kss, kt_outs)


def _summed(paths, kts, kss, kt_outs):
    """`refracted_integrand`'s `values` from its `paths` (`refracted_paths`)."""
    def values(seg, x, cs, panels=None):
        pt, _, value, k, o = paths(seg, x, panels)
        return _sums(x, pt, value, k, o, kts, kss, kt_outs, cs)[0]
    return values


def _sums(x, pt, value, k, o, kts, kss, kt_outs, cs, eps=None, spot=None):
    """The paths' terms ks value exp(-kt (x + k) - kt_out o) summed per point (len(x), len(cs)), and with eps (paths,
    len(cs)) and spot (paths,) their rounding bounds, the terms times eps plus ks spot exp(...), summed."""
    out = np.empty((len(x), len(cs)))
    err = np.empty((len(x), len(cs))) if eps is not None else None
    for j, c in enumerate(cs):
        att = np.exp(-kts[c] * (x[pt] + k) - kt_outs[c] * o)
        w = kss[c] * value * att
        out[:, j] = np.bincount(pt, weights=w, minlength=len(x))
        if eps is not None:
            err[:, j] = np.bincount(pt, weights=w * eps[:, j] + kss[c] * spot * att, minlength=len(x))
    return out, err


def refracted_paths(prep, sid, geo, ell, code, g):
    """`refracted_integrand`'s paths as a function `paths(seg, x, panels=None, every=False)`: (point, face, value per
    unit light without the exponential, k, o) of each path found (`face_paths`) whose legs are clear; with
    `every`, (point, face, `face_paths`' rows, whether the legs are clear) of every path found."""
    own, tris, planes, eta, geo, ell = _faces(prep, sid, geo, ell)
    whole = _candidates(tris, planes, geo, eta, np.arange(len(ell)), np.zeros(len(ell)), ell,
                        np.zeros(len(ell), np.int64), *every(len(tris)))

    def found(seg, x, which, starts, stops, faces):
        rows, cost, start = [], np.cumsum(stops[which] - starts[which]), 0
        while start < len(x):
            stop = max(int(np.searchsorted(cost, (cost[start - 1] if start else 0) + PATH_CHUNK, "right")), start + 1)
            part = slice(start, stop)
            out = np.empty((int((stops[which[part]] - starts[which[part]]).sum()), PATH_COLUMNS))
            m = face_paths(seg[part], which[part], x[part], geo, tris, planes, starts, stops, faces, eta, code, g, out)
            out[:m, 0] += start
            rows.append(out[:m])
            start = stop
        return np.concatenate(rows) if rows else np.zeros((0, PATH_COLUMNS))

    def paths(seg, x, panels=None, every=False):
        if panels is None:
            rows = found(seg, x, seg, *whole)
        else:
            pseg, a, b, pid = panels
            rows = found(seg, x, pid, *_candidates(tris, planes, geo, eta, pseg, a, b, pseg, *whole))
        pt, face = rows[:, 0].astype(np.int64), rows[:, 1].astype(np.int64)
        keep = clear_legs(own, prep.accel.scale, geo[seg[pt], :3] + x[pt, None] * geo[seg[pt], 3:6], rows[:, 2:5],
                          geo[seg[pt], 6:9], face, rows[:, 8], rows[:, 9])
        if every:
            return pt, face, rows, keep
        return pt[keep], face[keep], rows[keep, 5], rows[keep, 6], rows[keep, 7]
    return paths


def shape_faces(prep, sid):
    """(the accelerator over shape sid's triangles alone, its triangles (T, 3, 3) in float64, their planes (T, 4))."""
    own = prep.accel.subset(("shape", sid), lambda: np.nonzero(prep.shape_ids == sid)[0])
    tris = np.ascontiguousarray(own.triangles, dtype=np.float64)
    return own, tris, prep.memo(("face planes", sid), lambda: face_planes(tris))


def _faces(prep, sid, geo, ell):
    """(`shape_faces`, its relative index, geo, ell) as media/nonconvex_refraction.py's kernels take them."""
    return (*shape_faces(prep, sid), float(prep.scene.shapes[sid].interior.ior),
            np.ascontiguousarray(geo, dtype=np.float64), np.ascontiguousarray(ell, dtype=np.float64))


def _candidates(tris, planes, geo, eta, seg, lo, hi, which, starts, stops, faces):
    """media/nonconvex_refraction.py `candidates` of the pieces [lo, hi] of segments seg among the lists `which`
    of (starts, stops, faces): their (starts, stops, faces)."""
    counts = np.zeros(len(seg), np.int64)
    args = (tris, planes, geo, seg, lo, hi, eta, which, starts, stops, faces, counts)
    candidates(*args, np.zeros(0, np.int64), False)
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    out = np.empty(offsets[-1], np.int64)
    candidates(*args, out, True)
    return offsets[:-1], offsets[1:], out


def refracted_breaks(prep, sid, geo, ell):
    """media/nonconvex_refraction.py `face_breaks` of the segments (geo rows, over [0, ell]) in the refractive
    shape sid that is not convex, those where the face's path is blocked (`clear_legs` at the break: its term
    is 0 on both sides) left out: (segment, x) of the breaks, and whether each segment's were all found."""
    own, tris, planes, eta, geo, ell = _faces(prep, sid, geo, ell)
    n = len(ell)
    whole = _candidates(tris, planes, geo, eta, np.arange(n), np.zeros(n), ell, np.zeros(n, np.int64),
                        *every(len(tris)))
    rows, found = face_breaks(geo, ell, tris, planes, *whole, eta, float(prep.accel.scale))
    seg, face, R = rows[:, 0].astype(np.int64), rows[:, 2].astype(np.int64), rows[:, 3:6]
    X, L = geo[seg, :3] + rows[:, 1:2] * geo[seg, 3:6], geo[seg, 6:9]
    k, o = np.linalg.norm(R - X, axis=1), np.linalg.norm(L - R, axis=1)
    cos_in = np.abs(np.einsum("ij,ij->i", planes[face, :3], R - X)) / np.maximum(k, 1e-300)
    cos_out = np.abs(np.einsum("ij,ij->i", planes[face, :3], L - R)) / np.maximum(o, 1e-300)
    keep = clear_legs(own, prep.accel.scale, X, R, L, face, cos_in, cos_out)
    return seg[keep], rows[keep, 1], found


NARROW = 1e-2  # `refracted_quadrature`'s panels narrower than this x rtol x the segment are accepted as they are
SET_ENDS = 1e-9  # `set_breaks` reads the path set this fraction of a panel inside its ends
SET_WIDTH = 1e-6  # x the segment: `set_breaks` searches the panels wider than this
SET_STEPS = 60  # halvings of `set_breaks`' bisection
MERGE = 1e-13  # x the segment: breaks closer than this are one (`_kinks`)


def refracted_quadrature(prep, sid, geo, ell, kts, kss, code, g, kt_outs, rule, stats):
    """∫_0^ell of `refracted_integrand` per segment and channel (N, C) by `adaptive` at the QUAD `rule`'s rtol
    from first panels cut at the breaks `refracted_breaks` locates (a refraction point crossing its face's edge,
    a spot's cone) and then at those `set_breaks` finds between them (a leg starting or ceasing to meet
    another face, where the panel's ends see different sets of faces), placed by the exact leg test (`refined`);
    the jumps still not located are halved until narrower than NARROW x rtol x the segment, then accepted,
    counted in stats[0] (a jump of size J adds at most about J x that width). Its bound (N, C), `_refracted_bound`:
    the rule's and the paths' rounding (media/nonconvex_refraction.py `path_rounding`) where every node's paths
    are those `lit_scan` proves lit, and the scan's clusters' widths times their jumps; inf where that fails, and
    where a panel narrower than NARROW x rtol x the segment may be accepted unconverged (`_unconverged`). A node
    inside a cluster (a narrow panel between two faces' breaks a few ulps apart has its outer nodes there) may
    count a face wrongly, by at most ks x the cluster's jump: that goes into the node's error bound, which `adaptive`
    carries as it does rounding (2 G20 + G10 of it: the sum's own and its convergence test's)."""
    paths = refracted_paths(prep, sid, geo, ell, code, g)
    end = np.minimum(ell, 745.0 / max(float(np.min(kts)), 1e-300))
    bseg, bx, _ = refracted_breaks(prep, sid, geo, end)
    seg, a, b = _first_panels(geo, True, end, kinks=_kinks(end, bseg, bx))
    wide = b - a > SET_WIDTH * end[seg]
    more = refined(prep, sid, geo, end, code, g, paths, *set_breaks(paths, seg[wide], a[wide], b[wide]))
    kinks = _kinks(end, np.concatenate([bseg, more[0]]), np.concatenate([bx, more[1]]))
    seg, a, b = _first_panels(geo, True, end, kinks=kinks)
    scan = _lit_scan(prep, sid, geo, end, code, g)
    unbounded = ~scan.found
    cs = list(range(len(kts)))

    def values(ss, xs, panels):
        pt, face, rows, keep = paths(ss, xs, panels, every=True)
        status = scan.status(ss[pt], face, xs[pt])
        unbounded[ss[pt[(status != CLUSTER) & ((status == LIT) != keep)]]] = True
        pt, face, rows = pt[keep], face[keep], rows[keep]
        eps, spot = scan.rounding(ss[pt], xs[pt], face, rows[:, 2:5], kts, kt_outs)
        out = _sums(xs, pt, rows[:, 5], rows[:, 6], rows[:, 7], kts, kss, kt_outs, cs, eps, spot)
        out[1][:] += scan.jumps(ss, xs)[:, None] * np.asarray(kss, float)[None, :]
        unbounded[_unconverged(panels, out[0], NARROW * rule.rtol * end, rule.rtol)] = True
        return out
    val, err = adaptive(values, end, len(kts), seg, a, b, rule.rtol, stats, bounded=True, narrow=NARROW,
                        by_panel=True)
    err += scan.cluster_errors(kinks, end, kss)
    err[unbounded] = np.inf
    return val, err


def _unconverged(panels, f, narrow, rtol):
    """The segments of the panels (seg, a, b, the panel of each point: `adaptive`'s by_panel, its 10 Gauss nodes
    then its 20 in their order) narrower than narrow[seg] whose 10- and 20-point values differ by more than half
    of rtol x the 20-point one in a channel (f: the values at the points): `adaptive` may accept them unconverged
    (its test holds where this one does), so their bound is not the rule's; the narrow panels that converge are
    (first panels between two breaks a few ulps of the segment apart, common on fine meshes)."""
    pseg, a, b, pid = panels
    small = np.flatnonzero(b - a <= narrow[pseg])
    if not len(small):
        return pseg[:0]
    at = np.flatnonzero(np.isin(pid, small))
    at = at[np.argsort(pid[at], kind="stable")].reshape(len(small), 30)
    half = 0.5 * (b[small] - a[small])[:, None]
    g10 = np.einsum("pkc,k->pc", f[at[:, :10]], W10) * half
    g20 = np.einsum("pkc,k->pc", f[at[:, 10:]], W20) * half
    return pseg[small[~np.all(np.abs(g20 - g10) <= 0.5 * rtol * np.abs(g20), axis=1)]]


class _Scan(NamedTuple):
    """media/nonconvex_refraction.py `lit_scan` of a shape's segments: whether each finished (found), the kind
    at nodes (`status(seg, face, x)`: LIT, CLUSTER or 0), the summed jumps of the clusters holding nodes
    (`jumps(seg, x)`, media/nonconvex_refraction.py `cluster_jumps`), the paths' rounding (`rounding(seg, x, face, R, kts,
    kt_outs)`: `path_rounding`'s eps, spot) and the clusters' bound (`cluster_errors`)."""
    found: np.ndarray
    status: object
    jumps: object
    rounding: object
    cluster_errors: object


def _lit_scan(prep, sid, geo, end, code, g):
    """`lit_scan` of the segments (geo rows over [0, end]) in the refractive shape sid that is not convex."""
    _, tris, planes, eta, geo, end = _faces(prep, sid, geo, end)
    dn, dc = prep.memo(("face plane errors", sid), lambda: plane_errors(tris, planes))
    n, nt = len(end), len(tris)
    whole = _candidates(tris, planes, geo, eta, np.arange(n), np.zeros(n), end, np.zeros(n, np.int64),
                        *every(nt))
    tree = prep.memo(("face tree", sid), lambda: face_tree(tris))
    rows, found = lit_scan(geo, end, tris, planes, tree, *whole, eta, dn, dc, code, g)
    gid = rows[:, 0].astype(np.int64) * nt + rows[:, 1].astype(np.int64)
    order = np.lexsort((rows[:, 2], gid))
    rows, gid = rows[order], gid[order]
    cmax = float(np.max(np.abs(planes[:, 3]), initial=0.0))

    def status(seg, face, x):
        key = seg * nt + face
        return scan_status(gid, rows[:, 2], rows[:, 3], rows[:, 4], key, x, np.searchsorted(gid, key))

    cl = rows[rows[:, 4] == CLUSTER]
    cl = cl[np.lexsort((cl[:, 2], cl[:, 0]))]
    cseg = cl[:, 0].astype(np.int64)

    def jumps(seg, x):
        return cluster_jumps(cseg, cl[:, 2], cl[:, 3], cl[:, 5], np.searchsorted(cseg, seg), seg, x)

    def rounding(seg, x, face, rp, kts, kt_outs):
        eps, spot = np.empty((len(x), len(kts))), np.empty(len(x))
        path_rounding(seg, x, face, np.ascontiguousarray(rp), geo, planes, eta, end, np.asarray(kts, float), np.asarray(kt_outs, float), code,
                      g, dn, dc, cmax, eps, spot)
        return eps, spot

    def cluster_errors(kinks, end, kss):
        """Each cluster's width times its jump x ks per channel (N, C), widened by RESOLUTION x the scene's size
        each side, where a cut (a first panel's end) lies within that of it; without one, where the face lights
        one side of it and not the other, or a cone level may be crossed in it where it lights either: inf (an
        unlocated jump or kink inside a panel)."""
        out = np.zeros((len(end), len(kss)))
        cl = np.flatnonzero(rows[:, 4] == CLUSTER)
        if not len(cl):
            return out
        s = rows[cl, 0].astype(np.int64)
        width = RESOLUTION * float(prep.accel.scale)
        offsets, cuts = kinks
        x0, x1 = rows[cl, 2] - width, rows[cl, 3] + width
        near = np.array([u <= 0.0 or v >= end[k] or
                         np.searchsorted(cuts[offsets[k]:offsets[k + 1]], u) < np.searchsorted(
                             cuts[offsets[k]:offsets[k + 1]], v, "right")
                         for k, u, v in zip(s.tolist(), x0.tolist(), x1.tolist())], bool)
        lit = rows[:, 4] == LIT
        prv = np.maximum(cl - 1, 0)
        left = lit[prv] & (cl > 0) & (gid[prv] == gid[cl]) & (rows[prv, 3] == rows[cl, 2])
        nxt = np.minimum(cl + 1, len(rows) - 1)
        right = lit[nxt] & (gid[nxt] == gid[cl]) & (rows[nxt, 2] == rows[cl, 3])
        bad = ~near & ((left != right) | ((rows[cl, 6] > 0.0) & (left | right)))
        span = np.where(near, x1 - x0, rows[cl, 3] - rows[cl, 2])
        np.add.at(out, s, (span * rows[cl, 5])[:, None] * np.asarray(kss, float)[None, :])
        out[s[bad]] = np.inf
        return out
    return _Scan(found, status, jumps, rounding, cluster_errors)


def _kinks(end, bseg, bx):
    """(offsets (n + 1,), breaks) of `_first_panels`' kinks from breaks (segment, x) in any order, a break
    within MERGE x end of the one before it dropped (two faces' breaks a few ulps apart: the piece between
    them would never converge)."""
    order = np.lexsort((bx, bseg))
    bseg, bx = bseg[order], bx[order]
    keep = np.ones(len(bx), dtype=bool)
    keep[1:] = (bseg[1:] != bseg[:-1]) | (np.diff(bx) > MERGE * end[bseg[1:]])
    return np.searchsorted(bseg[keep], np.arange(len(end) + 1)), bx[keep]


def set_breaks(paths, seg, a, b):
    """(segment, x, lo, hi) where the set of faces lighting a point (`refracted_paths`' paths: each face's hash, summed)
    changes inside the panels (seg, a, b), found where the sets SET_ENDS inside a panel's ends differ and
    bisected SET_STEPS times (a third set met halfway splits the search in two); changes whose sets agree at the
    panel's ends are not found (the caller leaves out panels narrower than SET_WIDTH x the segment: their ends'
    sets are read too near the breaks that bound them)."""
    keys = np.random.default_rng(0).integers(1, 2 ** 62, size=1 << 20, dtype=np.int64)

    def sets(s, x):
        pt, face, _, _, _ = paths(s, x)
        return np.bincount(pt, weights=(keys[face % len(keys)] % (1 << 40)).astype(np.float64), minlength=len(x))
    lo, hi = a + SET_ENDS * (b - a), b - SET_ENDS * (b - a)
    both = sets(np.concatenate([seg, seg]), np.concatenate([lo, hi]))
    slo, shi = both[:len(seg)], both[len(seg):]
    open_ = slo != shi
    seg, lo, hi, slo, shi = seg[open_], lo[open_], hi[open_], slo[open_], shi[open_]
    for _ in range(SET_STEPS):
        if not len(seg):
            break
        mid = 0.5 * (lo + hi)
        sm = sets(seg, mid)
        left, right = sm != slo, sm != shi  # the change lies left of mid, right of it, or both
        seg, lo, hi, slo, shi = (np.concatenate([seg[left], seg[right]]), np.concatenate([lo[left], mid[right]]),
                                 np.concatenate([mid[left], hi[right]]), np.concatenate([slo[left], sm[right]]),
                                 np.concatenate([sm[left], shi[right]]))
    return seg, 0.5 * (lo + hi), lo, hi


REFINE = 1e-5  # x the segment: how far `refined` seeks a set break's exact place on either side


def refined(prep, sid, geo, end, code, g, paths, seg, x, lo, hi):
    """The set breaks (seg, x) of `set_breaks` (found between lo and hi by Embree's float32 leg tests, `paths`)
    moved to where the exact leg test (`exact_clear`) of a face that lights one side and not the other changes,
    bisected in [x - REFINE end, x + REFINE end] where that test differs at its ends (else x kept)."""
    a, b = paths(np.concatenate([seg, seg]), np.concatenate([lo, hi]))[:2]
    n = len(seg)
    side = {}
    for p_, f in zip(a.tolist(), b.tolist()):
        side.setdefault((p_ % n, f), set()).add(p_ // n)
    pairs = [(p_, f) for (p_, f), sides in side.items() if len(sides) == 1]
    if not pairs:
        return seg, x
    _, tris, planes, eta, geo, _ = _faces(prep, sid, geo, end)
    k = np.array([p_ for p_, _ in pairs])
    face = np.array([f for _, f in pairs], dtype=np.int64)
    s, h = seg[k], REFINE * end[seg[k]]
    u, v = np.maximum(x[k] - h, 0.0), np.minimum(x[k] + h, end[s])
    lu = _exact_lit(tris, planes, eta, geo, s, u, face, code, g, prep.accel.scale)
    moved = lu != _exact_lit(tris, planes, eta, geo, s, v, face, code, g, prep.accel.scale)
    s, face, u, v, lu = s[moved], face[moved], u[moved], v[moved], lu[moved]
    for _ in range(SET_STEPS):
        mid = 0.5 * (u + v)
        same = _exact_lit(tris, planes, eta, geo, s, mid, face, code, g, prep.accel.scale) == lu
        u, v = np.where(same, mid, u), np.where(same, v, mid)
    out = x.copy()
    out[k[moved]] = 0.5 * (u + v)
    return seg, out


def _exact_lit(tris, planes, eta, geo, seg, x, face, code, g, scale):
    """Whether face `face`'s path lights the point x of segment seg (media/nonconvex_refraction.py `face_paths`
    with that face alone) with both legs clear by `exact_clear`."""
    m = len(x)
    out = np.empty((m, PATH_COLUMNS))
    idx = np.arange(m, dtype=np.int64)
    found = out[:face_paths(seg, idx, x, geo, tris, planes, idx, idx + 1, face, eta, code, g, out)]
    pt = found[:, 0].astype(np.int64)
    X = geo[seg[pt], :3] + x[pt, None] * geo[seg[pt], 3:6]
    ok = exact_clear(tris, scale, X, found[:, 2:5], geo[seg[pt], 6:9], face[pt], found[:, 8], found[:, 9])
    lit = np.zeros(m, dtype=bool)
    lit[pt[ok]] = True
    return lit


def exact_clear(tris, scale, X, R, L, face, cos_in, cos_out):
    """`clear_legs` in float64 (Moller-Trumbore) against the triangles whose boxes meet each leg's, the same
    lengths skipped at the ends."""
    skip = LEG_SKIP * scale
    clear = np.ones(len(X), dtype=bool)
    tlo, thi = tris.min(axis=1), tris.max(axis=1)
    ones = np.ones(len(X))
    for a, b, end_skip, start_skip in ((X, R, skip / np.maximum(cos_in, 1e-2), skip * ones),
                                       (R, L, skip * ones, skip / np.maximum(cos_out, 1e-2))):
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        step = max(1, (1 << 22) // max(len(tris), 1))  # legs per box test: memory bounded
        pairs = [np.nonzero(np.all((tlo[None] <= hi[i:i + step, None]) & (thi[None] >= lo[i:i + step, None]), axis=2)
                            & (np.arange(len(tris))[None] != face[i:i + step, None])) for i in range(0, len(X), step)]
        leg = np.concatenate([p[0] + i * step for i, p in enumerate(pairs)] or [np.zeros(0, np.int64)])
        tri = np.concatenate([p[1] for p in pairs] or [np.zeros(0, np.int64)])
        v0, d = tris[tri, 0], b[leg] - a[leg]
        e1, e2 = tris[tri, 1] - v0, tris[tri, 2] - v0
        length = np.linalg.norm(d, axis=1)
        pv = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, pv)
        with np.errstate(divide="ignore", invalid="ignore"):
            tv = a[leg] - v0
            u = np.einsum("ij,ij->i", tv, pv) / det
            qv = np.cross(tv, e1)
            v = np.einsum("ij,ij->i", d, qv) / det
            t = np.einsum("ij,ij->i", e2, qv) / det * length
        hit = ((det != 0.0) & (u >= 0.0) & (v >= 0.0) & (u + v <= 1.0) & (t > start_skip[leg])
               & (t < length - end_skip[leg]))
        clear[leg[hit]] = False
    return clear


def clear_legs(own, scale, X, R, L, face, cos_in, cos_out):
    """Whether each path's legs are clear of the shape `own` (its accelerator: the shape's triangles
    alone): X to its refraction point R on triangle `face` meets no other triangle, nor R to the light L.
    Embree's hits within LEG_SKIP x scale of a leg's start, or of its end over the leg's cosine there
    (cos_in, cos_out: the legs' cosines to the face's normal), are not counted (float32 crossings at
    the leg's own ends)."""
    skip = LEG_SKIP * scale
    clear = np.ones(len(X), dtype=bool)
    for a, b, end_skip, start_skip in ((X, R, skip / np.maximum(cos_in, 1e-2), skip),
                                       (R, L, skip, skip / np.maximum(cos_out, 1e-2))):
        rel = b - a
        d = np.linalg.norm(rel, axis=1)
        u = rel / np.maximum(d, 1e-300)[:, None]
        t, prim = own.first_hit(a + start_skip[..., None] * u if np.ndim(start_skip) else a + start_skip * u, u)
        clear &= (prim < 0) | (prim == face) | (t + start_skip >= d - end_skip)
    return clear


def holding(prep, point, sids) -> np.ndarray:
    """(len(sids),) whether the point (3,) lies inside each shape of `sids` (`contains`, once per point
    and shape in a render: the points are lights' positions)."""
    key = np.asarray(point, float).tobytes()
    return np.array([prep.memo(("holds", sid, key), lambda: contains(prep, point, sid)) for sid in sids], dtype=bool)


def lights_holding(prep, li, sids) -> np.ndarray:
    """(N, len(sids)) whether the light of each id in `li` lies inside each shape of `sids` (a
    directional light never does): a table over the scene's lights, built once per `sids`."""
    lights = prep.lights
    table = prep.memo(("lights holding", tuple(sids)), lambda: np.array(
        [[not lights.distant[l] and contains(prep, lights.position[l], sid) for sid in sids]
         for l in range(len(lights.position))], dtype=bool).reshape(-1, len(sids)))
    return table[np.asarray(li)]


def contains(prep, o, sid) -> bool:
    """Whether shape sid contains the point o: an exact sphere by its radius, a mesh by the parity of
    its triangles' crossings of a ray from o (a fixed direction off every axis and diagonal)."""
    sphere = exact_sphere(prep, sid)
    if sphere is not None:
        return bool(np.linalg.norm(np.asarray(o, float) - sphere[:3]) < sphere[3])
    d = np.array([0.5773502691896258, 0.5773502691896257, 0.5773502691896259]) + np.array([1e-3, -2e-3, 0.0])
    d /= np.linalg.norm(d)
    tris = prep.accel.triangles[prep.shape_ids == sid]
    e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    pv = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, pv)
    ok = np.abs(det) > 1e-300
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    tv = o - tris[:, 0]
    u = np.einsum("ij,ij->i", tv, pv) * inv
    qv = np.cross(tv, e1)
    v = (qv @ d) * inv
    t = np.einsum("ij,ij->i", e2, qv) * inv
    return bool(np.count_nonzero(ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)) % 2)


def exact_sphere(prep, sid):
    """(centre, radius) (4,) of shape sid if it is an exact sphere (geometry/sphere.py), else None."""
    k = prep.accel.sphere_of[prep.shape_ids == sid]
    return prep.accel.spheres[k[0]] if len(k) and k[0] >= 0 else None


def boundary(prep, sid):
    """(kind, rows) of shape sid's boundary for the float64 kernels of media/convex_chords.py: PLANES
    and its face planes (convex: shapes.hull_planes' cache, filled before), SPHERE and an exact
    sphere's (centre, radius); None for a shape walked with Embree."""
    planes = prep.interior_planes.get(sid)
    if planes is not None:
        return PLANES, planes
    sphere = exact_sphere(prep, sid)
    return None if sphere is None else (SPHERE, sphere.reshape(1, 4))


def _on_sphere(sphere, geo, directional, ell, kts, kss, code, g, kt_outs, rule, stats=None, keys=None, dim0=0, seed=0):
    """The `segment_quadrature` (QUAD), `segment_march` (MARCH) or `segment_samples` (SAMPLE) by `rule` of the
    segments inside the exact sphere (centre, radius), per channel: (value, variance, bound) (N, C) each,
    by media/slab.py `sphere_radiance`; stats[0] += its integrals short of their tolerance."""
    n, nc = len(ell), len(kts)
    out, var, err = np.zeros((n, nc)), np.zeros((n, nc)), np.zeros((n, nc))
    col, col_var, col_err = np.empty(n), np.empty(n), np.empty(n)
    slots = np.zeros(3)  # media/adaptive.py's statistics
    keys = np.zeros(n, np.uint64) if keys is None else keys
    geo, ell = np.ascontiguousarray(geo, dtype=np.float64), np.ascontiguousarray(ell, dtype=np.float64)
    for c in range(nc):
        sphere_radiance(np.ascontiguousarray(sphere, dtype=np.float64), geo, bool(directional), ell, float(kts[c]),
                        float(kss[c]), code, g, float(kt_outs[c]), rule, keys, np.uint64(dim0), np.uint64(seed), col,
                        col_var, col_err, slots)
        out[:, c], var[:, c], err[:, c] = col, col_var, col_err
    if stats is not None:
        stats[0] += slots[CAPPED]
    return out, var, err
