"""What the renderer asks of an emitter (`area.Emitter`) along camera rays and at surface points, whatever
its kind: rendering/near_emitters.py, shading.py and shadows/penumbra_airlight.py ask these and never
which kind an emitter is (docs/area_lights.md, "Rays near an emitter", "Sphere emitters along a ray").

A flat emitter (`Emitter.planar`) replaces its rows along the camera rays that cross its plane on or
near it (within cubature.NEAR_FRACTION of its diameter) by a rule about the ray's foot point, and a
sphere (`Emitter.ball`) along every camera ray from outside it by a rule about the ray's segment
(`near`); an emissive shape keeps its rows. Along the rays that pass within cubature.PASSING of a
polygon grazing its plane, a rule graded toward the ray's projection on it (`passing_rule`). A sphere's
rows' shadow states decide nothing (all lit, all dark or none shining: a cap between them may differ,
`rows_decide`), so the occluders' geometry (`segments_clear`, `free`) and its probes of the part a point
sees (`seen_probes`) tell instead.
"""
from __future__ import annotations

import functools
from typing import Callable, NamedTuple

import numpy as np

from .cubature import NEAR_FRACTION, PASSING, passes
from .planar import GRAZE, plane_feet
from .sphere_occluders import free as sphere_free, segments_free
from .sphere_rule import FIRST

ORDERS = (2, 3, 4, 6, 8, 12, 16, 24, 32)  # nodes per parameter of each of a rule's parts (consecutive pairs compared)


class Near(NamedTuple):
    """The camera rays near an emitter and its rule about them: `rays` (N,) which are near, `rule(rays,
    rs)` -> rule(at, order) -> (points (M, 3), unit normals (M, 3), area weights (M,), owner (M,): the
    index into `at` of each node) about the camera rays rs[at] (rays = (origins, dirs, tmax, ...)),
    `orders` its ladder."""
    rays: np.ndarray
    rule: Callable
    orders: tuple


def replaces_rows(emitter, stochastic: bool) -> bool:
    """Whether camera rays near the emitter may take a rule of its own or a stochastic method's own
    estimate of it: a sphere's always, a flat emitter's with a deterministic method (a stochastic one
    samples its rows)."""
    return emitter.ball is not None or (emitter.planar is not None and not stochastic)


def rows_decide(emitter) -> bool:
    """Whether the shadow states of the emitter's rows decide its own: all lit along a segment (or at
    a point) prove all of it lit, all dark all of it hidden, and none shining that it shines not; not a
    sphere's (module docstring)."""
    return emitter.ball is None


def near(emitter, origins, dirs, tmax) -> Near | None:
    """The emitter's `Near` for the camera rays (origins, unit dirs, tmax) (N,) each: a sphere's every
    ray from outside it, its ladder from sphere_rule.FIRST; a flat emitter's those whose segment's foot
    point (`planar.plane_feet`) lies within NEAR_FRACTION of its diameter of it, the whole ladder.
    None: the emitter keeps its rows (an emissive shape)."""
    if emitter.ball is not None:
        return Near(emitter.ball.outside(origins), functools.partial(_ball_rule, emitter.ball),
                    ORDERS[ORDERS.index(FIRST):])
    if emitter.planar is None:
        return None
    planar = emitter.planar
    foot, height = plane_feet(planar.centre, planar.normal, origins, dirs, tmax)
    close = np.hypot(height, planar.outside(foot)) < NEAR_FRACTION * planar.diameter
    return Near(close, functools.partial(_planar_rule, planar, foot), ORDERS)


def passing(emitter, origins, dirs) -> np.ndarray:
    """(N,) the camera rays that pass within cubature.PASSING of a flat emitter's diameter of it (the
    pilot's measure, `cubature.passes`: they do not choose its order); none for other kinds."""
    if emitter.planar is None:
        return np.zeros(len(origins), bool)
    return passes(emitter.sample, origins, dirs, PASSING)


def passing_rule(emitter, rays, rs):
    """rule(at, order) -> (points, normals, weights, owner) (`Near.rule`) of a flat emitter about the camera rays
    rs[at] (rays = (origins, dirs, ...)) that pass near it (`passing`): those that graze its plane (sine below
    planar.GRAZE) by its `Planar.ridge` where it has one, the others by its rows (`Emitter.rule`), the same nodes
    for each ray."""
    planar = emitter.planar
    origins, dirs = rays[0][rs], rays[1][rs]
    graze = (np.abs(dirs @ planar.normal) < GRAZE) & (planar.ridge is not None)
    ridge = planar.ridge(origins[graze], dirs[graze]) if graze.any() else None
    where = np.cumsum(graze) - 1  # each grazing ray's index among them

    def rule(at, order):
        parts = []
        g = graze[at]
        if g.any():
            points, weights, owner = ridge(where[at[g]], order)
            parts.append((points, np.broadcast_to(planar.normal, points.shape), weights, np.nonzero(g)[0][owner]))
        if not g.all():
            points, normals, weights = emitter.rule(order)
            others = np.nonzero(~g)[0]
            k = len(others)
            parts.append((np.tile(points, (k, 1)), np.tile(normals, (k, 1)), np.tile(weights, k),
                          np.repeat(others, len(weights))))
        return tuple(np.concatenate(c) for c in zip(*parts))
    return rule


def own_estimate(emitter, estimate):
    """A stochastic method's own estimate of the emitter (`Method.sphere`'s, estimate(ball, radiance, owner,
    rays, rs[, visible])) bound to it: (owner, rays, rs[, visible]) -> (value (P, 3), variance (P, 3)), or
    None where the estimate does not take it (not a sphere) or there is none."""
    if estimate is None or emitter.ball is None:
        return None
    return functools.partial(estimate, emitter.ball, emitter.radiance)


def cap_samplers(emitter, rays, rs) -> list:
    """[(camera rays, sampler)]: of the camera rays `rs` (of rays = (origins, dirs, tmax, ...)) near a
    sphere emitter, those whose segments see a part of it within a cap (`sphere_rule.Ball.seen_cap`) with
    a sampler of that cap (penumbra_airlight.emitter_estimate's `sample`), and those whose cap is the
    whole sphere with None (the emitter's own samples)."""
    ball = emitter.ball
    origins, dirs, tmax = rays[:3]
    h = ball.seen_cap(origins[rs], dirs[rs], np.asarray(tmax, float)[rs])[1]
    capped, whole = rs[h < 2.0], rs[h >= 2.0]

    def sample(at, u, v):
        return ball.sample_cap(*ball.seen_cap(origins[at], dirs[at], np.asarray(tmax, float)[at]), u, v)
    return [(r, f) for r, f in ((capped, sample), (whole, None)) if len(r)]


def segments_clear(emitter, accel, origins, dirs, tmax) -> np.ndarray:
    """(P,) whether the occluders' geometry clears each camera ray's segment of hiding part of a sphere
    emitter (`sphere_occluders.segments_free`, the same for every cubature order); everywhere for other
    kinds (their rows tell)."""
    if emitter.ball is None:
        return np.ones(len(origins), bool)
    return segments_free(emitter.ball.centre, emitter.ball.radius, origins, dirs, tmax, accel.triangles,
                         accel.sphere_of, accel.spheres, accel.epsilon)


def free(emitter, accel, points, normals) -> np.ndarray:
    """(N,) where nothing but the emitter can hide any of it from the surface points: for a sphere, the
    exact test of the occluders' geometry (`sphere_occluders.free`, the same for every cubature order);
    nowhere for other kinds (their rows and probes tell)."""
    if emitter.ball is None:
        return np.zeros(len(points), dtype=bool)
    return sphere_free(emitter.ball.centre, emitter.ball.radius, points, normals, accel.triangles, accel.sphere_of,
                       accel.spheres, accel.epsilon)


def seen_probes(emitter, points, normals):
    """(probes (M, K, 3), outward (M, K, 3)): a sphere emitter's probes of the part each point sees
    (`sphere_rule.Ball.probes`, NaN where unused; `normals` (M, 3) or a list of them) and the sphere's
    outward normals at them, unnormalised (probe - centre)."""
    y = emitter.ball.probes(points, normals)
    return y, y - emitter.ball.centre


def _planar_rule(planar, feet, rays, rs):
    """rule(at, order) of a flat emitter about the `feet` [rs[at]] of camera rays rs[at] (`Near.rule`), what
    does not depend on the order built once (`Planar.about`)."""
    nodes = planar.about(feet[rs], rays[1][rs])

    def rule(at, order):
        points, weights, owner = nodes(at, order)
        return points, np.broadcast_to(planar.normal, points.shape), weights, owner
    return rule


def _ball_rule(ball, rays, rs):
    """rule(at, order) of a sphere emitter about camera rays rs[at] (`Near.rule`)."""
    origins, dirs, tmax = rays[:3]

    def rule(at, order):
        r = rs[at]
        return ball.rule(origins[r], dirs[r], np.asarray(tmax, float)[r], order)
    return rule
