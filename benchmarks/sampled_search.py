"""The sampled lit-interval search that preceded the exact lit intervals (raytrace/shadows/frusta.py),
kept for benchmarks/exact_shadows.py's comparison (not part of the renderer).

Lit-interval search. Seen from the light L, the point of a segment at distance x is at the angle
theta = atan((x - x_h) / h) from the foot point (the closed form's own variable, METHODS.md §1);
the ray from L towards it is cos(theta) n + sin(theta) w with length h / cos(theta) (n: unit vector
from L to the foot point, w: the ray direction). Visibility is sampled at angles spaced evenly by
at most `spacing` between the segment's ends, with shadow rays *from the light* (so points far
along rays to infinity need no huge coordinates); the lights' depth pyramids (shadow_maps.py)
decide most samples, alone or in runs, without a ray. Every change of visibility between two
samples is located at the edge of the triangle that blocks the light (`_edges`, exact in float64)
or, where that fails, bisected to BOUNDARY_TOL radians. What it can miss: an occluder (or a gap)
narrower than `spacing` as seen from the light, between two samples of equal visibility.
"""
from __future__ import annotations

import math

import numpy as np

from raytrace.jit import njit
from raytrace.methods import Segments
from raytrace.shadows.shadow_rays import chunks
from benchmarks.shadow_maps import ShadowMaps, face_texel, verdict

SHADOW_SPACING = 0.01  # radians seen from the light between visibility samples (render.shadow_spacing)
SPACING_RANGE = (1e-5, 0.5)
EDGE_STEP = 1e-6  # radians: the probes either side of an occluder edge that confirm it as the boundary
EDGE_ITERS = 4  # triangles followed along one occluder before bisection takes over
BOUNDARY_TOL = 3e-8  # radians: boundaries are bisected to the resolution of float32 ray directions (6e-8)
SAMPLES_PER_CHUNK = 1 << 20  # visibility samples per batch of shadow rays (~100 MB of arrays)

# lit-interval statistics (`lit_intervals`' stats array)
LI_SEGMENTS, LI_SAMPLES, LI_BOUNDARIES, LI_BISECTIONS, LI_INTERVALS, LI_SHADOWED, LI_RAYS, LI_EDGES = range(8)
LI_NAMES = ("segments searched", "visibility samples", "shadow boundaries", "bisection steps",
            "lit intervals", "segments fully shadowed", "shadow rays traced", "boundaries at occluder edges")


def _light_frame(segs: Segments, lights):
    """Per segment: light position L (S, 3), unit n (S, 3) from L to the foot point, x_h, h, and the
    angles of the segment's ends seen from L (theta_b = pi/2 for a segment to infinity)."""
    L = lights.position[segs.light]
    xh = np.einsum("ij,ij->i", L - segs.origins, segs.dirs)
    nvec = segs.origins + xh[:, None] * segs.dirs - L
    h = np.linalg.norm(nvec, axis=1)
    tiny = h <= 1e-12 * np.maximum(np.abs(xh), segs.scale)
    if tiny.any():  # the ray passes through the light: any direction perpendicular to the ray
        w = segs.dirs[tiny]
        alt = np.where(np.abs(w[:, :1]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
        nvec[tiny] = np.cross(w, np.cross(alt, w))
        h[tiny] = np.maximum(h[tiny], 1e-300)
    n = nvec / np.linalg.norm(nvec, axis=1)[:, None]
    th_a = np.arctan2(-xh, h)
    with np.errstate(invalid="ignore"):
        th_b = np.where(np.isinf(segs.length), 0.5 * np.pi, np.arctan2(segs.length - xh, h))
    return L, n, xh, h, th_a, th_b


FLOAT32_MARGIN = 4e-7  # relative: what Embree's float32 rays can misplace a point by


@njit(inline="always")  # called per sample from the kernels below: a call would cost more than its work
def _write_ray(L, lnorm, s, dx, dy, dz, dist, epsilon, o32, d32, t32, j):
    """The float32 shadow ray j from segment s's light towards its point in the air at distance dist
    in the direction (dx, dy, dz). It starts the shadow-ray epsilon away from the light (a light on
    a surface lights the side it faces) and stops float32 rounding short of the point."""
    o32[j, 0], o32[j, 1], o32[j, 2] = L[s, 0] + epsilon * dx, L[s, 1] + epsilon * dy, L[s, 2] + epsilon * dz
    d32[j, 0], d32[j, 1], d32[j, 2] = dx, dy, dz
    if dist < math.inf:
        t32[j] = max(dist - FLOAT32_MARGIN * (dist + lnorm[s]) - epsilon, 0.0)
    else:
        t32[j] = math.inf


@njit(inline="always")
def _point(n, w, h, s, c, sn):
    """Unit direction from segment s's light to its point at the angle of cosine c and sine sn, and
    the distance."""
    return (c * n[s, 0] + sn * w[s, 0], c * n[s, 1] + sn * w[s, 1], c * n[s, 2] + sn * w[s, 2],
            h[s] / c if c > 0.0 else math.inf)


MAX_RUN_LOG2 = 6  # runs of at most 64 samples decided at once by one coarse texel


@njit
def _sample(L, n, w, h, lnorm, light, th_a, th_b, count, first, order, epsilon, table, sizes, offsets, vis, trace,
            o32, d32, t32):
    """Visibility samples k = 0..count[s] of every segment at evenly spaced angles. Runs of samples
    inside one texel of the depth pyramid (shadow_maps.py) that decides their whole range of
    distances are set at once (the run length, a power of two, doubles after a success and halves
    after a failure); other samples are decided by their finest texel or, failing that and always
    get a shadow ray in o32/d32/t32 with their index in trace. The last sample (on the surface the
    segment ends on) is left to `end_visible`. Angles advance by rotation (cosine and sine of the step and of its powers
    of two), so the loop calls no trigonometry. Returns the number of rays to trace."""
    m = 0
    levels = sizes.shape[0]
    rot_c = np.empty(MAX_RUN_LOG2 + 1)
    rot_s = np.empty(MAX_RUN_LOG2 + 1)
    for s in order:  # light by light, neighbouring rays together: their samples share texels
        step = (th_b[s] - th_a[s]) / count[s]
        rot_c[0], rot_s[0] = math.cos(step), math.sin(step)
        for e in range(MAX_RUN_LOG2):
            rot_c[e + 1] = rot_c[e] * rot_c[e] - rot_s[e] * rot_s[e]
            rot_s[e + 1] = 2.0 * rot_s[e] * rot_c[e]
        li = light[s]
        e = -1  # the run is 2^e samples; -1: single samples
        c, sn = math.cos(th_a[s]), math.sin(th_a[s])
        k = 0
        while k < count[s]:
            dx, dy, dz, dist = _point(n, w, h, s, c, sn)
            if levels == 0:
                _write_ray(L, lnorm, s, dx, dy, dz, dist, epsilon, o32, d32, t32, m)
                trace[m] = first[s] + k
                m += 1
                k += 1
                c, sn = c * rot_c[0] - sn * rot_s[0], sn * rot_c[0] + c * rot_s[0]
                continue
            face, i, j = face_texel(sizes, dx, dy, dz)
            decided = False
            while e > 0:
                end = k + (1 << e)
                if end <= count[s] - 1:
                    ce, se = c * rot_c[e] - sn * rot_s[e], sn * rot_c[e] + c * rot_s[e]
                else:
                    end = count[s] - 1
                    if end <= k:
                        break
                    theta = th_a[s] + step * end
                    ce, se = math.cos(theta), math.sin(theta)
                ex, ey, ez, edist = _point(n, w, h, s, ce, se)
                f2, i2, j2 = face_texel(sizes, ex, ey, ez)
                level = 0
                diff = max(i ^ i2, j ^ j2)
                while diff > 0:
                    diff >>= 1
                    level += 1
                if f2 == face and level < levels:
                    r_lo = h[s] if (sn <= 0.0 <= se) else min(dist, edist)
                    v = verdict(table, sizes, offsets, level, li, face, i, j, r_lo, max(dist, edist))
                    if v >= 0:
                        for q in range(k, end + 1):
                            vis[first[s] + q] = v == 1
                        k = end + 1
                        c, sn = ce * rot_c[0] - se * rot_s[0], se * rot_c[0] + ce * rot_s[0]
                        e = min(e + 1, MAX_RUN_LOG2)
                        decided = True
                        break
                e -= 1
            if decided:
                continue
            v = verdict(table, sizes, offsets, 0, li, face, i, j, dist, dist)
            if v >= 0:
                vis[first[s] + k] = v == 1
                e = 1
            else:
                _write_ray(L, lnorm, s, dx, dy, dz, dist, epsilon, o32, d32, t32, m)
                trace[m] = first[s] + k
                m += 1
            k += 1
            c, sn = c * rot_c[0] - sn * rot_s[0], sn * rot_c[0] + c * rot_s[0]
    return m


@njit
def _rays_at(L, n, w, h, lnorm, light, seg, theta, epsilon, table, sizes, offsets, vis, trace, o32, d32, t32):
    """The finest texels' verdicts on one point per entry (bisection midpoints, never on a surface),
    the undecided ones' shadow rays as in `_sample`."""
    m = 0
    for q in range(theta.shape[0]):
        s = seg[q]
        dx, dy, dz, dist = _point(n, w, h, s, math.cos(theta[q]), math.sin(theta[q]))
        v = -1
        if sizes.shape[0]:
            face, i, j = face_texel(sizes, dx, dy, dz)
            v = verdict(table, sizes, offsets, 0, light[s], face, i, j, dist, dist)
        if v >= 0:
            vis[q] = v == 1
        else:
            _write_ray(L, lnorm, s, dx, dy, dz, dist, epsilon, o32, d32, t32, m)
            trace[m] = q
            m += 1
    return m


@njit
def _changes(vis, first, count):
    """(segment, k) of every pair of samples k, k + 1 of one segment with different visibility."""
    seg, ks = [], []
    for s in range(first.shape[0]):
        for k in range(count[s]):
            if vis[first[s] + k] != vis[first[s] + k + 1]:
                seg.append(s)
                ks.append(k)
    return np.array(seg, dtype=np.int64), np.array(ks, dtype=np.int64)


@njit
def _edge_angles(tris, prim, L, n, w, seg, sign, out):
    """For the triangle prim[q] hit from segment seg[q]'s light: the angle (seen from the light, in
    the plane of the light and the segment) where the triangle's cross-section with that plane ends
    on the side `sign` (+1: larger angles); nan where there is no such cross-section."""
    for q in range(prim.shape[0]):
        out[q] = math.nan
        p, s = prim[q], seg[q]
        if p < 0:
            continue
        nx = n[s, 1] * w[s, 2] - n[s, 2] * w[s, 1]
        ny = n[s, 2] * w[s, 0] - n[s, 0] * w[s, 2]
        nz = n[s, 0] * w[s, 1] - n[s, 1] * w[s, 0]
        best = -math.inf
        for e in range(3):
            a, b = tris[p, e], tris[p, (e + 1) % 3]
            da = (a[0] - L[s, 0]) * nx + (a[1] - L[s, 1]) * ny + (a[2] - L[s, 2]) * nz
            db = (b[0] - L[s, 0]) * nx + (b[1] - L[s, 1]) * ny + (b[2] - L[s, 2]) * nz
            if (da > 0.0) == (db > 0.0) and da != 0.0:
                continue
            f = da / (da - db) if da != db else 0.0
            qx = a[0] + f * (b[0] - a[0]) - L[s, 0]
            qy = a[1] + f * (b[1] - a[1]) - L[s, 1]
            qz = a[2] + f * (b[2] - a[2]) - L[s, 2]
            ang = math.atan2(qx * w[s, 0] + qy * w[s, 1] + qz * w[s, 2], qx * n[s, 0] + qy * n[s, 1] + qz * n[s, 2])
            best = max(best, sign[q] * ang)
        if best > -math.inf:
            out[q] = sign[q] * best


def _edges(accel, frame, pyramid, so, lo, hi, vis_lo, stats):
    """Shadow boundaries from the occluders' own edges: from the shadowed end of each bracket, the
    triangle that blocks the light is found (a first-hit ray from the light) and the end of its
    cross-section with the plane of the light and the segment gives the boundary angle exactly, once
    a step of EDGE_STEP beyond it is lit and a step before it shadowed; if not lit, the next triangle
    is tried from there. Returns the brackets, zero-width where a boundary was found."""
    L, n, w, h = frame[:4]
    shadowed = np.where(vis_lo, hi, lo)
    lit = np.where(vis_lo, lo, hi)
    sign = np.where(vis_lo, -1.0, 1.0)  # from the shadowed end towards the lit one
    open_ = np.ones(len(so), bool)
    for _ in range(EDGE_ITERS):
        act = np.nonzero(open_)[0]
        if not len(act):
            break
        s = so[act]
        c, sn = np.cos(shadowed[act]), np.sin(shadowed[act])
        d = c[:, None] * n[s] + sn[:, None] * w[s]
        _, prim = accel.first_hit(L[s] + accel.epsilon * d, d)
        stats[LI_RAYS] += len(act)
        edge = np.empty(len(act))
        _edge_angles(accel.triangles, prim, L, n, w, s, sign[act], edge)
        inside = np.isfinite(edge) & ((edge - shadowed[act]) * sign[act] > 0) & ((lit[act] - edge) * sign[act] > EDGE_STEP)
        open_[act[~inside]] = False  # no usable edge: bisection takes the bracket as it is
        act, edge = act[inside], edge[inside]
        if not len(act):
            break
        probe = np.concatenate([edge + sign[act] * EDGE_STEP, edge - sign[act] * EDGE_STEP])
        seg2 = np.concatenate([so[act], so[act]])
        vis = _trace(accel, _rays_at, frame + (seg2, probe) + pyramid, len(probe), stats)
        after, before = vis[:len(act)], vis[len(act):]
        found = after & ~before
        lo[act[found]] = hi[act[found]] = edge[found]
        open_[act[found]] = False
        stats[LI_EDGES] += int(found.sum())
        onward = ~after & ~before  # the occluder goes on past this triangle
        shadowed[act[onward]] = edge[onward] + sign[act[onward]] * EDGE_STEP
        open_[act[~found & ~onward]] = False
    rest = open_ | (lo != hi)
    lo[rest], hi[rest] = np.minimum(shadowed, lit)[rest], np.maximum(shadowed, lit)[rest]
    return lo, hi


def _trace(accel, kernel, args, m, stats):
    """Run a sampling kernel, then trace the rays it could not decide; returns the visibility."""
    vis = np.zeros(m, bool)
    trace = np.empty(m, np.int64)
    o32, d32, t32 = np.empty((m, 3), np.float32), np.empty((m, 3), np.float32), np.empty(m, np.float32)
    k = kernel(*args, vis, trace, o32, d32, t32)
    vis[trace[:k]] = ~accel.occluded(o32[:k], d32[:k], t32[:k])
    stats[LI_RAYS] += k
    return vis


def end_visible(accel, segs: Segments, L: np.ndarray) -> np.ndarray:
    """Whether each segment's last point sees its light at L (S, 3), tested from the light with a
    float64 first hit: the last point usually lies on a surface, and a shadow ray stopped short of
    it would miss an occluder closer to it than the stop (the far wall of a small closed shape, seen
    through its near wall near the silhouette). What the light's ray meets within float32 reach of
    the point is the point's own surface. A segment to infinity ends lit unless the ray's direction
    itself is blocked."""
    finite = np.isfinite(segs.length)
    end = segs.origins + np.where(finite, segs.length, 0.0)[:, None] * segs.dirs
    v = end - L
    dist = np.where(finite, np.linalg.norm(v, axis=1), np.inf)
    d = np.where(finite[:, None], v / np.where(dist > 0.0, dist, 1.0)[:, None], segs.dirs)
    t, _ = accel.first_hit(L + accel.epsilon * d, d)
    reach = FLOAT32_MARGIN * (dist + np.linalg.norm(L, axis=1))
    with np.errstate(invalid="ignore"):  # inf - inf on segments to infinity
        return (dist <= accel.epsilon) | (t >= dist - accel.epsilon - reach) | ~np.isfinite(t)


def _search(accel, maps, segs, light_frame, spacing, end_lit, stats, edges=True):
    """Lit angular intervals of a chunk: (segment index, theta start, theta end, starts at the
    segment's start, ends at its end). `light_frame`: the chunk's `_light_frame`; `end_lit`:
    whether the light is on the near side of the surface each segment ends on (True where it ends
    in the air)."""
    L, n, xh, h, th_a, th_b = light_frame
    count = np.clip(np.ceil((th_b - th_a) / spacing), 1, None).astype(np.int64)
    first = np.concatenate(([0], np.cumsum(count + 1)[:-1]))
    last = first + count
    frame = (L, n, segs.dirs, h, np.linalg.norm(L, axis=1), segs.light)
    order = np.argsort(segs.light, kind="stable")
    pyramid = (maps.table, maps.sizes, maps.offsets)
    vis = _trace(accel, _sample, frame + (th_a, th_b, count, first, order, accel.epsilon) + pyramid,
                 int(last[-1]) + 1, stats)
    vis[last] = end_lit & end_visible(accel, segs, L)
    stats[LI_RAYS] += len(segs)
    stats[LI_SAMPLES] += len(vis)
    # visibility changes between consecutive samples of one segment: bisect each to BOUNDARY_TOL
    so, k = _changes(vis, first, count)
    width = th_b[so] - th_a[so]
    lo, hi, vis_lo = th_a[so] + width * (k / count[so]), th_a[so] + width * ((k + 1) / count[so]), vis[first[so] + k]
    if len(so) and edges:
        lo, hi = _edges(accel, frame, (accel.epsilon,) + pyramid, so, lo, hi, vis_lo, stats)
    todo = np.nonzero(hi - lo > BOUNDARY_TOL)[0]
    if len(todo):
        steps = int(np.ceil(np.log2(float(np.max(hi[todo] - lo[todo])) / BOUNDARY_TOL)))
        for _ in range(steps):
            mid = 0.5 * (lo[todo] + hi[todo])
            same = _trace(accel, _rays_at, frame + (so[todo], mid, accel.epsilon) + pyramid, len(mid),
                          stats) == vis_lo[todo]
            lo[todo], hi[todo] = np.where(same, mid, lo[todo]), np.where(same, hi[todo], mid)
        stats[LI_BISECTIONS] += steps * len(todo)
    stats[LI_BOUNDARIES] += len(so)
    bound = 0.5 * (lo + hi)
    # interval starts: a visible first sample, or a change to visible; ends: the reverse
    s_seg = np.concatenate([np.nonzero(vis[first])[0], so[~vis_lo]])
    s_th = np.concatenate([th_a[vis[first]], bound[~vis_lo]])
    s_at_start = np.concatenate([np.ones(int(vis[first].sum()), bool), np.zeros(int((~vis_lo).sum()), bool)])
    e_seg = np.concatenate([np.nonzero(vis[last])[0], so[vis_lo]])
    e_th = np.concatenate([th_b[vis[last]], bound[vis_lo]])
    e_at_end = np.concatenate([np.ones(int(vis[last].sum()), bool), np.zeros(int(vis_lo.sum()), bool)])
    si, ei = np.lexsort((s_th, s_seg)), np.lexsort((e_th, e_seg))
    stats[LI_SHADOWED] += len(segs) - len(np.unique(s_seg))
    return s_seg[si], s_th[si], e_th[ei], s_at_start[si], e_at_end[ei]


def lit_intervals(accel, segs: Segments, lights, n_lights: int, spacing: float = SHADOW_SPACING,
                  end_normals=None, maps=None, edges=True):
    """The lit pieces of `segs` as new segments (each from its own start point, t0 along the camera
    ray), and the search's statistics (LI_NAMES). `end_normals` (S, 3): the normal of the surface
    each segment ends on (zero where it ends in the air); the air just before that surface sees the
    light only from the surface's near side. `maps`: the lights' depth cube maps for this spacing
    (shadow_maps.build; None: an exact shadow ray for every sample). `edges`: locate boundaries at
    the occluders' edges where possible (else bisection alone)."""
    maps = ShadowMaps.empty() if maps is None else maps
    directional = lights.distant[segs.light]
    if directional.any():  # directional lights: their own search (`sun_intervals`), the rest as below
        rest = np.nonzero(~directional)[0]
        others, stats = segs.take(rest), np.zeros(len(LI_NAMES))
        if len(rest):
            others, stats = lit_intervals(accel, others, lights, n_lights, spacing,
                                          None if end_normals is None else end_normals[rest], maps, edges)
        sun_idx = np.nonzero(directional)[0]
        pieces = sun_intervals(accel, segs.take(sun_idx), lights, n_lights, spacing,
                               None if end_normals is None else end_normals[sun_idx], stats)
        return concat([p for p in (others, pieces) if len(p)], segs), stats
    end_lit = np.ones(len(segs), bool)
    if end_normals is not None:
        end = segs.origins + np.where(np.isfinite(segs.length), segs.length, 0.0)[:, None] * segs.dirs
        to_light = np.einsum("ij,ij->i", end_normals, lights.position[segs.light] - end)
        toward_camera = -np.einsum("ij,ij->i", end_normals, segs.dirs)
        end_lit = to_light * toward_camera >= 0.0
    stats = np.zeros(len(LI_NAMES))
    stats[LI_SEGMENTS] = len(segs)
    frame = _light_frame(segs, lights)
    th_a, th_b = frame[4], frame[5]
    per_segment = np.clip(np.ceil((th_b - th_a) / spacing), 1, None) + 1
    parts = []
    for part in chunks(per_segment, SAMPLES_PER_CHUNK):
        seg = segs.take(part)
        local = tuple(a[part] for a in frame)
        xh, h = local[2], local[3]
        idx, t_s, t_e, at_start, at_end = _search(accel, maps, seg, local, spacing, end_lit[part], stats, edges)
        x0 = np.where(at_start, 0.0, xh[idx] + h[idx] * np.tan(t_s))
        x1 = np.where(at_end, seg.length[idx], xh[idx] + h[idx] * np.tan(t_e))
        x0 = np.clip(x0, 0.0, seg.length[idx])
        x1 = np.clip(x1, x0, seg.length[idx])
        piece = np.arange(len(idx)) - np.searchsorted(idx, idx)  # number of the piece within its segment
        parts.append(Segments(seg.origins[idx] + x0[:, None] * seg.dirs[idx], seg.dirs[idx], x1 - x0,
                              seg.light[idx], seg.ray[idx], seg.t0[idx] + x0, seg.keys[idx],
                              seg.stream[idx] + n_lights * piece, seg.seed, seg.scale))
    stats[LI_INTERVALS] = sum(len(p) for p in parts)
    return concat(parts, segs), stats


def sun_end_visible(accel, segs: Segments, wi: np.ndarray) -> np.ndarray:
    """Whether each segment's last point sees the sun (toward wi), tested as `end_visible` does for
    a point light: a float64 first hit from outside the scene's bounds toward the point, so that no
    offset steps over an occluder near it. Segments to infinity end lit."""
    finite = np.isfinite(segs.length)
    end = segs.origins + np.where(finite, segs.length, 0.0)[:, None] * segs.dirs
    far = np.linalg.norm(end, axis=1) + 2.0 * accel.scale  # beyond every triangle (|coordinates| <= scale)
    start = end + far[:, None] * wi
    t, _ = accel.first_hit(start, -wi)
    reach = FLOAT32_MARGIN * (far + np.linalg.norm(start, axis=1))
    return ~finite | (t >= far - reach)


SUN_BISECTIONS = 48  # halvings of a sample interval in u: below 1e-14 of the scene's size near the camera


def sun_intervals(accel, segs: Segments, lights, n_lights: int, spacing: float, end_normals, stats) -> Segments:
    """The pieces of directional lights' segments from which the sun is not hidden by a mesh (the
    planet of an atmosphere shadows through the transmittance). The sun has no position to measure
    angles from, so a segment is sampled evenly in u = x / (x + S), S the segment's length or, if
    shorter, the scene's size (u < 1 on rays to infinity; a point light's quarter circle of angles
    maps to u in [0, 1) alike), with
    ceil(u_end / (2 spacing / pi)) intervals; each sample in the air sends a shadow ray to infinity
    toward the sun, the last one (on the surface the segment ends on) is tested by `sun_end_visible`,
    and every change of visibility between two samples is bisected SUN_BISECTIONS times in u. What
    it can miss: an occluder (or gap) thinner than a sample interval. A segment ending on a surface
    that faces away from the sun ends unlit."""
    ell = segs.length
    S = np.maximum(np.minimum(ell, segs.scale), 1e-300)
    u_end = np.divide(ell, ell + S, out=np.ones_like(ell), where=np.isfinite(ell))
    count = np.maximum(1, np.ceil(u_end / (2.0 * spacing / np.pi))).astype(np.int64)
    first = np.concatenate([[0], np.cumsum(count + 1)[:-1]]).astype(np.int64)
    last = first + count
    seg_of = np.repeat(np.arange(len(segs)), count + 1)
    k = np.arange(len(seg_of)) - first[seg_of]
    u = u_end[seg_of] * k / count[seg_of]
    wi = -lights.axis[segs.light]

    def visible(seg, uu):
        x = np.where(uu >= 1.0, np.inf, S[seg] * uu / np.maximum(1.0 - uu, 1e-300))
        finite = np.isfinite(x)
        p = segs.origins[seg] + np.where(finite, x, 0.0)[:, None] * segs.dirs[seg]
        out = ~accel.occluded(p, wi[seg], np.full(len(seg), np.inf))
        # a ray to infinity: its far end sees the sun unless the ray itself runs into the shadow
        return np.where(finite, out, True)

    air = np.ones(len(seg_of), bool)
    air[last] = False
    vis = np.empty(len(seg_of), bool)
    vis[air] = visible(seg_of[air], u[air])
    vis[last] = sun_end_visible(accel, segs, wi)
    if end_normals is not None:  # the last sample of a segment ending on a surface facing away: unlit
        facing = np.einsum("ij,ij->i", end_normals, wi) * -np.einsum("ij,ij->i", end_normals, segs.dirs) >= 0.0
        vis[last] &= facing
    stats[LI_SEGMENTS] += len(segs)
    stats[LI_SAMPLES] += len(vis)
    stats[LI_RAYS] += len(vis)
    change = np.nonzero((vis[:-1] != vis[1:]) & (seg_of[:-1] == seg_of[1:]))[0]
    lo, hi = u[change], np.minimum(u[change + 1], 1.0 - 1e-12)
    vis_lo = vis[change]
    cseg = seg_of[change]
    for _ in range(SUN_BISECTIONS):
        if not len(change):
            break
        mid = 0.5 * (lo + hi)
        same = visible(cseg, mid) == vis_lo
        lo, hi = np.where(same, mid, lo), np.where(same, hi, mid)
        stats[LI_RAYS] += len(change)
        stats[LI_BISECTIONS] += len(change)
    stats[LI_BOUNDARIES] += len(change)
    src, u0, u1 = _lit_runs(vis, first, count, u_end, cseg, 0.5 * (lo + hi))
    x0 = S[src] * u0 / (1.0 - u0)
    with np.errstate(divide="ignore"):
        x1 = np.where(u1 >= u_end[src], ell[src], S[src] * u1 / (1.0 - u1))
    x1 = np.clip(x1, x0, ell[src])
    piece = np.arange(len(src)) - np.searchsorted(src, src)
    stats[LI_SHADOWED] += len(segs) - len(np.unique(src))
    stats[LI_INTERVALS] += len(src)
    return Segments(segs.origins[src] + x0[:, None] * segs.dirs[src], segs.dirs[src], x1 - x0, segs.light[src],
                    segs.ray[src], segs.t0[src] + x0, segs.keys[src], segs.stream[src] + n_lights * piece, segs.seed,
                    segs.scale)


@njit
def _lit_runs(vis, first, count, u_end, cseg, bound):
    """(segment, u0, u1) of every lit run: samples k = 0..count[s] of segment s from first[s], the
    boundaries `bound` (ascending within each segment, in segment order cseg) where visibility
    changes; a run starts at 0 or at a boundary to lit and ends at the next boundary or u_end."""
    src, a, b = [], [], []
    j = 0
    for s in range(first.shape[0]):
        lit = vis[first[s]]
        start = 0.0
        while j < cseg.shape[0] and cseg[j] == s:
            if lit:
                src.append(s)
                a.append(start)
                b.append(bound[j])
            else:
                start = bound[j]
            lit = not lit
            j += 1
        if lit:
            src.append(s)
            a.append(start)
            b.append(u_end[s])
    return np.array(src, dtype=np.int64), np.array(a), np.array(b)



def concat(parts: list[Segments], like: Segments) -> Segments:
    if not parts:
        return like.take(slice(0, 0))
    cat = lambda name: np.concatenate([getattr(p, name) for p in parts])  # noqa: E731
    return Segments(cat("origins"), cat("dirs"), cat("length"), cat("light"), cat("ray"), cat("t0"), cat("keys"),
                    cat("stream"), like.seed, like.scale)
