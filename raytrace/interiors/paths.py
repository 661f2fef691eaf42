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
media/slab.py instead). `through_quadrature` integrates the outside medium where its light crosses
index-matched shapes (media/convex_chords.py's kernel when they are all convex). The shadow rays of
surfaces use `inside_lengths` too (bounded.shadow_through): through an index-matched interior they are
attenuated, not blocked.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..geometry import facet_walk
from ..jit import njit
from ..lights import NO_CONE, SMOOTHSTEP, falloff_array
from ..media.convex_chords import chords_into, through_pieces
from ..media.phase import phase_value
from ..media.slab import straight_cuts
from ..rng import uniform

MAX_CROSSINGS = 64  # boundary crossings followed along one segment (more: the rest counts as outside)
FAR = 3.5  # x the scene's scale: from any scene point this far toward a directional light is outside every shape
MAX_LEVELS = 40  # halvings of a quadrature panel
# open panels one level of `segment_quadrature` may hold: an integrand that never settles (float32
# crossings jitter inside lengths by ~1e-7 of the scene) would otherwise double them every level
# (the slow fuzz run reached 23 GB); beyond it the open panels keep their 20-point values, counted
MAX_OPEN_PER_SEGMENT, MAX_OPEN = 4, 1 << 16
FLOAT32_SLACK = 1e-6  # relative: how far Embree's float32 distance may be from the exact one


def inside_lengths(prep, points, dirs, dist, sids, block=False, margin=0.0, end_inside=None):
    """`walk`, and again from a far end moved sideways by RETRY_SHIFT x the scene's scale for the
    segments whose parity at the point contradicts `end_inside` (N, len(sids)) where given: Embree's
    float32 decisions for two rays near a shape's edge can disagree and lose one crossing of a short
    chord (a path grazing a corner), which would count the rest of the path on the wrong side."""
    lengths, blocked, inside = walk(prep, points, dirs, dist, sids, block, margin)
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
    return lengths, blocked


RETRIES = 3
RETRY_SHIFT = 1e-5
SIDEWAYS = np.array([[0.6, 0.0, 0.8], [0.0, 0.8, 0.6], [0.8, 0.6, 0.0]])


def walk(prep, points, dirs, dist, sids, block=False, margin=0.0):
    """Lengths (N, len(sids)) inside each shape of `sids` of the segments from `points` along the
    unit `dirs` over `dist` (inf: toward a directional light), and (N,) whether another shape lies on
    the segment (only looked for with `block`; then the walk stops there). The segment is walked from
    its far end, which must lie outside every shape of `sids`, back to the point (crossings closer to it
    than `margin` are not counted: a surface point's own face); and
    (N, len(sids)) whether the walk ends inside each shape."""
    accel = prep.accel
    n = len(points)
    sids = np.asarray(sids, dtype=np.int64)
    lengths = np.zeros((n, len(sids)))
    blocked = np.zeros(n, dtype=bool)
    far = np.where(np.isinf(dist), FAR * accel.scale + np.linalg.norm(points, axis=1), dist)
    start = points + far[:, None] * dirs
    back = -dirs
    stop = far - margin
    inside = np.zeros((n, len(sids)), dtype=bool)
    since = np.zeros((n, len(sids)))
    s = np.where(np.isinf(dist), 0.0, accel.epsilon)  # a point light on a surface: not that surface
    active = np.nonzero(stop > 0.0)[0]
    lookup = np.full(len(prep.scene.shapes), -1, dtype=np.int64)
    lookup[sids] = np.arange(len(sids))
    for _ in range(MAX_CROSSINGS):
        if not len(active):
            break
        o = start[active] + s[active, None] * back[active]
        t, prim = accel.first_hit(o, back[active])
        t32 = accel.hit_distance32(o, back[active])
        with np.errstate(invalid="ignore"):  # inf - inf on a miss
            off = (prim >= 0) & (np.abs(t - t32) > FLOAT32_SLACK * (t32 + accel.scale))
        t[off] = t32[off]  # the refinement took a neighbour's plane (a ray grazing an edge): keep Embree's
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
        go = np.nonzero(~done)[0]
        r = active[go]
        cos = np.abs(np.einsum("ij,ij->i", accel.hit_normals(prim[go], start[r] + at[go, None] * back[r]), back[r]))
        skip = accel.epsilon / np.maximum(cos, 1e-2)
        s[r] = at[go] + skip
        # a second crossing within the skip (a corner clipped): found looking back from the new start
        tb, pb = accel.first_hit(start[r] + s[r, None] * back[r], dirs[r])
        extra = (pb >= 0) & (pb != prim[go]) & (tb < (1.0 - 1e-9) * skip) & (s[r] - tb < stop[r])
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
        active = r[s[r] < stop[r]]
        fin = r[s[r] >= stop[r]]
        lengths[fin] += np.where(inside[fin] & np.isfinite(s[fin, None]), far[fin, None] - since[fin], 0.0)
    return lengths, blocked, inside


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


def _geometry(prep, sid, geo, directional, seg, x, facets=None):
    """At the points x along segments `seg` (geo rows of media/slab.py's inside_radiance: entry point,
    direction w, the light's position or minus its direction of travel, a spot's axis and cone): the
    light's distance d (inf for a directional light), its path's length k inside shape sid (on the
    exit facets of `exit_facets` where the walk holds them), the scattering cosine mu and a spot's
    falloff toward the direction it leaves in (1 for other lights)."""
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
    if facets is not None:
        walked = lit[facets.counts[seg[lit]] >= 0]
        col = np.empty(len(walked))
        facet_walk.exit_lengths(seg[walked], x[walked], p[walked], np.ascontiguousarray(to[walked]), d[walked],
                                facets.offsets, facets.counts, facets.bt, facets.bf, facets.planes, col)
        k[walked] = col
        lit = lit[facets.counts[seg[lit]] < 0]
    if prep.interior_planes.get(sid) is not None:  # convex (bounded.hull_planes, filled before integrating)
        k[lit] = convex_exits(prep, sid, p[lit], to[lit], d[lit])
    else:
        k[lit] = inside_lengths(prep, p[lit], to[lit], d[lit], [sid],
                                end_inside=np.ones((len(lit), 1), dtype=bool))[0][:, 0]
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


def _channels(prep, sid, geo, directional, seg, x, kts, kss, code, g, kt_outs, facets=None):
    """The integrand at (seg, x) for the channels (M, C)."""
    d, k, mu, f = _geometry(prep, sid, geo, directional, seg, x, facets)
    out = np.empty((len(x), len(kts)))
    col = np.empty(len(x))
    for c in range(len(kts)):
        _values(x, d, k, mu, float(kts[c]), float(kss[c]), code, g, float(kt_outs[c]), col)
        out[:, c] = col * f
    return out


_N10, _W10 = np.polynomial.legendre.leggauss(10)
_N20, _W20 = np.polynomial.legendre.leggauss(20)


def segment_quadrature(prep, sid, geo, directional, ell, kts, kss, code, g, kt_outs, rtol, stats):
    """∫_0^ell of the integrand per segment and channel (N, C), by `adaptive`; the first panels end at
    a spot's cone crossings (media/slab.py straight_cuts) and, in a convex shape, where the light's
    exit facet changes (`exit_facets`): the integrand is smooth on each panel."""
    end = np.minimum(ell, 745.0 / max(float(np.min(kts)), 1e-300))
    facets = exit_facets(prep, sid, geo, directional, end) if prep.interior_planes.get(sid) is not None else None
    seg, a, b = _first_panels(geo, directional, end, facets)
    return adaptive(lambda ss, xs: _channels(prep, sid, geo, directional, ss, xs, kts, kss, code, g, kt_outs, facets),
                    end, len(kts), seg, a, b, rtol, stats)


class Facets(NamedTuple):
    """facet_walk.walk's pieces of each segment: breakpoints bt from offsets[s] (counts[s] of them; -1:
    not walked), the facets bf of the pieces from offsets[s] + s, and the facets' planes (T, 4)."""
    offsets: np.ndarray
    counts: np.ndarray
    bt: np.ndarray
    bf: np.ndarray
    planes: np.ndarray


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
    return Facets(offsets, counts, bt, bf, links[0])


def adaptive(integrand, end, nc, seg, a, b, rtol, stats):
    """∫ over [0, end] of `integrand(seg, x)` (M, nc) per segment and channel (N, nc) from the first
    panels (seg, a, b; ascending in seg), adaptive: panels are halved until their 10- and 20-point
    Gauss-Legendre values agree to rtol, or to rtol/10 of a first estimate of the whole per unit
    length (media/slab.py's rule, vectorised over segments because every evaluation traces rays);
    panels still open after MAX_LEVELS halvings, or beyond the MAX_OPEN bound, count in stats[0].
    The first panels go in groups of whole segments of about MAX_OPEN panels (the facet walk gives
    a segment of a fine mesh hundreds), so that memory stays bounded whatever their number."""
    total = np.zeros((len(end), nc))
    bounds = np.flatnonzero(np.diff(seg)) + 1  # where a segment's first panels begin
    lo = 0
    while lo < len(seg):
        k = np.searchsorted(bounds, lo + MAX_OPEN)
        hi = bounds[k] if k < len(bounds) else len(seg)
        total += _adaptive(integrand, end, nc, seg[lo:hi], a[lo:hi], b[lo:hi], rtol, stats)
        lo = hi
    return total


def _adaptive(integrand, end, nc, seg, a, b, rtol, stats):
    """`adaptive` from one group of first panels."""
    n = len(end)
    total = np.zeros((n, nc))
    floor = None
    for _ in range(MAX_LEVELS):
        if not len(seg):
            return total
        half, mid = 0.5 * (b - a), 0.5 * (a + b)
        xs = np.concatenate([(mid[:, None] + half[:, None] * _N10).ravel(), (mid[:, None] + half[:, None] * _N20).ravel()])
        ss = np.concatenate([np.repeat(seg, 10), np.repeat(seg, 20)])
        f = integrand(ss, xs)
        m = len(seg)
        g10 = np.einsum("pkc,k->pc", f[:10 * m].reshape(m, 10, nc), _W10) * half[:, None]
        g20 = np.einsum("pkc,k->pc", f[10 * m:].reshape(m, 20, nc), _W20) * half[:, None]
        if floor is None:
            floor = np.zeros((n, nc))
            np.add.at(floor, seg, np.abs(g20))
            floor *= 0.1 * rtol / np.where(end > 0.0, end, 1.0)[:, None]
        ok = np.all(np.abs(g20 - g10) <= np.maximum(rtol * np.abs(g20), floor[seg] * (b - a)[:, None]), axis=1)
        if 2 * np.count_nonzero(~ok) > max(MAX_OPEN_PER_SEGMENT * n, MAX_OPEN):  # a memory bound, not a tolerance
            np.add.at(total, seg, g20)
            stats[0] += np.count_nonzero(~ok)
            return total
        np.add.at(total, seg[ok], g20[ok])
        seg, a, b, mid = seg[~ok], a[~ok], b[~ok], mid[~ok]
        seg, a, b = np.concatenate([seg, seg]), np.concatenate([a, mid]), np.concatenate([mid, b])
    stats[0] += len(seg) // 2
    return total


def through_quadrature(prep, segs, medium, sids, kt_in, rtol, stats):
    """The outside medium's single scattering (N, 3) over segments `segs` (point and spot lights)
    whose light crosses the index-matched shapes `sids` (interior sigma_t `kt_in`, (S, 3)) on its
    straight path: the integrand ks Phi(mu) F exp(-kt (x + d)) / d^2 of the unshadowed air-light
    times exp(-(kt_in - kt) . k) over the lengths k inside each shape (`chords`), by `adaptive`
    from the whole segments (cone crossings were cut before: segments.cone_segments); when every
    shape is convex, by media/convex_chords.py's kernel of the same rule, chords and integrand."""
    lights = prep.lights
    kt, ks = medium.sigma_t, medium.sigma_s
    end = np.minimum(segs.length, 745.0 / max(float(np.min(kt)), 1e-300))
    dk = kt_in - kt[None, :]
    planes = [prep.interior_planes.get(sid) for sid in sids]
    if all(p is not None for p in planes):  # convex: the whole rule in one kernel (media/convex_chords.py)
        out = np.empty((len(end), 3))
        through_pieces(segs.origins, segs.dirs, end, segs.light, lights.position, lights.axis, lights.cone,
                       lights.intensity, np.concatenate([np.zeros((0, 4)), *planes]),
                       np.cumsum([0] + [len(p) for p in planes]),
                       np.ascontiguousarray(dk), kt, ks, medium.phase, medium.g, rtol, MAX_LEVELS, MAX_OPEN,
                       _N10, _W10, _N20, _W20, out, stats)
        return out
    seg = np.nonzero(end > 0.0)[0]
    return adaptive(through_integrand(prep, segs, medium, sids, dk), end, 3, seg, np.zeros(len(seg)), end[seg], rtol,
                    stats)


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
        att = f[:, None] * np.exp(-chords(prep, sids, p, to, d) @ dk) * lights.intensity[li]
        out = np.empty((len(x), 3))
        col = np.empty(len(x))
        zero = np.zeros(len(x))
        for c in range(3):
            _values(x, d, zero, mu, float(kt[c]), float(ks[c]), medium.phase, medium.g, float(kt[c]), col)
            out[:, c] = col * att[:, c]
        return out

    return integrand


def chords(prep, sids, points, dirs, dist):
    """Lengths (M, len(sids)) inside each index-matched shape of the segments from `points` outside
    every shape along the unit `dirs` over `dist`: a convex shape's by its face planes in float64
    (bounded.hull_planes' cache), another's walked with Embree (`inside_lengths`)."""
    out = np.zeros((len(points), len(sids)))
    walked = []
    for j, sid in enumerate(sids):
        planes = prep.interior_planes.get(sid)
        if planes is None:
            walked.append(j)
            continue
        col = np.empty(len(points))
        chords_into(np.ascontiguousarray(points), np.ascontiguousarray(dirs), np.ascontiguousarray(dist), planes, col)
        out[:, j] = col
    if walked:
        out[:, walked] = inside_lengths(prep, points, dirs, dist, [sids[j] for j in walked],
                                        end_inside=np.zeros((len(points), len(walked)), dtype=bool))[0]
    return out


def _first_panels(geo, directional, end, facets=None):
    """(segment, start, end) of the first panels of `segment_quadrature`: [0, end] of every segment
    with end > 0, cut at its spot's cone crossings and at the breakpoints of `facets`."""
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
    seg, at = np.concatenate(seg).astype(np.int64), np.concatenate(at)
    order = np.lexsort((at, seg))
    seg, at = seg[order], at[order]
    keep = (seg[1:] == seg[:-1]) & (at[1:] > at[:-1])
    return seg[:-1][keep], at[:-1][keep], at[1:][keep]


def segment_march(prep, sid, geo, directional, ell, kts, kss, code, g, kt_outs, steps, tau_max):
    """The midpoint rule with `steps` points per segment and channel, the segment cut where its optical
    depth reaches tau_max (media/slab.py's MARCH)."""
    out = np.zeros((len(ell), len(kts)))
    seg = np.repeat(np.arange(len(ell)), steps)
    j = np.tile(np.arange(steps) + 0.5, len(ell))
    for c in range(len(kts)):
        dx = np.minimum(ell, tau_max / kts[c]) / steps
        f = _channels(prep, sid, geo, directional, seg, j * dx[seg], kts[c:c + 1], kss[c:c + 1], code, g,
                      kt_outs[c:c + 1])[:, 0]
        out[:, c] = f.reshape(len(ell), steps).sum(axis=1) * dx
    return out


def segment_samples(prep, sid, geo, directional, ell, kts, kss, code, g, kt_outs, steps, keys, dim0, seed):
    """Free-path sampling (media/slab.py's SAMPLE): `steps` samples per segment and channel, the same
    random numbers for every channel; the mean and the variance of the mean (N, C) each."""
    n = len(ell)
    out, var = np.zeros((n, len(kts))), np.zeros((n, len(kts)))
    seg = np.repeat(np.arange(n), steps)
    u = np.empty(len(seg))
    _uniforms(keys, seg, np.tile(np.arange(steps, dtype=np.uint64), n) + np.uint64(dim0), np.uint64(seed), u)
    for c in range(len(kts)):
        kt = float(kts[c])
        mass = -np.expm1(-kt * np.minimum(ell, 745.0 / kt)) / kt
        x = -np.log1p(-u * kt * mass[seg]) / kt
        f = _channels(prep, sid, geo, directional, seg, x, kts[c:c + 1], kss[c:c + 1], code, g, kt_outs[c:c + 1])[:, 0]
        f = (f * mass[seg] * np.exp(kt * x)).reshape(n, steps)
        out[:, c] = f.mean(axis=1)
        var[:, c] = np.maximum((f * f).mean(axis=1) - out[:, c] ** 2, 0.0) / max(steps - 1, 1)
    return out, var
