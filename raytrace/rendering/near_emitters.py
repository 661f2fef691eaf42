"""The air-light of flat emitters along camera rays that pass near them or end on them (docs/area_lights.md,
"Rays near an emitter").

An emitter's rows (lights/area.py) are one rule for the whole render. Along a camera ray each node's
air-light behaves like w_i / rho_i, rho_i the node's distance to the ray, so where the ray crosses the
emitter's plane on or near the emitter (within cubature.NEAR_FRACTION of its diameter, or ends on it)
the rows meet a 1 / rho singularity they integrate poorly: up to a few per cent off, and an emitter seen
face-on shows faint bright dots at its nodes. For such a (camera ray, emitter) pair the emitter's rows
are replaced by a rule of the pair's own about the ray's foot point on the plane (`planar.Planar.rule`,
whose Jacobian cancels the 1 / rho), its nodes LAMBERT spot rows integrated by the method itself, at
the orders ORDERS in turn until two agree to SHARE x the method's precision (then the finer is kept;
where none agree the finest, counted). Methods without a precision take DEFAULT_ORDER.

With volumetric shadows the rule replaces the rows only where all of the emitter's rows are lit along
the whole ray (`penumbra_airlight`'s states); where occluders shadow them the rows (or the penumbra's
samples) stay. A sphere's rows lit along the whole ray are no proof that nothing hides part of it:
there the rule applies only where the occluders' geometry clears the segment
(`sphere_occluders.segments_free`, the same for every cubature order); elsewhere the penumbra's
stratified samples replace the rows (`penumbra_airlight`'s estimate). Nor are a sphere's rows all dark
along the whole ray a proof that all of it is hidden (a cap above a floor, between the rows, lights the
ray): `penumbra_airlight.cut_pairs` samples those pairs, so no order of the rows decides that a segment
is lit or dark. Nor that the sphere does not shine on it: a segment near the sphere may see a cap of it
on which no row lies, so the sphere shines on every ray from outside it (`_shines`) and the pairs that
no row faces take the rule where the geometry clears them, else the samples, drawn from a cap of the
sphere that holds all the segment sees (`sphere_rule.Ball.seen_cap`). A stochastic method keeps a flat
emitter's rows (it samples them); a sphere's pairs take its own estimate where it has one
(`Method.sphere`), without shadow rays where the geometry clears the segment, else with them (`_in_sight`).

A sphere emitter's rows meet a kink along the horizon of each of a segment's points, where it crosses
the rows' rule (an error of about n^-2 that the pilot's rows cannot reach 1e-6 with), so for every
camera ray the sphere shines on from outside it, not only near ones, its rows are replaced the same
way by a rule about the segment (`sphere_rule.Ball.rule`: the pencil of the segment's horizons, split
at its ends), its ladder from sphere_rule.FIRST, counted among the rays near an emitter.
"""
from __future__ import annotations

import functools

import numpy as np

from ..lights.cubature import SHARE, agree
from ..lights.near_rules import (ORDERS, cap_samplers, near as near_of, own_estimate, passing as passing_of,
                                 passing_rule, replaces_rows, rows_decide, segments_clear)
from ..shadows.penumbra_airlight import (LIT, NONE, emitter_estimate, emitter_states, lit_states, per_group,
                                         point_segments, spot_rows)

DEFAULT_ORDER = 8  # raymarch's (no precision to meet)
STATS_NAMES = ("rays near an emitter", "rays near an emitter not converged")


def applies(lights, method, sampled: bool = False) -> bool:
    """Whether a render has sphere emitters, or flat emitters whose near rays a deterministic method
    integrates so; with a shadow ray per medium sample (`sampled`: the method's points, not its lit
    intervals), sphere emitters of a method with its own estimate of them (`Method.sphere`), which
    `replaced` then samples with their own shadow rays (the rows' stay with the points)."""
    if sampled:
        return any(e is not None and own_estimate(e, method.sphere) is not None for e in lights.emitters)
    return any(e is not None and replaces_rows(e, method.stochastic) for e in lights.emitters)


def replaced(lights, method, medium, params, tol, cone, segs, rays, shadows: bool, seen, ctx=None):
    """(`segs` less the rows of the near (camera ray, emitter) pairs, their air-light (N, 3), statistics
    (STATS_NAMES), (N,) whether each camera ray has such a pair: no error bound there, the variance
    (N, 3) of the sphere pairs sampled instead). `cone`: the segments before the lit intervals (`segs`
    itself without shadows); `rays` = (origins, dirs, tmax, keys, seed) of the N camera rays; `tol` the
    method's precision (None: DEFAULT_ORDER), relative to the larger of the pair's air-light and `seen`
    (N, 3), the radiance the ray brings from where it ends (an emitter's own, seen through the medium);
    `ctx` = (accelerator, the triangles that stop light) with shadows."""
    origins, dirs, tmax = rays[:3]
    n, n_e = len(origins), len(lights.emitters)
    air, stats, var = np.zeros((n, 3)), np.zeros(len(STATS_NAMES)), np.zeros((n, 3))
    near = np.zeros((n, n_e), bool)
    rules = [None if em is None else near_of(em, origins, dirs, tmax) for em in lights.emitters]
    for e, r in enumerate(rules):
        if r is not None:
            near[:, e] = r.rays
    passing = _passing(lights, method, tol, origins, dirs, near)
    shine = _shines(lights, cone, tmax, n)
    near &= shine
    passing &= shine
    own = method.sphere(medium, params) if method.stochastic and method.sphere is not None else None
    owns = [None if em is None else own_estimate(em, own) for em in lights.emitters]
    if method.stochastic:  # its own estimate (of the spheres), else the rows (a flat emitter's: it samples them)
        near &= np.array([o is not None for o in owns], bool)[None, :]
    hidden = np.zeros((n, n_e), bool)
    if shadows and (near | passing).any():
        if not method.stochastic:
            lit = _lit_or_unseen(lights, cone, segs, n)
            near &= lit
            passing &= lit
        hidden = _may_hide(ctx[0], lights, near, rays)
        near &= ~hidden
    if not (near | hidden | passing).any():
        return segs, air, stats, near.any(axis=1), var
    owner = np.where(lights.cubature, lights.owner, 0)[segs.light]
    drop = (near | hidden | passing)[segs.ray, owner] & lights.cubature[segs.light]
    kept = segs.take(np.nonzero(~drop)[0])
    for e in np.unique(np.nonzero(hidden)[1]):
        if owns[e] is not None:
            rs = np.nonzero(hidden[:, e])[0]
            value, v = owns[e](e, rays, rs, functools.partial(_in_sight, ctx[0]))
            air[rs] += value
            var[rs] += v
            continue
        for rs, sample in cap_samplers(lights.emitters[e], rays, np.nonzero(hidden[:, e])[0]):
            value, v = emitter_estimate(ctx[0], method, medium, params, lights.emitters[e], e, rs, rays, ctx[1],
                                        sample)
            air[rs] += value
            var[rs] += v
    for e in np.unique(np.nonzero(near)[1]):
        rs = np.nonzero(near[:, e])[0]
        em = lights.emitters[e]
        if owns[e] is not None:
            value, v = owns[e](e, rays, rs)
            air[rs] += value
            var[rs] += v
            continue
        value, stray = _ladder(em, rules[e].rule(rays, rs), rules[e].orders, method, medium, params, tol, rs, rays,
                               segs.scale, np.abs(seen[rs]))
        air[rs] += value
        stats += (len(rs), stray)
    for e in np.unique(np.nonzero(passing)[1]):
        rs = np.nonzero(passing[:, e])[0]
        em = lights.emitters[e]
        value, stray = _ladder(em, passing_rule(em, rays, rs), ORDERS, method, medium, params, tol, rs, rays,
                               segs.scale, np.abs(seen[rs]))
        air[rs] += value
        stats += (len(rs), stray)
    return kept, air, stats, (near | hidden | passing).any(axis=1), var


def _passing(lights, method, tol, origins, dirs, near) -> np.ndarray:
    """(N, E) the camera rays that pass within cubature.PASSING of a flat emitter's diameter of it (the
    pilot's measure: they do not choose its order) and are not `near` it, for a deterministic method
    with a precision (whose pilot chose the order)."""
    out = np.zeros(near.shape, bool)
    if tol is None or method.stochastic:
        return out
    for e, em in enumerate(lights.emitters):
        if em is not None:
            out[:, e] = passing_of(em, origins, dirs) & ~near[:, e]
    return out


def _in_sight(accel, points, dirs, dist) -> np.ndarray:
    """Whether nothing lies between each point and the point `dist` along its unit direction."""
    eps = accel.epsilon
    return ~accel.occluded(points + eps * dirs, dirs, np.maximum(dist - 2.0 * eps, 0.0))


def _may_hide(accel, lights, near, rays) -> np.ndarray:
    """(N, E) the near pairs whose camera ray's segment the occluders' geometry does not clear of hiding
    part of the emitter (`near_rules.segments_clear`: a sphere's; the others' rows tell)."""
    origins, dirs, tmax = rays[:3]
    out = np.zeros(near.shape, bool)
    for e in np.unique(np.nonzero(near)[1]):
        rs = np.nonzero(near[:, e])[0]
        out[rs, e] = ~segments_clear(lights.emitters[e], accel, origins[rs], dirs[rs], np.asarray(tmax, float)[rs])
    return out


def _shines(lights, cone, tmax, n: int) -> np.ndarray:
    """(N, E) whether emitter e shines on camera ray r: a flat emitter where one of its rows does (its
    cone segments `cone`); a sphere wherever it is on (its rows' intensity is not zero: none in another
    light's layer) and the ray's segment has a length (its origin outside the sphere, checked apart,
    sees a cap of it, on which no row may lie: no order of the rows decides it)."""
    n_e = len(lights.emitters)
    rows = lights.cubature[cone.light]
    out = np.zeros((n, n_e), bool)
    out[cone.ray[rows], lights.owner[cone.light[rows]]] = True
    on = np.zeros(n_e + 1, bool)
    on[np.where(lights.cubature & np.any(lights.intensity != 0.0, axis=1), lights.owner, n_e)] = True
    out[:, _undecided(lights) & on[:n_e]] = (np.asarray(tmax, float) > 0.0)[:, None]
    return out


def _lit_or_unseen(lights, cone, lit, n: int) -> np.ndarray:
    """(N, E) whether every row of emitter e that shines on camera ray r is lit along all of it, or, for
    a sphere, no row shines on it (`_shines`: its rule or samples decide, `_may_hide`)."""
    n_l = len(lights)
    row_state = lit_states(cone, lit, cone.ray * n_l + cone.light, lit.ray * n_l + lit.light, n * n_l)
    state = emitter_states(row_state.reshape(n, n_l), lights.owner, lights.cubature, len(lights.emitters))
    return (state == LIT) | ((state == NONE) & _undecided(lights)[None, :])


def _undecided(lights) -> np.ndarray:
    """(E,) whether each emitter's rows decide nothing of it (`near_rules.rows_decide`: a sphere's)."""
    return np.array([em is not None and not rows_decide(em) for em in lights.emitters], dtype=bool)


def _ladder(emitter, rule, orders, method, medium, params, tol, rs, rays, scale, seen):
    """((P, 3) the air-light of `emitter` along camera rays `rs` by its `rule` (`near_rules.Near.rule`,
    `near_rules.passing_rule`) at `orders` in turn (the first two, which every ray takes, in one batch), the
    number of rays whose last two orders disagree; `seen` (P, 3) the rays' other radiance)."""
    if tol is None:
        return _values(emitter, rule, method, medium, params, np.arange(len(rs)), rs, rays, scale,
                       (DEFAULT_ORDER,))[0], 0
    out = np.zeros((len(rs), 3))
    todo = np.arange(len(rs))
    first = _values(emitter, rule, method, medium, params, todo, rs, rays, scale, orders[:2])
    coarse = first[0]
    for k, order in enumerate(orders[1:]):
        fine = first[1] if k == 0 else _values(emitter, rule, method, medium, params, todo, rs[todo], rays, scale,
                                               (order,))[0]
        ok = agree(coarse, fine, SHARE * tol, seen[todo])
        out[todo] = fine
        todo, coarse = todo[~ok], fine[~ok]
        if not len(todo):
            break
    return out, len(todo)


def _values(emitter, rule, method, medium, params, at, rs, rays, scale, orders):
    """[(P, 3) per order of `orders`]: the air-light of `emitter` along camera rays `rs` (= the pairs
    `at` of its `rule`) by the rule of each order, their rows integrated in one batch."""
    built = [rule(at, order) for order in orders]
    points, normals, weights, owner = (np.concatenate(c) for c in zip(*built))
    part = np.repeat(np.arange(len(orders)), [len(b[2]) for b in built])  # the order of each node
    rows = spot_rows(points, normals, weights[:, None] * emitter.radiance[None, :], emitter.two_sided)
    group, part = (np.repeat(owner, 2), np.repeat(part, 2)) if emitter.two_sided else (owner, part)  # a node twice
    each = per_group(method, medium, params, rows, point_segments(rows, 1, rays, rs[group], scale), len(rows))
    out = np.zeros((len(orders), len(rs), 3))
    np.add.at(out, (part, group), each)
    return list(out)
