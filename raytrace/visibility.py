"""From camera rays to segments, and light visibility inside the medium (ARCHITECTURE.md).

`whole_rays` makes the unshadowed segments: one [0, t_hit] per (ray, light). `gather` adds
segment air-lights to their camera rays with the transmittance exp(-kt t0) in front of each segment.
`shadowed_airlight` is the sampled volumetric shadowing of the methods that expose their medium
points (raymarch, montecarlo): a shadow ray from every point to its light, in chunks of bounded
memory.
"""
from __future__ import annotations

import numpy as np

from .methods import Segments

POINTS_PER_CHUNK = 1 << 19  # medium points (x 3 channels) per batch of shadow rays: ~60 MB of arrays


def whole_rays(origins, dirs, tmax, keys, n_lights, seed=0, scale=1.0) -> Segments:
    """One segment [0, tmax] per (ray, light), ray-major (segment r L + l)."""
    n = len(origins)
    rep = lambda a: np.repeat(a, n_lights, axis=0)  # noqa: E731
    light = np.tile(np.arange(n_lights, dtype=np.int64), n)
    return Segments(rep(origins), rep(dirs), rep(np.asarray(tmax, float)), light,
                    rep(np.arange(n, dtype=np.int64)), np.zeros(n * n_lights), rep(np.asarray(keys, np.uint64)),
                    light.copy(), int(seed), float(scale))


def gather(segs: Segments, values: np.ndarray, n_rays: int, medium, power: int = 1) -> np.ndarray:
    """Sum (N, 3) over each ray's segments of exp(-kt t0)^power * values (S, 3); power 2 adds the
    variances of independent segment estimates."""
    out = np.zeros((n_rays, 3))
    np.add.at(out, segs.ray, values * medium.transmittance(segs.t0) ** power)
    return out


def unshadowed_airlight(method, medium, lights, params, origins, dirs, tmax, keys, seed=0, scale=1.0):
    """Air-light (N, 3) of whole rays [0, tmax] summed over lights, the method's statistics, and the
    variance (N, 3) of each ray's estimate (None for a deterministic method)."""
    segs = whole_rays(origins, dirs, tmax, keys, len(lights), seed, scale)
    res = method.airlight(segs, medium, lights, params)
    var = gather(segs, res[2], len(origins), medium, power=2) if method.stochastic else None
    return gather(segs, res[0], len(origins), medium), res[1], var


def chunks(sizes: np.ndarray, budget: int):
    """Consecutive slices of items whose count times their largest size stays within `budget`
    (a single item larger than the budget is a chunk of its own)."""
    start, n = 0, len(sizes)
    while start < n:
        stop, biggest = start + 1, int(sizes[start])
        while stop < n and (stop + 1 - start) * max(biggest, int(sizes[stop])) <= budget:
            biggest = max(biggest, int(sizes[stop]))
            stop += 1
        yield slice(start, stop)
        start = stop


def _visible(accel, lights, segs, pos, weight):
    """Shadow-ray visibility (same shape as weight) of the medium points pos toward their lights."""
    visible = np.zeros(weight.shape, dtype=bool)
    eps = accel.epsilon
    lp = lights.position[segs.light]
    for c in range(3):
        p, w = pos[..., c, :], weight[..., c]
        if c > 0 and np.array_equal(p, pos[..., 0, :]):
            visible[..., c] = visible[..., 0]
            continue
        m = w != 0.0
        to_light = np.broadcast_to(lp[:, None, None, :], p.shape)[m] - p[m]
        dist = np.linalg.norm(to_light, axis=1)
        d = to_light / np.where(dist > 0.0, dist, 1.0)[:, None]
        vis = visible[..., c]
        vis[m] = ~accel.occluded(p[m] + eps * d, d, dist - 2.0 * eps)
        visible[..., c] = vis
    return visible


def shadowed_airlight(accel, method, medium, lights, params, segs: Segments, n_rays: int):
    """Air-light (N, 3) with volumetric shadows from the method's medium points and the variance
    (N, 3) of each ray's estimate: the sum over its segments (independent random numbers) of the
    variance of each segment's mean over iterations (zero for one iteration or a deterministic
    method)."""
    counts = method.point_count(segs, medium, params)
    air = np.zeros((n_rays, 3))
    var = np.zeros((n_rays, 3))
    for part in chunks(counts, POINTS_PER_CHUNK):
        seg = segs.take(part)
        pos, weight = method.points(seg, medium, lights, params)
        est = (weight * _visible(accel, lights, seg, pos, weight)).sum(axis=2)  # (S, n, 3) per iteration
        air += gather(seg, est.mean(axis=1), n_rays, medium)
        n = est.shape[1]
        if method.stochastic and n > 1:
            var += gather(seg, est.var(axis=1, ddof=1) / n, n_rays, medium, power=2)
    return air, var
