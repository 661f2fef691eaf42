"""The classic volumetric shadow test of the methods that expose their medium points (raymarch,
montecarlo with `shadow_test = "samples"`, and in the penumbrae of flat emitters): a shadow ray from every
point to its light (Monte Carlo's flat emitters: to the emitter's point drawn for it), in chunks of at most
POINTS_PER_CHUNK points.
"""
from __future__ import annotations

import functools

import numpy as np

from ..jit import njit
from ..methods import Segments
from ..segments import gather

POINTS_PER_CHUNK = 1 << 19  # medium points (x 3 channels) per batch of shadow rays: ~60 MB of arrays


@njit
def _chunk_ends(sizes, budget):
    ends = []
    start, biggest = 0, 0
    for i in range(sizes.shape[0]):
        biggest = max(biggest, sizes[i])
        if i > start and (i + 1 - start) * biggest > budget:
            ends.append(i)
            start, biggest = i, sizes[i]
    ends.append(sizes.shape[0])
    return ends


def chunks(sizes: np.ndarray, budget: int):
    """Consecutive slices of items whose count times their largest size stays within `budget`
    (a single item larger than the budget is a chunk of its own)."""
    start = 0
    for stop in (_chunk_ends(np.asarray(sizes, np.int64), int(budget)) if len(sizes) else []):
        yield slice(start, stop)
        start = stop


def _visible(accel, lights, segs, pos, weight, targets=None):
    """Shadow-ray visibility (same shape as weight) of the medium points pos toward their lights, or toward
    the points targets (S, n, 3) of each iteration where the method drew its lights' points (`points`)."""
    visible = np.zeros(weight.shape, dtype=bool)
    eps = accel.epsilon
    lp = lights.position[segs.light][:, None, None, :] if targets is None else targets[:, :, None, :]
    for c in range(3):
        p, w = pos[..., c, :], weight[..., c]
        if c > 0 and np.array_equal(p, pos[..., 0, :]):
            visible[..., c] = visible[..., 0]
            continue
        m = w != 0.0
        to_light = np.broadcast_to(lp, p.shape)[m] - p[m]
        dist = np.linalg.norm(to_light, axis=1)
        d = to_light / np.where(dist > 0.0, dist, 1.0)[:, None]
        vis = visible[..., c]
        vis[m] = ~accel.occluded(p[m] + eps * d, d, dist - 2.0 * eps)
        visible[..., c] = vis
    return visible


def shadowed_airlight(accel, method, medium, lights, params, segs: Segments, n_rays: int, visible=None):
    """Air-light (N, 3) with volumetric shadows from the method's medium points and the variance
    (N, 3) of each ray's estimate: the sum over its segments (independent random numbers) of the
    variance of each segment's mean over iterations (zero for one iteration or a deterministic
    method). `visible(segs, pos, weight[, targets])`: the factor (same shape as weight) of each point's light,
    by default its shadow ray's visibility; targets (S, n, 3), where the method's `points` returns them (Monte
    Carlo's flat emitters with shadow_test = samples: each iteration's drawn point of the emitter), are where
    each iteration's light is."""
    visible = visible or functools.partial(_visible, accel, lights)
    counts = method.point_count(segs, medium, params)
    air = np.zeros((n_rays, 3))
    var = np.zeros((n_rays, 3))
    for part in chunks(counts, POINTS_PER_CHUNK):
        seg = segs.take(part)
        pos, weight, *targets = method.points(seg, medium, lights, params)
        est = (weight * visible(seg, pos, weight, *targets)).sum(axis=2)  # (S, n, 3) per iteration
        air += gather(seg, est.mean(axis=1), n_rays, medium)
        n = est.shape[1]
        if method.stochastic and n > 1:
            with np.errstate(over="ignore"):  # estimates beyond ~1e154 (a light of 1e150 on the camera): inf
                var += gather(seg, est.var(axis=1, ddof=1) / n, n_rays, medium, power=2)
    return air, var
