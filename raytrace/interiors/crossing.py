"""Media inside shapes (after the analytic note on single scattering in homogeneous slabs): the
boundary crossing. Camera rays whose first hit is a shape holding an `interior` medium are taken
across its boundary (`cross`; a camera inside a shape: `start_inside`): refracted in
(Snell, smooth dielectric; straight when ior = 1; fresnel.py) with Fresnel's transmittance T, followed inside to
their exit (Embree; `_inside_hits`), refracted out, and mirrored by a refractive boundary with 1 - T.
What comes of it is a `Crossing`: one inside `Segments` row per ray, which carries its medium (the
shape) and how light reaches it (`STRAIGHT` to a convex index-matched shape's faces, `TRACED` through
a non-convex one or an exact sphere (paths.py: Embree walks, or the sphere's closed-form chords in
media/slab.py's kernel), `REFRACTED` through a refractive boundary), the rays that go on beyond the exit or
the mirror, which the renderer shades like camera rays (up to MAX_DEPTH boundaries deep; deeper ones
are black), and the factors that carry what they see back (`combine`). The rows are integrated by
the method's inside rule (interiors/rows.py); a plain surface met inside is shaded by surfaces.py
(`surface_inside`), one met where a ray leaves with the lights inside refractive shapes too (held.py).
Radiance crossing into a denser medium is multiplied by T eta^2 and back out by T / eta^2 (the
invariance of L / n^2, as pbrt-v4 and Mitsuba 3 scale it); reflections inside a shape are not
followed: total internal reflection at an exit ends the path. What the methods take inside shapes and the
statistics of the inside integrals: support.py; the shapes' planes and caches: shapes.py.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..methods import Segments
from ..shading import facing_normals, shading_normals, surface_radiance
from .fresnel import refract, transmittance
from .held import lit_from_inside
from .shapes import convex_planes, enters, nudge, shadow_through
from .surfaces import surface_inside

MAX_DEPTH = 4  # boundaries a camera path crosses into bounded media; deeper ones are black
STRAIGHT, TRACED, REFRACTED = range(3)  # how light reaches an inside row (`Segments.reach`)


def warm_up_rays(prep, origins, dirs):
    """`origins`, `dirs` and one ray from the camera toward the centre of each shape holding a medium,
    so that the renderer's warm-up compiles the kernels of bounded media too."""
    cam = prep.scene.camera.position
    extra = []
    for sid in prep.interior_shapes:
        to = prep.accel.triangles[prep.shape_ids == sid].reshape(-1, 3).mean(axis=0) - cam
        if np.linalg.norm(to) > 0.0:
            extra.append(to / np.linalg.norm(to))
    if not extra:
        return origins, dirs
    return (np.concatenate([origins, np.repeat(cam[None, :], len(extra), axis=0)]),
            np.concatenate([dirs, np.array(extra)]))


def _skip(prep, cos):
    """The step (N,) past which the first hit of a ray leaving a shape (cosine `cos` to the face it
    leaves) is asked (shapes.py `nudge`'s), so that Embree does not report the face left; the ray itself goes on
    from the face (its air-light and transmittance from there: renderer `_across`)."""
    return prep.accel.epsilon / np.maximum(cos, 1e-2)


def _plane_distance(accel, points, dirs, prim, hit):
    """Distance from each point along its direction to the plane of triangle prim (inf on a miss): the
    inside segment measured from the entry point itself, not from the offset start of the Embree ray;
    on an exact sphere, `hit`: the query's own float64 distance, measured from the point."""
    out = np.full(len(points), np.inf)
    ok = prim >= 0
    n = accel.normals[prim[ok]]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.einsum("ij,ij->i", accel.triangles[prim[ok], 0] - points[ok], n) / np.einsum("ij,ij->i", dirs[ok], n)
    out[ok] = np.where(np.isfinite(t) & (t > 0.0), t, 0.0)
    on_sphere = ok & (accel.sphere_of[np.maximum(prim, 0)] >= 0)
    out[on_sphere] = hit[on_sphere]
    return out


def _parts(prep):
    """Embree scenes of the interiors' boundaries and of the opaque surfaces apart (built once)."""
    inner = np.isin(prep.shape_ids, prep.interior_shapes)
    return [prep.accel.subset(key, lambda m=mask: np.nonzero(m)[0])
            for key, mask in (("interior boundaries", inner), ("opaque surfaces", ~inner))]


def _met_at_once(prep, q, w, cos, touch):
    """The opaque triangle (or -1) a ray leaving a shape at q along w (cosine `cos` to the exit
    face) meets within the step `_skip` would skip, and where: `touch` (`_inside_hits`: a
    surface touching the exit face, met at q) or the first opaque surface from q itself (the
    interior's own faces are not in that scene), such as a floor beside the foot of a block that the
    ray leaves through a side face just above it."""
    opaque = _parts(prep)[1]
    t, k = opaque.first_hit(q, w)
    k[k >= 0] = opaque.ids[k[k >= 0]]
    near = (touch < 0) & (k >= 0) & (t <= prep.accel.epsilon / np.maximum(cos, 1e-2))
    return np.where(near, k, touch), q + np.where(near, t, 0.0)[:, None] * w


def _inside_hits(prep, p, w, cos, prim):
    """What rays entering a shape at p along w (cosine `cos` to the entry face) meet first inside:
    (distance from p, triangle, the triangle of an opaque surface touching the boundary crossed, or
    -1). The interiors' boundaries and the opaque surfaces are asked of separate Embree scenes and
    their hits measured from p in float64 (`_plane_distance`), so which of two coincident faces
    Embree's float32 reports first does not matter: a surface is inside the medium only if it comes
    more than accel.epsilon / cos (the step `_skip` takes) before the boundary; one within that of
    it, on either side, touches the boundary (a block standing on a floor), and the ray leaves the
    medium and meets it at once, the limit of a small gap. A ray that meets no boundary beyond the
    step left the closed shape within it (it clips an edge or a corner of the entry face `prim`): it
    leaves at once, back through the entry face's plane (distance 0, triangle `prim`), the limit of
    a clip of vanishing length, never a surface beyond taken for one inside the medium."""
    accel = prep.accel
    start = nudge(accel, p, w, cos)
    hits = []
    for part in _parts(prep):
        t, k = part.first_hit(start, w)
        k[k >= 0] = part.ids[k[k >= 0]]
        hits.append((_plane_distance(accel, p, w, k, np.einsum("ij,ij->i", start - p, w) + t), k))
    (tb, kb), (to, ko) = hits
    at = p + np.where(ko >= 0, to, 0.0)[:, None] * w
    tol = accel.epsilon / np.maximum(np.abs(np.einsum("ij,ij->i", accel.hit_normals(np.maximum(ko, 0), at), w)), 1e-2)
    clip = kb < 0
    wall = (ko >= 0) & ~clip & (to < tb - tol)
    touch = np.where(~wall & (ko >= 0) & ~clip & (to <= tb + tol), ko, -1)
    return np.where(wall, to, np.where(clip, 0.0, tb)), np.where(wall, ko, np.where(clip, prim, kb)), touch


@dataclass
class Crossing:
    """N rays taken across the boundary of shapes that hold a medium: one inside row each (`rows`,
    ell = 0 where nothing is inside: total reflection, a clipped edge, the depth cap), what their
    integrals are multiplied by at the entry (`entry` (N,): Fresnel's T / eta^2, the invariance of
    L / n^2), the radiance already known behind each row (`direct` (N, 3): a surface met inside the
    medium, or met at once where the ray leaves it), and the rays that go on (`origins`, `dirs`,
    `keys`): through the exit face (`parent`, with the factor `weight` (M, 3) that carries what they
    see to the row's end and back to its start, under `entry`) or mirrored by a refractive boundary
    (`mirrored`: `weight` is Fresnel's 1 - T, outside `entry`)."""
    rows: Segments
    entry: np.ndarray
    direct: np.ndarray
    origins: np.ndarray
    dirs: np.ndarray
    keys: np.ndarray
    parent: np.ndarray
    weight: np.ndarray
    mirrored: np.ndarray
    skip: np.ndarray  # (M,) the going-on rays' first hits are asked past this step from their origins


def _rows(prep, sid, points, normals, w, ell, keys) -> Segments:
    """Inside rows of shape sid from `points` along `w` for `ell` (every light: light -1), with how light
    reaches them: refracted through the boundary, straight to a convex shape's planes, or traced."""
    n = len(points)
    reach = (REFRACTED if prep.scene.shapes[sid].interior.ior != 1.0 else
             STRAIGHT if len(convex_planes(prep, sid)) else TRACED)
    return Segments(points, w, ell, np.full(n, -1, np.int64), np.arange(n), np.zeros(n), keys, np.zeros(n, np.int64),
                    scale=prep.accel.scale, medium=np.full(n, sid, np.int64), normals=normals,
                    reach=np.full(n, reach, np.int8))


def _joined(parts: list, n: int) -> Crossing:
    """One Crossing of N rays from the per-shape parts (index arrays into the N rays, Crossing)."""
    rows = [c.rows for _, c in parts]
    order = np.argsort(np.concatenate([sel for sel, _ in parts]), kind="stable")
    cat = lambda get: np.concatenate([get(r) for r in rows])[order]
    joined = Segments(cat(lambda r: r.origins), cat(lambda r: r.dirs), cat(lambda r: r.length),
                      np.full(n, -1, np.int64), np.arange(n), np.zeros(n), cat(lambda r: r.keys),
                      np.zeros(n, np.int64), scale=rows[0].scale, medium=cat(lambda r: r.medium),
                      normals=cat(lambda r: r.normals), reach=cat(lambda r: r.reach))
    grab = lambda get: np.concatenate([get(c) for _, c in parts])
    return Crossing(joined, grab(lambda c: c.entry)[order], grab(lambda c: c.direct)[order],
                    grab(lambda c: c.origins), grab(lambda c: c.dirs), grab(lambda c: c.keys),
                    np.concatenate([sel[c.parent] for sel, c in parts]), grab(lambda c: c.weight),
                    grab(lambda c: c.mirrored), grab(lambda c: c.skip))


def cross(prep, origins, dirs, t, prim, keys, depth) -> Crossing | None:
    """Rays that meet a shape holding a medium from outside at t (triangle prim), taken across its
    boundary: refracted in (Snell, smooth dielectric; straight when ior = 1) with Fresnel's T, followed
    inside to what they meet first (`_inside_hits`), refracted out at the exit, and mirrored by a
    refractive boundary with 1 - T (1 on total reflection). None at MAX_DEPTH boundaries deep: black by
    the model."""
    if depth >= MAX_DEPTH:
        return None
    points = origins + t[:, None] * dirs
    normals = facing_normals(prep.accel.hit_normals(prim, points), dirs)
    shape = prep.shape_ids[prim]
    parts = []
    for sid in np.unique(shape).tolist():
        sel = np.nonzero(shape == sid)[0]
        parts.append((sel, _across(prep, sid, points[sel], dirs[sel], normals[sel], keys[sel], prim[sel])))
    return _joined(parts, len(origins))


def _across(prep, sid, p, d, nf, keys, prim) -> Crossing:
    """`cross` for the rays entering shape sid at p along d (facing entry normals nf; triangles prim)."""
    n = len(p)
    none = np.zeros(0, np.int64)
    medium = prep.scene.shapes[sid].interior
    eta = medium.ior
    w, cos_t = refract(d, nf, eta)
    t_in = transmittance(-np.einsum("ij,ij->i", d, nf), eta) * (cos_t > 0.0)  # T, 0 on total reflection
    ell, prim2, touch = _inside_hits(prep, p, w, cos_t, prim)
    direct = np.zeros((n, 3))
    exits = np.nonzero((prim2 >= 0) & (prep.shape_ids[np.maximum(prim2, 0)] == sid))[0]
    go = [(none, np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), False, np.zeros(0))]  # Crossing's parent,
    # origins, dirs, weight, mirrored and skip
    if len(exits):
        go.append(_exit(prep, medium, exits, p[exits] + ell[exits, None] * w[exits], w[exits], prim2[exits],
                         ell[exits], touch[exits], direct))
    walls = np.nonzero((prim2 >= 0) & ~enters(prep, prim2))[0]  # a plain surface inside the medium
    if len(walls):
        direct[walls] = surface_inside(prep, sid, p[walls], nf[walls], w[walls], prim2[walls], ell[walls])
    if eta != 1.0:  # the boundary's mirror reflection, Fresnel's 1 - T (1 on total reflection)
        cos = -np.einsum("ij,ij->i", d, nf)
        mirrored = d + 2.0 * cos[:, None] * nf
        go.append((np.arange(n), p, mirrored, np.repeat((1.0 - t_in)[:, None], 3, axis=1), True, _skip(prep, cos)))
    parent = np.concatenate([g[0] for g in go])
    return Crossing(_rows(prep, sid, p, nf, w, ell, keys), t_in / (eta * eta), direct,
                    np.concatenate([g[1] for g in go]), np.concatenate([g[2] for g in go]), keys[parent], parent,
                    np.concatenate([g[3] for g in go]), np.concatenate([np.full(len(g[0]), g[4]) for g in go]),
                    np.concatenate([g[5] for g in go]))


def _exit(prep, medium, rows, q, w, prim, ell, touch, direct):
    """The rays of inside rows `rows` leaving their shape (interior `medium`) at q (M, 3) along w through
    its boundary's triangles prim after `ell` inside: refracted out (straight when ior = 1) with
    Fresnel's T (0 on total reflection) times eta^2 and the inside transmittance; a surface met at
    once where a ray leaves (`_met_at_once`; `touch` from `_inside_hits`, or -1) is shaded into
    `direct` (N, 3) at once. Returns the rays going on as a Crossing's (parent, origins (on the boundary),
    dirs, weight, mirrored, skip)."""
    accel = prep.accel
    eta = medium.ior
    m = facing_normals(accel.hit_normals(prim, q), w)
    w_out, cos_o = refract(w, m, 1.0 / eta)
    t_out = transmittance(-np.einsum("ij,ij->i", w, m), 1.0 / eta) * (cos_o > 0.0)
    on, at = _met_at_once(prep, q, w_out, cos_o, touch)
    rest = on >= 0
    kt = medium.sigma_t[None, :]
    with np.errstate(over="ignore", invalid="ignore"):
        tr = np.where(kt == 0.0, 1.0, np.exp(-kt * ell[:, None]))
    f = (t_out * eta * eta)[:, None] * tr
    if rest.any():  # a surface met at once where the ray leaves
        on = on[rest]
        geometric = facing_normals(accel.hit_normals(on, at[rest]), w_out[rest])
        shading = shading_normals(accel, prep.corner_normals, on, at[rest], geometric)
        direct[rows[rest]] = f[rest] * (surface_radiance(
            accel, at[rest], geometric, prep.reflectance[on], prep.lights, prep.scene.medium, shadow_through(prep),
            shading) + lit_from_inside(prep, at[rest], geometric, shading, prep.reflectance[on]))
    return rows[~rest], q[~rest], w_out[~rest], f[~rest], False, _skip(prep, cos_o[~rest])


def start_inside(prep, origins, dirs, t, prim, keys) -> Crossing:
    """Camera rays that start inside the shape prep.camera_inside (index-matched, or convex and
    refractive: an underwater camera) and first meet its boundary or a surface at t (triangle prim):
    their inside rows over [0, t], the surface met inside, and the rays going on beyond the boundary
    (`_exit`: refracted out, times T eta^2 exp(-sigma_t t)). The rows have no entry face: normals -dirs
    in an index-matched shape, zero in a refractive one (media/slab.py `refracting_faces` then takes
    every face alike)."""
    sid = prep.camera_inside
    medium = prep.scene.shapes[sid].interior
    n = len(origins)
    direct = np.zeros((n, 3))
    exits = np.nonzero((prim >= 0) & (prep.shape_ids[np.maximum(prim, 0)] == sid))[0]
    parent, start, w_out, f, _, skip = _exit(prep, medium, exits, origins[exits] + t[exits, None] * dirs[exits],
                                             dirs[exits], prim[exits], t[exits], np.full(len(exits), -1), direct)
    normals = -dirs if medium.ior == 1.0 else np.zeros_like(dirs)
    walls = np.nonzero((prim >= 0) & ~enters(prep, prim))[0]
    if len(walls):
        direct[walls] = surface_inside(prep, sid, origins[walls], normals[walls], dirs[walls], prim[walls], t[walls])
    return Crossing(_rows(prep, sid, origins, normals, dirs, t, keys), np.ones(n), direct, start, w_out, keys[parent],
                    parent, f, np.zeros(len(parent), bool), skip)


def combine(crossing: Crossing, inner, inner_var, inner_bound, seen, seen_var, seen_bound):
    """Radiance (N, 3), variance (N, 3) and error bound (N, 3) arriving back along the crossing's rays:
    entry x (the inside rows' integrals `inner` + what comes through from behind: `direct`, or the
    rays going on through the exit, `seen`, times their weights), plus the mirrored rays' radiance
    times 1 - T. Variances scale with the factors squared, bounds with `scaled`."""
    ex = np.nonzero(~crossing.mirrored)[0]
    on = crossing.parent[ex]
    w = crossing.weight[ex]
    behind = crossing.direct.copy()
    behind[on] = w * seen[ex]
    bound = inner_bound.copy()
    bound[on] += scaled(seen_bound[ex], w)
    behind_var = np.zeros_like(behind)
    if seen_var is not None:
        behind_var[on] = w * w * seen_var[ex]
    f = crossing.entry[:, None]
    out = f * (inner + behind)
    out_var = f * f * (inner_var + behind_var)
    out_bound = scaled(bound, f)
    mi = np.nonzero(crossing.mirrored)[0]
    on, r = crossing.parent[mi], crossing.weight[mi]
    out[on] += r * seen[mi]
    out_bound[on] += scaled(seen_bound[mi], r)
    if seen_var is not None:
        out_var[on] += r * r * seen_var[mi]
    return out, out_var, out_bound


def scaled(bound, f):
    """bound x f (f >= 0), inf where bound is inf (also where f = 0: nothing known was multiplied)."""
    out = np.full(np.broadcast_shapes(bound.shape, np.shape(f)), np.inf)
    np.multiply(bound, f, out=out, where=~np.isinf(bound))
    return out
