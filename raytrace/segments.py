"""From camera rays to segments (ARCHITECTURE.md): `whole_rays` makes the unshadowed segments, one
[0, t_hit] per (ray, light); `cone_segments` cuts them to where spot lights shine; the lit intervals
of shadows/frusta.py cut them further (volumetric shadows), so that every method integrates the
shadowed air-light exactly between shadow boundaries. `gather` adds segment air-lights to their
camera rays with the medium's transmittance from the camera to each segment's start.
"""
from __future__ import annotations

import math

import numpy as np

from .jit import exact_njit, njit
from .lights import has_cone, segment_cone
from .methods import Segments
from .methods.geometry import segment_geometry, v_of


def whole_rays(origins, dirs, tmax, keys, n_lights, seed=0, scale=1.0) -> Segments:
    """One segment [0, tmax] per (ray, light), ray-major (segment r L + l)."""
    s = len(origins) * n_lights
    o, d, length = np.empty((s, 3)), np.empty((s, 3)), np.empty(s)
    light, ray, k = np.empty(s, np.int64), np.empty(s, np.int64), np.empty(s, np.uint64)
    _whole_rays(origins, dirs, np.asarray(tmax, np.float64), np.asarray(keys, np.uint64), o, d, length, light, ray, k)
    return Segments(o, d, length, light, ray, np.zeros(s), k, light.copy(), int(seed), float(scale), per_ray=n_lights)


@njit
def _whole_rays(origins, dirs, tmax, keys, o, d, length, light, ray, k):
    """Each ray's row copied to its segments r L + l (L = len(o) / len(origins)), light l."""
    per = o.shape[0] // max(origins.shape[0], 1)
    for s in range(o.shape[0]):
        r = s // per
        for a in range(3):
            o[s, a], d[s, a] = origins[r, a], dirs[r, a]
        length[s], light[s], ray[s], k[s] = tmax[r], s - r * per, r, keys[r]


CONE_STREAM = 1 << 20  # stream offset of a spot light's second lit piece (a cone cuts a line at most twice)


def cone_segments(segs: Segments, lights, end_normals=None):
    """The segments cut to where their spot lights shine (cosine to the axis above cos_end: at most
    two pieces of a line, lights.segment_cone), dark ones dropped; point lights' segments unchanged.
    `end_normals` (S, 3) or None follow the segments, zero for a piece that now ends in the air."""
    if not lights.cones():
        return segs, end_normals
    xh, h, _, cone = segment_geometry(segs, lights)
    src, x0, x1, piece = _cone_pieces(xh, h, segs.length, cone)
    cut = pieces(segs, src, x0, x1, piece, CONE_STREAM * len(lights))
    if end_normals is not None:
        end_normals = end_normals[src] * (x1 == segs.length[src])[:, None]
    return cut, end_normals


def pieces(segs: Segments, src, x0, x1, piece=None, step: int = 0) -> Segments:
    """The pieces [x0, x1] (along each segment from its own start) of the segments `src` as segments
    from their own start points: origin o + x0 w, t0 + x0, length x1 - x0, stream + step piece (the
    piece's number), the rest the source's; one kernel for what NumPy's indexing gave, bit for bit."""
    src = np.asarray(src, np.int64)
    piece = src if piece is None else np.asarray(piece, np.int64)
    o, d, length, t0, stream = _pieces(segs.origins, segs.dirs, segs.t0, segs.stream, src, x0, x1, piece, step)
    return Segments(o, d, length, segs.light[src], segs.ray[src], t0, segs.keys[src], stream, segs.seed, segs.scale)


@exact_njit
def _pieces(origins, dirs, t0, stream, src, x0, x1, piece, step):
    """`pieces`' kernel: the start points, directions, lengths, starts and streams of the pieces."""
    m = src.shape[0]
    o, d, length, t, st = np.empty((m, 3)), np.empty((m, 3)), np.empty(m), np.empty(m), np.empty(m, np.int64)
    for j in range(m):
        s = src[j]
        for a in range(3):
            o[j, a] = origins[s, a] + x0[j] * dirs[s, a]
            d[j, a] = dirs[s, a]
        length[j] = x1[j] - x0[j]
        t[j] = t0[s] + x0[j]
        st[j] = stream[s] + step * piece[j]
    return o, d, length, t, st


@njit
def _cone_pieces(xh, h, length, cone):
    """(source segment, x0, x1, piece number) of every lit piece: x = x_h + h (v - 1/v) / 2 at the
    cone's crossings v, the segment's own ends exactly."""
    n = xh.shape[0]
    src = np.empty(2 * n, np.int64)
    x0, x1, piece = np.empty(2 * n), np.empty(2 * n), np.empty(2 * n, np.int64)
    buf = np.empty((5, 3))
    m = 0
    for s in range(n):
        ell = length[s]
        if not has_cone(cone[s, 3]):
            src[m], x0[m], x1[m], piece[m] = s, 0.0, ell, 0
            m += 1
            continue
        va = v_of(-xh[s], h[s])
        vb = v_of(ell - xh[s], h[s]) if ell < math.inf else math.inf
        k = 0
        for i in range(segment_cone(cone[s, 0], cone[s, 1], cone[s, 2], cone[s, 2], va, vb, buf)):
            if buf[i, 2] == 0.0:
                continue
            a = 0.0 if buf[i, 0] == va else xh[s] + 0.5 * h[s] * (buf[i, 0] - 1.0 / buf[i, 0])
            b = ell if buf[i, 1] == vb else xh[s] + 0.5 * h[s] * (buf[i, 1] - 1.0 / buf[i, 1])
            a = min(max(a, 0.0), ell)
            b = min(max(b, a), ell)
            if b > a:
                src[m], x0[m], x1[m], piece[m] = s, a, b, k
                m += 1
                k += 1
    return src[:m], x0[:m], x1[:m], piece[:m]


def gather(segs: Segments, values: np.ndarray, n_rays: int, medium, power: int = 1, tr=None) -> np.ndarray:
    """Sum (N, 3) over each ray's segments of T^power * values (S, 3), T the transmittance from the
    camera ray's origin to the segment's start (exp(-kt t0) when homogeneous: the t0 before the
    segment's own origin); power 2 adds the variances of independent segment estimates. `tr`:
    `gather_weights(segs, medium, power)` where the caller gathers several values of one batch."""
    out = np.zeros((n_rays, 3))
    _add_by_ray(values, segs.ray, gather_weights(segs, medium, power) if tr is None else tr, out)
    return out


def gather_weights(segs: Segments, medium, power: int = 1) -> np.ndarray:
    """T^power (S, 3) of `gather`, empty for whole rays (all t0 = 0), which need no transmittance."""
    whole = segs.per_ray != 0 or not np.any(segs.t0)
    return _NO_WEIGHTS if whole else medium.transmittance_on(segs.origins, segs.dirs, -segs.t0, 0.0) ** power


_NO_WEIGHTS = np.ones((0, 3))  # `gather_weights` of whole rays (shared: nothing in it to change)


@njit
def _add_by_ray(values, ray, tr, out):
    """out[ray[s]] += values[s] (times tr[s] unless tr is empty; nothing where tr is 0, even if the
    segment's own value overflowed: a light on the camera in a medium of sigma ~ 1e300)."""
    for s in range(values.shape[0]):
        r = ray[s]
        for c in range(3):
            if not tr.shape[0]:
                out[r, c] += values[s, c]
            elif tr[s, c] != 0.0:
                out[r, c] += values[s, c] * tr[s, c]


def segment_airlight(method, medium, lights, params, segs: Segments, n_rays: int):
    """Air-light (N, 3) of the camera rays from their segments, the method's statistics, and the
    variance (N, 3) of each ray's estimate (None for a deterministic method)."""
    res = method.airlight(segs, medium, lights, params)
    var = gather(segs, res[2], n_rays, medium, power=2) if method.stochastic else None
    return gather(segs, res[0], n_rays, medium), res[1], var


def unshadowed_airlight(method, medium, lights, params, origins, dirs, tmax, keys, seed=0, scale=1.0):
    """`segment_airlight` of whole rays [0, tmax], one segment per light."""
    segs = whole_rays(origins, dirs, tmax, keys, len(lights), seed, scale)
    return segment_airlight(method, medium, lights, params, segs, len(origins))
