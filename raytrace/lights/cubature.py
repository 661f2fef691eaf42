"""Each emitter's cubature order, chosen per render by a pilot (docs/area_lights.md, "The order").

An area light's or emissive shape's rows are the nodes of a rule over its emitter (area.py), fixed for
the whole render. The pilot shades a sample of the render's camera rays with the render's own method
at two orders of one emitter, n and the next with at least 4 x the rows (about 2n per dimension;
an emissive shape's triangles split in 4), the other emitters at their coarsest rule, and grows n
until the two agree to SHARE x the method's precision (`precision`, `rtol`) on every pilot ray and
channel, relative to the ray's radiance; it keeps the coarser order of the agreeing pair. An emitter
whose pair still disagrees at MAX_ROWS rows is capped: it keeps its finest rule, and the render's
statistics count it and the pilot rays that disagree.

The pilot rays are the pixel centres of a GRID x GRID grid over the image and, per emitter, the NEAR
pixel rays (of a CANDIDATES x CANDIDATES sample of the image's, every pixel of a smaller image, each
once) that pass closest to its points: where a ray passes near or ends on an emitter each node's
air-light behaves like w_i / rho_i about the ray's foot point, the slowest place for the rule to converge.
Rays that pass within `near_fraction` of the emitter's diameter do not choose: a flat emitter's (within
PASSING) take rules of their own in the render (rendering/near_emitters.py), so its NEAR pixels are the
nearest of those beyond it, the rays that choose its order.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from ..jit import exact_njit

GRID = 6  # the pilot's pixel grid
NEAR = 8  # the pilot's rays nearest to each emitter
CANDIDATES = 96  # the near rays are chosen among the pixel centres of a CANDIDATES x CANDIDATES grid
PROBES = 17  # ... by their distance to PROBES x PROBES points of the emitter, its outline included
SHARE = 0.25  # the share of the method's precision the two orders must agree to
MAX_ROWS = 1024  # an emitter's rows at most (each row costs what a spot light costs)
NEAR_FRACTION = 1 / 8  # a pilot ray this close to an emitter (of its diameter) is in its 1/r region
PASSING = 1 / 4  # a camera ray this close to a flat emitter takes its own ladder of the emitter's rule (near_emitters)
FLOOR = 1e-13  # agreement relative to the largest pilot radiance (`agree`) below which rays are not told apart
AREA_LADDER = (2, 3, 4, 6, 8, 12, 16, 24, 32)  # orders of the area lights' rules (32 x 32: MAX_ROWS)
LEVELS = 6  # an emissive shape's subdivision levels at most (each triangle split in 4^level)


def ladder(steps, count) -> tuple:
    """The orders of `steps` (AREA_LADDER, or range(LEVELS) for an emissive shape) whose rows,
    `count(order)`, are at most MAX_ROWS; the coarsest is kept even if above (a shape of many triangles)."""
    return tuple(o for o in steps if count(o) <= MAX_ROWS) or (steps[0],)


def pairs(orders, count) -> list:
    """(coarse, fine) pairs of the ladder: each order with the first of at least 4 x its rows."""
    rows = [count(o) for o in orders]  # once each: a count builds the rule
    out = []
    for i, o in enumerate(orders):
        finer = [f for f, r in zip(orders[i + 1:], rows[i + 1:]) if r >= 4 * rows[i]]
        if finer:
            out.append((o, finer[0]))
    return out


def grid(n: int, width: int, height: int) -> np.ndarray:
    """(n^2, 2) pixels (row, column) of an n x n grid spread over the image (repeats where it is smaller)."""
    ys, xs = np.meshgrid((np.arange(n) + 0.5) * height // n, (np.arange(n) + 0.5) * width // n, indexing="ij")
    return np.stack([ys.ravel(), xs.ravel()], axis=1).astype(np.int64)


def near_fraction(emitter) -> float:
    """The share of an emitter's diameter within which a pilot ray is near it and does not choose its
    order: PASSING for a flat emitter (`Emitter.planar`; near_emitters integrates such rays per ray),
    NEAR_FRACTION for the others."""
    return PASSING if emitter.planar is not None else NEAR_FRACTION


def pilot_pixels(emitters, ladders, rays_of, width: int, height: int):
    """(pixels (N, 2), near): the pilot's pixels (row, column), the GRID grid's and the NEAR pixels of
    the CANDIDATES grid (each pixel once: all of an image smaller than it) nearest to each emitter
    beyond its `near_fraction` of its diameter (all of them for the emitters whose fraction is
    NEAR_FRACTION), and per source (None where `ladders[s]` is None) whether each of their rays passes
    within that fraction of the emitter. `emitters[s]`: its area.Emitter; `rays_of(pixels)`: their rays
    (origins, unit directions). Only the candidates that may be among the NEAR nearest are measured
    (`nearest`), and a pilot pixel among those takes its candidate ray's distance (the same number:
    each ray's is its own)."""
    sources = [s for s, l in enumerate(ladders) if l is not None]
    cand = unique_pixels(grid(CANDIDATES, width, height), width)  # an image smaller than the grid: each pixel once
    o, d = rays_of(cand)
    picks = [grid(GRID, width, height)]
    measured = {}
    for s in sources:
        beyond = PASSING if emitters[s].planar is not None else 0.0  # its near rays are not the nearest that choose
        measured[s] = nearest(emitters[s].sample, o, d, NEAR, beyond)
        dist = measured[s][0]
        order = np.argsort(np.where(dist >= beyond * measured[s][1], dist, np.inf), kind="stable")[:NEAR]
        picks.append(cand[order[dist[order] >= beyond * measured[s][1]]])
    pixels = unique_pixels(np.concatenate(picks), width)
    key, cand_key = pixels @ [width, 1], cand @ [width, 1]  # both sorted
    at = np.minimum(np.searchsorted(cand_key, key), len(cand) - 1)
    near = [None] * len(ladders)
    for s in sources:
        dist = np.where(cand_key[at] == key, measured[s][0][at], np.nan)
        afresh = np.isnan(dist)  # off the candidates (an image larger than them) or not measured there
        if afresh.any():
            dist[afresh] = half_line_distances(probe_points(emitters[s].sample), *rays_of(pixels[afresh]))
        near[s] = dist < near_fraction(emitters[s]) * measured[s][1]
    return pixels, near


def unique_pixels(pixels, width: int) -> np.ndarray:
    """The pixels (row, column) each once, in raster order."""
    key = np.unique(pixels[:, 0] * width + pixels[:, 1])
    return np.stack([key // width, key % width], axis=1)


def probe_points(samples) -> np.ndarray:
    """(PROBES^2, 3) an emitter's `samples(u, v)` on a PROBES x PROBES grid of [0, 1]^2 (its outline included)."""
    g = np.linspace(0.0, 1.0 - 1e-12, PROBES)
    u, v = np.meshgrid(g, g, indexing="ij")
    return samples(u.ravel(), v.ravel())[0]


def nearest(samples, origins, dirs, k: int, beyond: float = 0.0) -> tuple[np.ndarray, float]:
    """(`distances` of the half-lines that may be among the k nearest to the emitter's probe points of
    those at least `beyond` x its diameter from them, NaN for the others; the diameter). Each distance
    lies within the radius r of the points' bounding sphere of the half-line's distance c to the
    sphere's centre: one whose c + r is below that floor is not among them, nor one whose c - r is
    beyond the k-th smallest c + r of those surely at or beyond the floor (c - r at or above it)."""
    points, size, radius, to_centre = _about(samples, origins, dirs)
    out = np.full(len(origins), np.nan)
    floor = beyond * size
    margin = 1e-9 * (floor + radius)  # for rounding
    maybe = np.flatnonzero(to_centre + radius >= floor - margin) if floor > 0.0 else np.arange(len(origins))
    sure = to_centre[maybe] - radius >= floor + margin if floor > 0.0 else np.ones(len(maybe), bool)
    if np.count_nonzero(sure) > k:
        kth = np.partition(to_centre[maybe][sure], k - 1)[k - 1] + radius
        maybe = maybe[to_centre[maybe] - radius <= kth + 1e-9 * (kth + radius)]
    out[maybe] = half_line_distances(points, origins[maybe], dirs[maybe])
    return out, size


def passes(samples, origins, dirs, fraction: float) -> np.ndarray:
    """(N,) whether each half-line passes within `fraction` of an emitter's diameter of its probe points
    (the pilot's measure, `near_fraction`); only those whose distance to the points' bounding sphere
    allows it are measured."""
    points, size, radius, to_centre = _about(samples, origins, dirs)
    limit = fraction * size
    maybe = np.flatnonzero(to_centre - radius < limit * (1.0 + 1e-9) + 1e-9 * radius)
    out = np.zeros(len(origins), bool)
    out[maybe] = half_line_distances(points, origins[maybe], dirs[maybe]) < limit
    return out


def _about(samples, origins, dirs):
    """(probe points (P, 3), their `diameter`, the radius of their bounding sphere about their mean, (N,)
    each half-line's distance to that centre)."""
    points, size, radius, centre = _probe_geometry(samples)
    return points, size, radius, half_line_distances(centre[None], origins, dirs)


@functools.lru_cache(maxsize=64)
def _probe_geometry(samples):
    """(probe points (P, 3), their `diameter`, their bounding sphere's radius and centre (their mean)) of
    an emitter's `samples` (`Emitter.sample`): once per emitter, not per tile of camera rays."""
    points = probe_points(samples)
    centre = points.mean(axis=0)
    return points, diameter(points), np.linalg.norm(points - centre, axis=1).max(), centre


def half_line_distances(points, origins, dirs) -> np.ndarray:
    """(N,) the distance from each half-line o + t d (t >= 0) to the nearest of `points` (P, 3): per
    point and half-line |rel - max(rel . d, 0) d|, rel = p - o (`_half_line_distances`)."""
    best = np.full(len(origins), np.inf)
    _half_line_distances(np.ascontiguousarray(points, float), np.ascontiguousarray(origins, float),
                         np.ascontiguousarray(dirs, float), best)
    return best


@exact_njit
def _half_line_distances(points, origins, dirs, best):
    """`half_line_distances`' kernel, each number rounded as NumPy's expressions round it (tested):
    rel . d as np.einsum sums its three products, (rel_y d_y) + ((rel_x d_x) + (rel_z d_z)); the
    norm as np.linalg.norm, sqrt((x^2 + y^2) + z^2); the least as np.minimum takes it (a NaN wins)."""
    for i in range(origins.shape[0]):
        dx, dy, dz = dirs[i, 0], dirs[i, 1], dirs[i, 2]
        for p in range(points.shape[0]):
            rx, ry, rz = points[p, 0] - origins[i, 0], points[p, 1] - origins[i, 1], points[p, 2] - origins[i, 2]
            t = ry * dy + (rx * dx + rz * dz)
            if not t >= 0.0 and t == t:  # np.maximum(t, 0.0): a NaN stays
                t = 0.0
            ex, ey, ez = rx - t * dx, ry - t * dy, rz - t * dz
            dist = math.sqrt((ex * ex + ey * ey) + ez * ez)
            if not best[i] <= dist and best[i] == best[i]:
                best[i] = dist


def diameter(points) -> float:
    """The largest distance from a few of `points` (every PROBES + 1-th) to the others."""
    return max(np.linalg.norm(points - p, axis=1).max() for p in points[:: PROBES + 1])


def agree(coarse, fine, tol, seen=0.0) -> np.ndarray:
    """(N,) whether two pilot radiances (N, 3) agree to tol relative to each ray's radiance (or `seen`
    (N, 3) where larger: radiance the two leave out)."""
    scale = np.maximum(np.maximum(np.abs(fine), seen), FLOOR * np.abs(fine).max(initial=0.0))
    return np.all(np.abs(coarse - fine) <= tol * scale, axis=1)


def choose(ladders, counts, near, shade, tol):
    """(the order of each source, emitters capped, near rays, rays whose last pair disagrees). Per source
    (scene lights, then emissive shapes): `ladders[s]` its orders (`ladder`; None: not a cubature of
    an emitter), `counts[s](order)` its rows, `near[s]` (N,) whether each pilot ray passes within
    NEAR_FRACTION of the emitter's diameter of it; `shade(orders, rays)` the radiance (len(rays), 3)
    of the pilot rays `rays` (indices) with each source at its order (None where not a cubature); `tol`
    the method's precision. The other rays choose the order (all of them where all are near), their
    agreement floor relative to the largest of their own radiances; the near rays, which do not
    choose, are shaded with them at each order (one pass an order: each ray's radiance is its own),
    and at the chosen pair (the finest, where capped) the rays that disagree are counted as not
    converged (all pilot rays, the floor of their largest radiance), summed over the sources."""
    base = tuple(None if l is None else l[0] for l in ladders)
    chosen, capped, n_near, stray = list(base), 0, 0, 0
    for s, orders in enumerate(ladders):
        if orders is None:
            continue
        every = np.arange(len(near[s]))
        decide = every[~near[s]] if not near[s].all() else every  # all near: they decide
        at = functools.lru_cache(maxsize=None)(lambda order, s=s: shade(base[:s] + (order,) + base[s + 1:], every))
        last = None
        for last in pairs(orders, counts[s]):
            if agree(at(last[0])[decide], at(last[1])[decide], SHARE * tol).all():
                chosen[s] = last[0]
                break
        else:
            chosen[s] = orders[-1]
            capped += 1
        n_near += int(np.count_nonzero(near[s]))
        if last is not None:
            stray += int(np.count_nonzero(~agree(at(last[0]), at(last[1]), SHARE * tol)))
    return tuple(chosen), capped, n_near, stray
