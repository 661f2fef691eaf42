"""The air-light of area lights in penumbrae: stratified samples of the emitter where occluders cut it
(docs/area_lights.md, "Penumbrae").

With volumetric shadows each cubature row of an emitter (lights/area.py) is a point light whose lit
intervals along the camera ray are exact (frusta.py), but between the rows the rule sees nothing of
an occluder's edge: where a shadow cuts the emitter the rows' sum can miss the penumbra by far more
than the method's precision. A camera ray and an emitter are taken as cut where the rows disagree
(a row partly lit along the ray, or some rows lit and some dark) or, where they agree, where the
emitter's corner probes (`area.Emitter.probes`: a straight shadow edge that leaves every node on one
side leaves a corner on the other), each a point light with its exact intervals, disagree with them.

There the rows are replaced by 2 S stratified samples of the emitter's (u, v) square (S = k^2
strata, two jittered points in each, keyed by the camera ray's key, the seed, the emitter and k as
the surface term's are: shading.py, rng.py; k per cut pair from shading.LADDER, chosen by a pilot to
meet the method's tolerance as on surfaces: shading.stratified), each a LAMBERT spot row of
intensity L / (2 S p_A) at its point y (p_A the area density; a two-sided emitter's point twice,
facing both ways), cut to its front half-space and to the exact lit intervals of y itself
(frusta.point_lit_pieces), and integrated by the method, its closed form or rule, per lit interval.
The estimate is the sum over the samples, its variance the surface term's estimator's
(area.collapsed_variance: strata collapsed 2 x 2, conservative), with the same floor where all
samples agree (all lit or all dark, though the rows or probes saw a cut): one sample's share of the
unshadowed sum, squared. Sampled rays have no error bound (the renderer makes it infinite).

Monte Carlo draws a flat emitter's points itself (methods/montecarlo.py `drawn_segments`): in the pairs cut
so (`drawn`) its medium points' shadow rays go each to its own drawn point (`draws`, shadows/shadow_rays.py).
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import exact_njit
from ..lights import LAMBERT, SPOT, Lights
from ..lights.area import collapsed_variance
from ..lights.near_rules import rows_decide
from ..lights.planar import flat_rows
from ..methods import Segments
from ..segments import cone_segments, gather, pieces
from ..shading import _jitter as jitter, block, stratified
from .frusta import GAP_REL, point_lit_pieces

DIM_AIRLIGHT = 1 << 49  # the first random-number dimension (rng.py) of the air-light's emitter samples
LIT, DARK, MIXED, NONE = 1, -1, 0, 2  # what a row (or the rows of an emitter) sees along a camera ray


def applies(lights, method, shadows: bool) -> bool:
    """Whether a render samples penumbrae in the air-light: volumetric shadows by exact lit intervals
    (the renderer's branch that calls this), a deterministic method (analytic, quadrature, raymarch:
    montecarlo samples the rows its own way) and an emitter that can be sampled (`sampled_emitters`)."""
    return shadows and not method.stochastic and bool(sampled_emitters(lights).any())


def sampled_emitters(lights) -> np.ndarray:
    """(E,) whether each emitter's penumbrae are sampled: one that can be sampled (`Lights.emitters`) and
    that does not shadow its own samples (`Emitter.self_shadowing`: an emissive shape, whose rows are kept)."""
    return np.array([e is not None and not e.self_shadowing for e in lights.emitters], dtype=bool)


def sampled(ctx, method, medium, params, cone: Segments, lit: Segments, rays, select):
    """(the lit segments `lit` less those of the cut (ray, emitter) pairs, air-light (N, 3) of their
    samples, variance (N, 3), (N,) whether each camera ray was sampled). `cone`: the segments before
    the lit intervals; `rays` = (origins, dirs, tmax, keys, seed) of the N camera rays; `ctx`: the
    accelerator and the scene's lights (`accel`, `lights`); `select` the triangles that stop light."""
    accel, lights = ctx
    origins, dirs, tmax, keys, seed = rays
    n = len(origins)
    air, var = np.zeros((n, 3)), np.zeros((n, 3))
    cut = cut_pairs(accel, lights, cone, lit, rays, select)
    if not cut.any():
        return lit, air, var, np.zeros(n, bool)
    ray_e, owner_e = np.nonzero(cut)
    drop = cut[lit.ray, np.where(lights.cubature, lights.owner, 0)[lit.light]] & lights.cubature[lit.light]
    kept = lit.take(np.nonzero(~drop)[0]) if drop.any() else lit
    for e in np.unique(owner_e):
        rs = ray_e[owner_e == e]
        value, v = emitter_estimate(accel, method, medium, params, lights.emitters[e], e, rs, rays, select)
        air[rs] += value  # rs: each ray once (np.nonzero's)
        var[rs] += v
    return kept, air, var, cut.any(axis=1)


def draws(lights, method, shadows: bool) -> bool:
    """Whether a render shadow-tests flat emitters' penumbrae with the method's own drawn points (`drawn`):
    volumetric shadows by exact lit intervals, a stochastic method with medium points (montecarlo: its
    `points` draw each flat emitter's point per iteration with shadow_test = samples, in any medium) and a
    flat emitter (lights/planar.py `flat_rows`)."""
    return shadows and method.stochastic and method.points is not None and bool(flat_rows(lights).any())


def drawn(ctx, cone: Segments, lit: Segments, rays, select):
    """(the lit segments `lit` less the flat emitters' rows of the cut (ray, emitter) pairs, the segments of
    `cone` of those rows): the renderer hands the latter to the shadow rays of the method's own points
    (shadows/shadow_rays.py, shadow_test = samples), each medium point's ray to the emitter's point drawn with
    it, so that the estimate is unbiased where an occluder cuts the emitter, not the rows' rule; `ctx`, `rays`
    and `select` as `sampled`'s."""
    accel, lights = ctx
    rows = flat_rows(lights)
    cut = cut_pairs(accel, lights, cone, lit, rays, select, rows)
    if not cut.any():
        return lit, cone.take(np.zeros(0, np.int64))
    owner = np.where(rows, lights.owner, 0)
    on = lambda segs: cut[segs.ray, owner[segs.light]] & rows[segs.light]
    return lit.take(np.nonzero(~on(lit))[0]), cone.take(np.nonzero(on(cone))[0])


def emitter_estimate(accel, method, medium, params, emitter, e, rs, rays, select, sample=None):
    """(estimate, variance), each (len(rs), 3), of emitter `e` along the camera rays `rs`: stratified
    samples whose strata follow the method's tolerance (`Method.tolerance`; shading.stratified: a
    pilot per ray, then fresh samples), shading.STRATA a side without one. `sample(rays, u, v)`: as
    `emitter.sample` of (u, v) (len(rays), K), ray by ray (None: `emitter.sample`)."""

    def estimate(at, strata, stage):
        return _stratified(accel, method, medium, params, emitter, rs[at], rays, select, strata,
                           block(DIM_AIRLIGHT, e, stage), sample)

    return stratified(estimate, len(rs), method.tolerance(params))


def _stratified(accel, method, medium, params, emitter, rs, rays, select, strata: int, dim: int, sample=None):
    """(estimate, variance), each (len(rs), 3): 2 strata^2 stratified samples of the emitter (or of
    `sample`'s part of it: `emitter_estimate`) along each camera ray rs (module docstring), at
    random-number dimensions from `dim`."""
    origins, dirs, tmax, keys, seed = rays
    per = 2 * strata * strata
    u, v = np.empty((len(rs), per)), np.empty((len(rs), per))
    jitter(keys[rs], seed, dim, strata, u, v)
    y, normals, density = emitter.sample(u.ravel(), v.ravel()) if sample is None else sample(rs, u, v)
    samples = spot_rows(y, normals, emitter.radiance[None, :] / (per * density[:, None]), emitter.two_sided)
    sides = 2 if emitter.two_sided else 1
    segs = point_segments(samples, sides, rays, np.repeat(rs, per), accel.scale)
    lit = lit_pieces(accel, samples, segs, sides * per, select)
    m = len(rs) * per
    states = _group_states(segs, lit, m).reshape(len(rs), per)
    agree = np.all(states != MIXED, axis=1) & (np.all(states != DARK, axis=1) | np.all(states != LIT, axis=1))
    free = segs.take(np.nonzero(np.repeat(agree, per)[segs.ray])[0])  # the floor's: the agreeing rays' unshadowed
    both = per_group(method, medium, params, samples, _joined(lit, free, m), 2 * m)  # one batch: the lit, then free
    g = per * both[:m]  # one sample's estimate
    value = g.reshape(len(rs), per, 3).mean(axis=1)
    var = collapsed_variance(g.reshape(len(rs), per, 3), strata)
    if agree.any():  # the floor: one sample's share of the unshadowed sum
        floor = both[m:].reshape(len(rs), per, 3).sum(axis=1)[agree] ** 2 / per**2
        var[agree] = np.maximum(var[agree], floor)
    return value, var


def _joined(a: Segments, b: Segments, offset: int) -> Segments:
    """The segments of `a` then those of `b`, b's groups (`ray`) moved by `offset` (a's and b's kept apart)."""
    cat = lambda x, y: np.concatenate((x, y))
    return Segments(cat(a.origins, b.origins), cat(a.dirs, b.dirs), cat(a.length, b.length), cat(a.light, b.light),
                    cat(a.ray, b.ray + offset), cat(a.t0, b.t0), cat(a.keys, b.keys), cat(a.stream, b.stream),
                    a.seed, a.scale)


def per_group(method, medium, params, lights, segs: Segments, groups: int) -> np.ndarray:
    """(groups, 3) the air-light of the segments per group (segs.ray), by the method, with the
    medium's transmittance from the camera to each segment's start."""
    if not len(segs):
        return np.zeros((groups, 3))
    return gather(segs, method.airlight(segs, medium, lights, params)[0], groups, medium)


def cut_pairs(accel, lights, cone: Segments, lit: Segments, rays, select, rows=None) -> np.ndarray:
    """(N, E) whether the camera ray's segments of emitter e are cut (module docstring): its rows'
    states (`_group_states` per row, LIT, DARK or MIXED) are mixed, or agree but the probes' differ, or
    are all DARK for a sphere (no order of its rows proves it hidden: rendering/near_emitters.py). `rows`
    (L,): the rows of the emitters asked about (None: `emitter_rows`)."""
    n, n_e = len(rays[0]), len(lights.emitters)
    rows = emitter_rows(lights) if rows is None else rows
    on = np.nonzero(rows[cone.light])[0]
    if not len(on):
        return np.zeros((n, n_e), bool)
    n_l = len(lights)
    mine = (cone, lit) if rows.all() else (cone.take(on), lit.take(np.nonzero(rows[lit.light])[0]))
    row_state = lit_states(*mine, *(s.ray * n_l + s.light for s in mine), n * n_l)
    state = emitter_states(row_state.reshape(n, n_l), lights.owner, rows, n_e)  # (N, E)
    agreed = np.nonzero((state == LIT) | (state == DARK))
    cut = state == MIXED
    for e in np.unique(agreed[1]):
        emitter = lights.emitters[e]
        if not rows_decide(emitter):  # a sphere's rows all dark prove nothing: a sliver between them may shine
            cut[agreed[0][agreed[1] == e], e] = state[agreed[0][agreed[1] == e], e] == DARK
        if emitter.probes is None:
            continue
        rs = agreed[0][agreed[1] == e]
        probes = spot_rows(*emitter.probes, np.ones((len(emitter.probes[0]), 3)), emitter.two_sided)
        per = len(probes)
        tiled = Lights(*(np.tile(a, (len(rs),) + (1,) * (a.ndim - 1)) for a in
                         (probes.kind, probes.position, probes.intensity, probes.axis, probes.cone, probes.owner,
                          probes.cubature)))
        segs = point_segments(tiled, per, rays, rs, accel.scale, whole=True)
        lit_p = lit_pieces(accel, tiled, segs, per, select)
        p_state = lit_states(segs, lit_p, segs.light, lit_p.light, len(tiled)).reshape(len(rs), per)
        probe = emitter_states(p_state, np.zeros(per, np.int64), np.ones(per, bool), 1)[:, 0]
        cut[rs, e] = (probe != NONE) & (probe != state[rs, e])
    return cut


def emitter_rows(lights) -> np.ndarray:
    """(L,) whether each row is a node of an emitter whose penumbrae are sampled (`sampled_emitters`)."""
    sampled_ = np.append(sampled_emitters(lights), False)
    return sampled_[np.where(lights.cubature, lights.owner, len(lights.emitters))]


def lit_states(cone: Segments, lit: Segments, cone_key, lit_key, size: int) -> np.ndarray:
    """(size,) per key (`cone_key`, `lit_key`: of each segment and lit piece) LIT where its lit pieces
    cover its cone segments, DARK where there are none, MIXED between, NONE where it has no cone
    segment (the row does not shine on the ray). A key's segments and pieces to infinity are measured
    to its own far end, beyond their last start (so a key's state does not depend on the others')."""
    return _lit_states(cone.t0, cone.length, np.asarray(cone_key, np.int64), lit.t0, lit.length,
                       np.asarray(lit_key, np.int64), float(cone.scale), size)


@exact_njit
def _lit_states(c_t0, c_len, c_key, l_t0, l_len, l_key, scale, size):
    """`lit_states`' kernel: the far ends (the largest start per key, plus the scene's scale), then the
    cone segments' count and measure and the lit pieces' measure per key, each summed in the order of
    the segments (as np.bincount sums), and the tolerance 2 GAP_REL far count. The largest start as
    np.maximum takes it (a NaN wins); plain loops and comparisons, which compile in half the time of
    np.isinf and max()."""
    far, sums = np.zeros(size), np.zeros((3, size))  # sums: count, total, covered
    for i in range(c_key.shape[0]):
        k = c_key[i]
        if not far[k] >= c_t0[i] and far[k] == far[k]:
            far[k] = c_t0[i]
    for i in range(l_key.shape[0]):
        k = l_key[i]
        if not far[k] >= l_t0[i] and far[k] == far[k]:
            far[k] = l_t0[i]
    for i in range(c_key.shape[0]):
        k, x = c_key[i], c_len[i]
        sums[0, k] += 1.0
        sums[1, k] += (far[k] + scale) - c_t0[i] if x == math.inf or x == -math.inf else x
    for i in range(l_key.shape[0]):
        k, x = l_key[i], l_len[i]
        sums[2, k] += (far[k] + scale) - l_t0[i] if x == math.inf or x == -math.inf else x
    out = np.empty(size, np.int64)
    for k in range(size):
        tol = 2.0 * GAP_REL * (far[k] + scale) * sums[0, k]
        if sums[0, k] == 0.0:
            out[k] = NONE
        elif sums[2, k] >= sums[1, k] - tol:
            out[k] = LIT
        elif sums[2, k] <= tol:
            out[k] = DARK
        else:
            out[k] = MIXED
    return out


def emitter_states(state, owner, rows, n_e) -> np.ndarray:
    """(N, E) from per-row states (N, L): LIT or DARK where all the emitter's rows that shine on the
    ray say so, NONE where none does, else MIXED."""
    out = np.full((state.shape[0], n_e), NONE)
    for e in range(n_e):
        mine = state[:, rows & (owner == e)]
        says = mine != NONE
        lit_all = np.all((mine == LIT) | ~says, axis=1)
        dark_all = np.all((mine == DARK) | ~says, axis=1)
        out[:, e] = np.where(~says.any(axis=1), NONE, np.where(lit_all, LIT, np.where(dark_all, DARK, MIXED)))
    return out


def _group_states(cone: Segments, lit: Segments, groups: int) -> np.ndarray:
    """(groups,) LIT, DARK, MIXED or NONE of each group's segments (segs.ray: one sample's)."""
    return lit_states(cone, lit, cone.ray, lit.ray, groups)


def spot_rows(points, normals, weight, two_sided: bool) -> Lights:
    """LAMBERT spot rows at `points` (n, 3) facing `normals` of intensity `weight` (n, 3): rows 2 i and
    2 i + 1 facing both ways where two-sided, else row i."""
    if two_sided:
        points, weight = np.repeat(points, 2, axis=0), np.repeat(weight, 2, axis=0)
        normals = np.repeat(normals, 2, axis=0) * np.tile([[1.0], [-1.0]], (len(normals), 1))
    n = len(points)
    return Lights(np.full(n, SPOT, np.int64), np.ascontiguousarray(points, float), np.ascontiguousarray(weight, float),
                  np.ascontiguousarray(normals, float), np.tile([0.0, 1.0, float(LAMBERT)], (n, 1)),
                  np.zeros(n, np.int64), np.ones(n, bool))


def point_segments(lights: Lights, per: int, rays, ray_of, scale, whole: bool = False) -> Segments:
    """Per group g of `per` rows (rows g per ... g per + per - 1) one segment [0, tmax] of the camera
    ray ray_of[g] per row, its `ray` the group (`whole`: the row), cut to the rows' front half-spaces."""
    origins, dirs, tmax, keys, seed = rays
    light = np.arange(len(lights), dtype=np.int64)
    r = ray_of[light // per]
    segs = Segments(origins[r], dirs[r], np.asarray(tmax, float)[r], light, light if whole else light // per,
                    np.zeros(len(light)), keys[r], light, int(seed), float(scale))
    return cone_segments(segs, lights)[0]


def lit_pieces(accel, lights: Lights, segs: Segments, per_box: int, select) -> Segments:
    """The exact lit pieces of `segs` each under its own row (frusta.point_lit_pieces) as segments
    from their own start points, the candidate triangles per box of `per_box` rows (one camera ray's)."""
    box = light_boxes(lights.position, segs, per_box)
    src, x0, x1 = point_lit_pieces(accel, segs, lights.position[segs.light], segs.light // per_box, box, select)
    return pieces(segs, src, x0, x1)


def light_boxes(points, segs: Segments, per_box: int):
    """((B, 3) lows, (B, 3) highs): per box b the bounding box of rows b per_box ... (their points and
    segments; infinite where a segment does not end)."""
    pts = points.reshape(-1, per_box, 3)
    lo, hi = pts.min(axis=1), pts.max(axis=1)
    _grow_boxes(lo, hi, segs.origins, segs.dirs, segs.length, segs.light, per_box)
    return lo, hi


@exact_njit
def _grow_boxes(lo, hi, origins, dirs, length, light, per_box):
    """`light_boxes`' kernel: each box grown to its segments' start and end points, as np.minimum and
    np.maximum would (exact, so the order of the segments does not matter; a NaN wins); a segment to
    infinity reaches +-inf along each axis its direction has a component on."""
    for s in range(light.shape[0]):
        b = light[s] // per_box
        finite = length[s] - length[s] == 0.0  # neither inf nor NaN
        for a in range(3):
            o = origins[s, a]
            if finite:
                e = o + length[s] * dirs[s, a]
            elif dirs[s, a] > 0.0:
                e = math.inf
            elif dirs[s, a] < 0.0:
                e = -math.inf
            else:
                e = o + 0.0 * dirs[s, a]
            for x in (o, e):
                if not lo[b, a] <= x and lo[b, a] == lo[b, a]:
                    lo[b, a] = x
                if not hi[b, a] >= x and hi[b, a] == hi[b, a]:
                    hi[b, a] = x
