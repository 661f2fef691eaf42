"""Media inside shapes (after the analytic note on single scattering in homogeneous slabs): camera rays
that enter a shape holding an `interior` medium.

The renderer (`renderer.shade_rays`) hands over the rays whose first hit is such a shape, from
outside. Here each ray is refracted into the shape (Snell, smooth dielectric; straight when
ior = 1) with the Fresnel transmittance T, followed inside to its exit (Embree), and its inside
segment gets the single scattering of every light (media/slab.py), the light entering through the
plane of the entry face (the note's planar boundary): a directional light refracted through it
(eq. 5; in convex shapes every method but slab_approx takes its exact path instead, through
whichever face it meets, and refracted through every face it meets if the shape is refractive:
`refracted_beams`; `analytic` in closed form, media/convex_directional.py), a point light along its straight path (index-matched,
eq. 7) or along its refracted path (Fermat's path through the plane, with the ray tube's
irradiance: media/slab.py refracted_point); a
spot light as a point light times its falloff on the direction in which the light leaves it. In
index-matched shapes quadrature, raymarch and montecarlo use the light's exact straight path instead:
to the boundary of a convex shape (`convex_planes`, numba, when it has few faces; Embree's batched
exits when it has many) or through every crossing of a non-convex one (inside_paths.py, Embree). At the exit the ray is refracted out and the renderer shades what lies
behind (recursively, up to MAX_DEPTH boundaries); a plain surface met inside is shaded there
(`_surface_inside`). Shadow rays pass through index-matched interiors (`shadow_through`). A camera
inside an index-matched medium starts its rays' first stretch there (`from_inside`).
Radiance crossing into a denser medium is multiplied by T eta^2 and back out by T / eta^2
(the invariance of L / n^2, as pbrt-v4 and Mitsuba 3 scale it). Where a camera path meets a
refractive boundary from outside, the boundary also mirrors what the reflected ray sees, times
Fresnel's reflectance 1 - T (`radiance`); reflections inside a shape are not followed: total internal
reflection at an exit ends the path.

Each method's `Supports.interiors` (methods/__init__.py) says how it integrates the inside segments
and what it takes there: `quadrature` (adaptive, the reference), `analytic` (directional lights only: the
exact closed form in convex index-matched shapes of at most MAX_FACES planes, with an error bound; the
adaptive quadrature in other index-matched shapes, counted; the refracted beams in convex refractive
shapes, bounded; eq. 5 through other refractive boundaries),
`slab_approx` (eq. 5 and the note's separable approximation for point lights, not spots), `raymarch` (its
`steps` midpoints per inside segment) and `montecarlo` (`samples` free-path samples per inside
segment and light, whatever its --sampling; variance kept) integrate the inside segments; `lecocq`
and `sun` are refused for scenes with interiors, in one line.
"""
from __future__ import annotations

import numpy as np

from . import inside_paths
from .errors import UserError
from .lights import DIRECTIONAL, Lights
from .media.adaptive import CAPPED
from .media.convex_directional import MAX_FACES, segments_bounded
from .media.slab import APPROX, CLOSED, GEO_COLUMNS, MARCH, QUAD, STREAM, inside_radiance, refract_rays, transmittances
from .methods import Segments, registry
from .beam_shadows import lit_pieces_of_beam
from .methods.geometry import segment_light_table
from .scene.meshes import convex_planes as hull_of
from .shading import facing_normals, surface_radiance
from .shadow_frusta import exact_lit_intervals
from .visibility import gather

# the inside integrals' statistics: media/adaptive.py's slots (EVALS, INTERVALS, CAPPED), the segments a
# CLOSED-mode method hands to quadrature (`single_scattering`); with volumetric shadows the inside segments
# rendered unshadowed (refractive or planar-model interiors: `lit_single_scattering`), the lit pieces of
# the others, and the outside air-light's pieces whose light crosses index-matched interiors
# (`through_airlight`) and those of their integrals that fell short of their tolerance
STATS_SIZE = 8
HANDED, UNSHADOWED, LIT_PIECES, THROUGH, THROUGH_CAPPED = range(3, 8)
MAX_DEPTH = 4  # boundaries a camera path crosses into bounded media; deeper ones are black
RTOL = 1e-10  # the inside quadrature's relative accuracy (`quadrature`: its own rtol)
# face planes of a convex shape up to which media/slab.py's kernel (every plane at every evaluation) is
# used; beyond, Embree's batched exits are faster (equal at ~120 planes: benchmarks/interiors_scale.py)
KERNEL_PLANES = 64


def summarize(prep, method, stats, shadows: bool = False) -> dict:
    """The render statistics of the inside integrals (`single_scattering`'s) in a scene with media
    inside shapes: the adaptive integrator's integrals that fell short of their tolerance (a piece
    accepted at a cap), as quadrature reports its own outside; for a CLOSED-mode method also the
    segments (one per ray and light) it handed to quadrature; nothing for the other inside
    integrators, which have no caps. With volumetric shadows also the inside segments rendered
    unshadowed, the lit pieces of the others, and the outside pieces integrated through interiors."""
    sup = method.supports.interiors
    if prep.interior_shapes is None or not len(prep.interior_shapes) or sup is None:
        return {}
    out = {}
    if sup.mode in (QUAD, CLOSED):
        out["inside: integrals not converged"] = int(stats[CAPPED])
    if sup.mode == CLOSED:
        out["inside: segments handed to quadrature"] = int(stats[HANDED])
    if shadows:
        out.update({"inside: segments unshadowed (refractive or planar model)": int(stats[UNSHADOWED]),
                    "inside: lit pieces": int(stats[LIT_PIECES]),
                    "shadows: pieces through interiors (quadrature)": int(stats[THROUGH]),
                    "shadows: through-interior integrals not converged": int(stats[THROUGH_CAPPED])})
    return out


def interiors(scene) -> list:
    """The interior medium of each shape (None for plain surfaces)."""
    return [s.interior for s in scene.shapes]


def outside_lights(prep):
    """The lights whose air-light outside the shapes a method must integrate: none when the scene has
    interior media and the outside does not scatter (then only bounded.py's kernels see them)."""
    if len(prep.interior_shapes) and not prep.scene.medium.scatters:
        return Lights.of([])
    return prep.lights


def matched(prep) -> list[int]:
    """The shapes whose interior is index-matched (ior = 1): light crosses them straight, attenuated."""
    if prep.interior_shapes is None:
        return []
    return [int(i) for i in prep.interior_shapes if prep.scene.shapes[i].interior.ior == 1.0]


def blockers(prep) -> np.ndarray | None:
    """The triangles that stop light (a mask over prep.accel.triangles; None: all of them): opaque
    surfaces and refractive interiors' boundaries (a refracted shadow would be a caustic, beyond
    single scattering), not index-matched interiors' boundaries, which attenuate it (`attenuators`)."""
    inner = matched(prep)
    return ~np.isin(prep.shape_ids, inner) if inner else None


def attenuators(prep) -> np.ndarray | None:
    """The index-matched interiors' triangles (a mask; None where the outside air-light never needs
    them: no such interior, or an outside medium that does not scatter)."""
    inner = matched(prep)
    if not inner or not prep.scene.medium.scatters:
        return None
    return np.isin(prep.shape_ids, inner)


def check(prep, method, method_params, source: str):
    """Refuse, in one line, what this first cut, or the method (its `Supports.interiors`), does not
    render in a scene with interior media."""
    inner = [i for i, m in enumerate(interiors(prep.scene)) if m is not None]
    if not inner:
        return
    key = f"shape[{inner[0]}].interior"
    sup = method.supports.interiors
    if sup is None:
        raise UserError(f"{source}: --method {method.name}: it does not integrate media inside shapes ({key}); use "
                        f"--method {', '.join(_takers())}")
    kinds = prep.lights.kinds()
    near = "point" in kinds or "spot" in kinds  # lights with a position
    fixed = [k for k in sup.fixed if method_params.get(k, method.params[k].default) != method.params[k].default]
    if fixed:
        raise UserError(f"{source}: {' / '.join('--' + k.replace('_', '-') for k in fixed)} "
                        f"({', '.join('render.' + k for k in fixed)}): not implemented inside bounded media ({key}) "
                        f"yet; remove {'it' if len(fixed) == 1 else 'them'}")
    for kind in sorted(kinds - set(sup.lights)):
        raise UserError(f"{source}: --method {method.name}: {kind} lights into a bounded medium ({key}): {sup.limits}; "
                        f"use --method {', '.join(_takers(lambda s: kind in s.lights))}")
    if method_params.get("shadow_test") == "samples":
        raise UserError(f"{source}: --shadow-test samples (render.shadow_test): not implemented with media inside "
                        f"shapes ({key}); use --shadow-test intervals (the default)")
    medium = prep.scene.medium
    if not medium.homogeneous:
        raise UserError(f"{source}: {key}: media inside shapes need a homogeneous (or vacuum) [medium] outside; "
                        f"{medium.type_name} is not implemented with them yet")
    for i in inner:
        m = prep.scene.shapes[i].interior
        method.check_phase(m, f"shape[{i}].interior.phase", source)
        for kind in sorted(kinds - set(sup.refracted) if m.ior != 1.0 else ()):
            raise UserError(f"{source}: shape[{i}].interior.ior: --method {method.name}: {kind} lights through a "
                            f"refractive boundary: {sup.limits}; use ior = 1, or --method "
                            f"{', '.join(_takers(lambda s: kind in s.refracted))}")
    if near:
        for i in inner:
            if prep.scene.shapes[i].interior.ior == 1.0:
                continue
            for j in range(len(prep.scene.shapes)):
                first = prep.accel.triangles[prep.shape_ids == j]
                if j != i and len(first) and inside_of(prep, first[0, 0], [i]) is not None:
                    raise UserError(f"{source}: shape[{j}]: lies inside shape[{i}], whose interior is refractive "
                                    f"(ior {prep.scene.shapes[i].interior.ior:g}); surfaces inside a refractive "
                                    "medium are lit by directional lights only (point and spot lights: not "
                                    "implemented yet); "
                                    "use ior = 1 or a directional light")
    inside = prep.camera_inside
    if inside is not None and (prep.scene.shapes[inside].interior.ior != 1.0 or not sup.exact_paths):
        raise UserError(f"{source}: camera.position: inside shape[{inside}], which holds a medium; a camera inside a "
                        "bounded medium needs an index-matched interior (ior = 1) and --method "
                        f"{', '.join(_takers(lambda s: s.exact_paths))}; move the camera out of the shape or change them")
    for li in np.nonzero(prep.lights.kind != DIRECTIONAL)[0]:
        inside = inside_of(prep, prep.lights.position[li], inner)
        if inside is not None:
            raise UserError(f"{source}: light[{li}].position: inside shape[{inside}], which holds a medium; lights "
                            "inside bounded media are not supported yet, move the light out of the shape")


def _takers(test=lambda interiors: True) -> list[str]:
    """The methods that integrate media inside shapes and whose `Supports.interiors` passes `test`."""
    return [m.name for m in registry().values() if m.supports.interiors is not None and test(m.supports.interiors)]


def inside_of(prep, o, inner) -> int | None:
    """The first shape of `inner` that contains the point o (odd number of crossings of a ray), else None."""
    d = np.array([0.5773502691896258, 0.5773502691896257, 0.5773502691896259]) + np.array([1e-3, -2e-3, 0.0])
    d /= np.linalg.norm(d)
    tris = prep.accel.triangles
    e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    pv = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, pv)
    ok = np.abs(det) > 1e-300
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    tv = o - tris[:, 0]
    u = np.einsum("ij,ij->i", tv, pv) * inv
    qv = np.cross(tv, e1)
    v = (qv @ d) * inv
    t = np.einsum("ij,ij->i", e2, qv) * inv
    cross = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    for i in inner:
        if np.count_nonzero(cross & (prep.shape_ids == i)) % 2:
            return i
    return None


def hull_planes(prep, sid):
    """The face planes (P, 4) of shape sid if it is convex (scene/meshes.py convex_planes), else
    None; cached on `prep` (inside_paths.py reads the cache for index-matched shapes)."""
    cache = prep.interior_planes
    if sid not in cache:
        sel = prep.shape_ids == sid
        cache[sid] = hull_of(prep.accel.triangles[sel], prep.accel.normals[sel])
    return cache[sid]


def convex_planes(prep, sid):
    """The face planes (P, 4: outward unit normal, offset) of shape `sid` for media/slab.py's convex
    kernel, which tests every plane at every integrand evaluation: those of a convex shape with at
    most KERNEL_PLANES of them, else an empty (0, 4) array (then an index-matched shape's light paths
    are measured with Embree, inside_paths.py: batched exits for convex shapes, walks for others; a
    refractive one keeps the entry plane)."""
    planes = hull_planes(prep, sid)
    return planes if planes is not None and len(planes) <= KERNEL_PLANES else np.zeros((0, 4))


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


def shadow_through(prep):
    """The shading's `through(li, points)` for a scene with index-matched interiors (else None): the
    transmittance toward light li of the interiors the straight shadow path crosses,
    exp(-(sigma_t inside - sigma_t outside) x length inside) each (the outside's own transmittance is
    the shading's); 0 where an opaque surface or a refractive interior blocks it (a refracted shadow
    would be a caustic, beyond single scattering)."""
    inner = matched(prep)
    if not inner:
        return None
    kt = np.array([prep.scene.shapes[i].interior.sigma_t for i in inner]) - prep.scene.medium.sigma_t[None, :]
    lights = prep.lights

    def through(li, points):
        if lights.kind[li] == DIRECTIONAL:
            dirs = np.broadcast_to(-lights.axis[li], points.shape)
            dist = np.full(len(points), np.inf)
        else:
            rel = lights.position[li] - points
            dist = np.linalg.norm(rel, axis=1)
            dirs = rel / dist[:, None]
        lengths, blocked = inside_paths.inside_lengths(prep, points, dirs, dist, inner, block=True,
                                                       margin=prep.accel.epsilon)
        return np.where(blocked[:, None], 0.0, np.exp(-lengths @ kt))
    return through


def enters(prep, prim) -> np.ndarray:
    """Which first hits `prim` (triangle ids, -1 for a miss) are on a shape holding a medium."""
    if prep.interior_shapes is None or not len(prep.interior_shapes):
        return np.zeros(len(prim), dtype=bool)
    return (prim >= 0) & np.isin(prep.shape_ids[np.maximum(prim, 0)], prep.interior_shapes)


def _nudge(accel, points, dirs, cos):
    """Points moved along their rays (cosine `cos` to the face they leave) to about accel.epsilon off
    the face: the ray's line is kept, so what it meets beyond is exactly what the unmoved ray meets."""
    return points + (accel.epsilon / np.maximum(cos, 1e-2))[:, None] * dirs


def _leave(prep, points, dirs, cos):
    """Where a ray leaving a shape at `points` goes on (`_nudge`) and the outside's transmittance (N, 3)
    over that short step, which the renderer's rays from the moved points no longer see."""
    step = prep.accel.epsilon / np.maximum(cos, 1e-2)
    return _nudge(prep.accel, points, dirs, cos), prep.scene.medium.transmittance_on(points, dirs, 0.0, step)


def _plane_distance(accel, points, dirs, prim):
    """Distance from each point along its direction to the plane of triangle prim (inf on a miss): the
    inside segment measured from the entry point itself, not from the offset start of the Embree ray."""
    out = np.full(len(points), np.inf)
    ok = prim >= 0
    n = accel.normals[prim[ok]]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.einsum("ij,ij->i", accel.triangles[prim[ok], 0] - points[ok], n) / np.einsum("ij,ij->i", dirs[ok], n)
    out[ok] = np.where(np.isfinite(t) & (t > 0.0), t, 0.0)
    return out


def _parts(prep):
    """Embree scenes of the interiors' boundaries and of the opaque surfaces apart (built once)."""
    inner = np.isin(prep.shape_ids, prep.interior_shapes)
    return [prep.accel.subset(key, lambda m=mask: np.nonzero(m)[0])
            for key, mask in (("interior boundaries", inner), ("opaque surfaces", ~inner))]


def _met_at_once(prep, q, w, cos, touch):
    """The opaque triangle (or -1) a ray leaving a shape at q along w (cosine `cos` to the exit
    face) meets within the step `_leave` would skip, and where: `touch` (`_inside_hits`: a
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
    more than accel.epsilon / cos (the step `_leave` takes) before the boundary; one within that of
    it, on either side, touches the boundary (a block standing on a floor), and the ray leaves the
    medium and meets it at once, the limit of a small gap. A ray that meets no boundary beyond the
    step left the closed shape within it (it clips an edge or a corner of the entry face `prim`): it
    leaves at once, back through the entry face's plane (distance 0, triangle `prim`), the limit of
    a clip of vanishing length, never a surface beyond taken for one inside the medium."""
    accel = prep.accel
    start = _nudge(accel, p, w, cos)
    hits = []
    for part in _parts(prep):
        _, k = part.first_hit(start, w)
        k[k >= 0] = part.ids[k[k >= 0]]
        hits.append((_plane_distance(accel, p, w, k), k))
    (tb, kb), (to, ko) = hits
    tol = accel.epsilon / np.maximum(np.abs(np.einsum("ij,ij->i", accel.normals[np.maximum(ko, 0)], w)), 1e-2)
    clip = kb < 0
    wall = (ko >= 0) & ~clip & (to < tb - tol)
    touch = np.where(~wall & (ko >= 0) & ~clip & (to <= tb + tol), ko, -1)
    return np.where(wall, to, np.where(clip, 0.0, tb)), np.where(wall, ko, np.where(clip, prim, kb)), touch


def _refract(d, n, eta):
    out, cos_t = np.empty_like(d), np.empty(len(d))
    refract_rays(np.ascontiguousarray(d), np.ascontiguousarray(n), float(eta), out, cos_t)
    return out, cos_t


def _transmittance(cos_i, eta):
    out = np.empty(len(cos_i))
    transmittances(np.ascontiguousarray(cos_i), float(eta), out)
    return out


def refracted_beams(planes, axis, eta):
    """The beams a directional light (unit direction of travel `axis`) makes inside a convex
    refractive shape (face planes P, 4): (faces, toward (B, 3) minus each beam's direction inside,
    irradiance (B,) per unit irradiance outside) for the faces the light meets from outside without
    total reflection, the irradiance T cos_i / cos_t of slab.beam_irradiance. A point inside is lit
    by face f's beam where its path back along `toward` leaves through f (media/convex_directional.py
    `only`)."""
    cos_i = -(planes[:, :3] @ axis)
    faces = np.nonzero(cos_i > 0.0)[0]
    t, cos_t = _refract(np.broadcast_to(axis, (len(faces), 3)).copy(), planes[faces, :3], eta)
    ok = cos_t > 0.0
    faces, t, cos_i, cos_t = faces[ok], t[ok], cos_i[faces[ok]], cos_t[ok]
    return faces, -t, _transmittance(cos_i, eta) * cos_i / cos_t


def single_scattering(prep, method, params, sid, points, normals, w, ell, keys, seed, depth, light=None, piece=0,
                      beam=None):
    """Inside single scattering (N, 3) at the entry points along the refracted rays w, over [0, ell],
    summed over the lights, for the interior `medium` with outward entry normals `normals`, its
    variance (N, 3) (0 but for the sampling integrator), its statistics (STATS_SIZE) and a bound
    (N, 3) on its error (inf where none is known). The method's inside integrator is its
    `Supports.interiors.mode`; in an index-matched shape the light's path inside is its exact
    straight path (convex: `convex_planes`; else traced, `_traced`) for the methods with
    `exact_paths`, else the note's entry plane (slab_approx). CLOSED (analytic, directional lights)
    in an index-matched shape: convex, at most MAX_FACES planes, the closed form of
    media/convex_directional.py with its bound; else the segments go to the adaptive quadrature
    (`_traced`, rtol RTOL), counted (HANDED), unbounded. Through a refractive boundary a directional
    light enters a convex shape (`convex_planes`) through every face it meets, one beam each
    (`refracted_beams`: the exact refracted path; CLOSED bounded as above), other shapes through the
    entry plane (eq. 5, unbounded), as does a point light (Fermat's path). `light`: that light only
    (else all); `piece`: the segments' rank among their ray's lit pieces (`lit_single_scattering`),
    which numbers their random streams; `beam`: of a directional light's refracted beams, only the
    one through that face (`lit_single_scattering`)."""
    medium = prep.scene.shapes[sid].interior
    planes = convex_planes(prep, sid)
    refractive = medium.ior != 1.0
    traced = not refractive and not len(planes)  # non-convex, index-matched: paths measured with Embree
    geo = np.zeros((len(points), GEO_COLUMNS))
    geo[:, :3], geo[:, 3:6], geo[:, 14:17] = points, w, normals
    lights = prep.lights
    n = len(points)
    out = np.zeros((n, 3))
    var = np.zeros((n, 3))
    sup = method.supports.interiors
    mode = sup.mode
    closed = mode == CLOSED and not refractive  # the exact closed form, or quadrature where there is none
    kernel = mode == CLOSED and 0 < len(planes) <= MAX_FACES  # exact and bounded (refractive: the beams)
    beams = refractive and len(planes) > 0 and mode != APPROX  # slab_approx keeps the note's plane
    bound = np.zeros((n, 3)) if kernel else np.full((n, 3), np.inf)
    rtol = params.get("rtol", RTOL)
    steps = int(params.get("steps", params.get("samples", 1)))
    tau_max = float(params.get("tau_max", 745.0))  # raymarch's cut of long segments
    stats = np.zeros(STATS_SIZE)
    a = -np.einsum("ij,ij->i", w, normals)
    dims = STREAM + piece * MAX_DEPTH * len(lights) * steps

    def integrate(li, distant, xh, h, hl, b, mu, wl, ll, scale, used, only=-1):
        for c in range(3):
            kt, ks = float(medium.sigma_t[c]), float(medium.sigma_s[c])
            if ks == 0.0 or lights.intensity[li, c] == 0.0:
                continue
            unit, unit_var = np.empty(n), np.empty(n)
            inside_radiance(distant, xh, h, hl, a, b, mu, ell, kt, ks, medium.phase, medium.g,
                            float(prep.scene.medium.sigma_t[c]), wl, ll, float(medium.ior), geo, used, only, mode,
                            rtol, steps, tau_max, keys,
                            np.uint64(dims + (depth * len(lights) + li) * steps + (only + 1) * STREAM), np.uint64(seed),
                            unit, unit_var, stats)
            f = scale * lights.intensity[li, c]
            out[:, c] += unit * f
            var[:, c] += unit_var * f * f

    def closed_form(li, toward, scale, only):
        val, b = np.empty((n, 3)), np.empty((n, 3))
        segments_bounded(np.ascontiguousarray(planes[:, :3]), np.ascontiguousarray(planes[:, 3]),
                         np.ascontiguousarray(points), np.ascontiguousarray(w), np.ascontiguousarray(ell),
                         np.ascontiguousarray(toward), medium.sigma_t, medium.sigma_s, medium.phase, medium.g, val, b,
                         only)
        out[:] += val * (lights.intensity[li] * scale)
        bound[:] += b * (lights.intensity[li] * scale)

    zero = np.zeros(n)
    for li in range(len(lights)) if light is None else [light]:
        idx = np.full(n, li, dtype=np.int64)
        distant = np.full(n, lights.kind[li] == DIRECTIONAL)
        if lights.kind[li] == DIRECTIONAL:
            geo[:, 9:12], geo[:, 12:14], geo[:, 17] = 0.0, lights.cone[li, :2], lights.cone[li, 2]
            if beams:
                for f, toward, irradiance in zip(*refracted_beams(planes, lights.axis[li], medium.ior)):
                    if beam is not None and f != beam:
                        continue
                    if kernel:
                        closed_form(li, toward, irradiance, int(f))
                        continue
                    geo[:, 6:9] = toward
                    integrate(li, distant, zero, zero, zero, zero, w @ toward, zero, zero, irradiance, planes, int(f))
                continue
            if kernel:
                closed_form(li, -lights.axis[li], 1.0, -1)
                continue
            geo[:, 6:9] = -lights.axis[li]
            axis = np.broadcast_to(lights.axis[li], (n, 3))
            cos_l = -(normals @ lights.axis[li])
            t_l, b = _refract(axis, normals, medium.ior)
            b = np.where(cos_l > 0.0, b, 0.0)
            mu = -np.einsum("ij,ij->i", t_l if refractive else axis, w)  # index-matched: not bent (_refract
            # would mirror the light off an entry face it meets from behind)
            scale = np.where(cos_l > 0.0, _transmittance(np.maximum(cos_l, 0.0), medium.ior) * np.maximum(cos_l, 0.0)
                             / np.maximum(b, 1e-300), 0.0) if refractive else 1.0
            if closed or (traced and sup.exact_paths):
                if closed:
                    stats[HANDED] += np.count_nonzero(ell > 0.0)
                _traced(prep, sid, medium, geo, True, ell, lights.intensity[li] * scale,
                        QUAD if closed else mode, rtol, steps, tau_max, keys, dims + (depth * len(lights) + li) * steps,
                        seed, out, var, stats)
                continue
            integrate(li, distant, zero, zero, zero, b, mu, zero, zero, scale, planes if not refractive else np.zeros((0, 4)))
            continue
        # a point or spot light (the spot's falloff toward the direction it leaves in: media/slab.py)
        xh, h, _, _ = segment_light_table(points, w, lights.position, lights.axis, lights.cone, idx, prep.accel.scale)
        geo[:, 6:9], geo[:, 9:12], geo[:, 12:14] = lights.position[li], lights.axis[li], lights.cone[li, :2]
        geo[:, 17] = lights.cone[li, 2]  # the spot's falloff curve
        rel = lights.position[li] - points
        hl = np.einsum("ij,ij->i", rel, normals)
        wl = ll = zero
        if refractive:  # horizontal parts, for the refracted path (media/slab.py refracted_point)
            lh = rel - hl[:, None] * normals
            wl = np.einsum("ij,ij->i", w + a[:, None] * normals, lh)
            ll = np.einsum("ij,ij->i", lh, lh)
        if closed or (traced and sup.exact_paths):
            if closed:
                stats[HANDED] += np.count_nonzero(ell > 0.0)
            _traced(prep, sid, medium, geo, False, ell, lights.intensity[li], QUAD if closed else mode, rtol, steps,
                    tau_max, keys, dims + (depth * len(lights) + li) * steps, seed, out, var, stats)
            continue
        integrate(li, distant, xh, h, hl, zero, zero, wl, ll, 1.0, planes if not refractive else np.zeros((0, 4)))
    return out, var, stats, bound


def lit_single_scattering(prep, method, params, sid, points, normals, w, ell, keys, seed, depth, shadows: bool):
    """`single_scattering` with volumetric shadows (`shadows`): over the pieces of each inside segment
    that each light reaches past the blockers (shadow_frusta.py's exact lit intervals of `blockers`;
    the shape's own boundary attenuates, it does not block), each piece integrated from its own
    start and carried back to the entry by exp(-sigma_t t0) (analytic's CLOSED too: its closed form
    and its quadrature fallback take the exact path from any start). Where the light's path is not
    straight (a refractive interior) or not traced (slab_approx: the note's planar model), the
    segments are unshadowed, counted (UNSHADOWED), and
    their bound is infinite if anything but the shape itself could stand on the light's path. Inside
    an index-matched shape the light is not attenuated by the other index-matched interiors on its
    path: with any other, the bound is infinite."""
    medium = prep.scene.shapes[sid].interior
    n, n_lights = len(points), len(prep.lights)
    if not shadows or not n or not n_lights:
        return single_scattering(prep, method, params, sid, points, normals, w, ell, keys, seed, depth)
    sup = method.supports.interiors
    if medium.ior != 1.0 and len(convex_planes(prep, sid)) and sup.mode != APPROX:
        return _lit_beams(prep, method, params, sid, points, normals, w, ell, keys, seed, depth)
    if medium.ior != 1.0 or not (sup.exact_paths or sup.mode == CLOSED):  # CLOSED: exact paths, directional lights
        out, var, stats, bound = single_scattering(prep, method, params, sid, points, normals, w, ell, keys, seed,
                                                   depth)
        stats[UNSHADOWED] += np.count_nonzero(ell > 0.0) * n_lights
        if np.any(prep.shape_ids != sid):
            bound = np.where(ell[:, None] > 0.0, np.inf, bound)
        return out, var, stats, bound
    rays = np.tile(np.arange(n), n_lights)
    segs = Segments(points[rays], w[rays], ell[rays], np.repeat(np.arange(n_lights), n), rays, np.zeros(len(rays)),
                    keys[rays], np.zeros(len(rays), np.int64), seed, prep.accel.scale)
    lit, _ = exact_lit_intervals(prep.accel, segs, prep.lights, n_lights, prep.frusta())
    out, var, bound = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
    stats = np.zeros(STATS_SIZE)
    stats[LIT_PIECES] += len(lit)
    piece = lit.stream // n_lights
    kt = medium.sigma_t[None, :]
    for li, rank in sorted(set(zip(lit.light.tolist(), piece.tolist()))):
        at = np.nonzero((lit.light == li) & (piece == rank))[0]
        r = lit.ray[at]
        val, v, st, b = single_scattering(prep, method, params, sid, lit.origins[at], normals[r], lit.dirs[at],
                                          lit.length[at], keys[r], seed, depth, li, rank)
        stats += st
        _carry(out, var, bound, r, kt, lit.t0[at], val, v, b)
    if len(matched(prep)) > 1:  # another index-matched interior may attenuate the light on its way in: not applied
        bound[ell > 0.0] = np.inf
    return out, var, stats, bound


def _carry(out, var, bound, r, kt, t0, val, v, b):
    """Add pieces' values, variances and bounds to their rays r, carried back to the entry by
    exp(-kt t0) (kt (1, 3))."""
    with np.errstate(over="ignore", invalid="ignore"):
        tr = np.where(kt == 0.0, 1.0, np.exp(-kt * t0[:, None]))
    np.add.at(out, r, tr * val)
    np.add.at(var, r, tr * tr * v)
    np.add.at(bound, r, scaled(b, tr))


def _lit_beams(prep, method, params, sid, points, normals, w, ell, keys, seed, depth):
    """`lit_single_scattering` in a convex refractive shape: each directional light's refracted beams
    over the pieces they reach past the blockers (beam_shadows.py: the leg inside the shape and the
    entry point's path outside), each from its own start, carried back by exp(-sigma_t t0); point and
    spot lights unshadowed (their refracted path is the entry plane's), counted, with an infinite bound
    if anything else stands in the scene. The other index-matched interiors on the light's way are not
    applied: with any, the bound is infinite."""
    medium, lights = prep.scene.shapes[sid].interior, prep.lights
    planes, mask = convex_planes(prep, sid), blockers(prep)
    n = len(points)
    out, var, bound = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
    stats = np.zeros(STATS_SIZE)
    kt = medium.sigma_t[None, :]

    for li in range(len(lights)):
        if lights.kind[li] != DIRECTIONAL:
            val, v, st, b = single_scattering(prep, method, params, sid, points, normals, w, ell, keys, seed, depth, li)
            st[UNSHADOWED] += np.count_nonzero(ell > 0.0)
            if np.any(prep.shape_ids != sid):
                b = np.where(ell[:, None] > 0.0, np.inf, b)
            stats += st
            _carry(out, var, bound, np.arange(n), kt, np.zeros(n), val, v, b)
            continue
        faces, towards, _ = refracted_beams(planes, lights.axis[li], medium.ior)
        for f, toward in zip(faces.tolist(), towards):
            src, x0, x1 = lit_pieces_of_beam(prep, sid, planes, mask, li, f, toward, points, w, ell)
            stats[LIT_PIECES] += len(src)
            rank = np.arange(len(src)) - np.searchsorted(src, src)
            for piece in np.unique(rank).tolist():
                at = np.nonzero(rank == piece)[0]
                r = src[at]
                val, v, st, b = single_scattering(prep, method, params, sid, points[r] + x0[at, None] * w[r],
                                                  normals[r], w[r], x1[at] - x0[at], keys[r], seed, depth, li, piece,
                                                  f)
                stats += st
                _carry(out, var, bound, r, kt, x0[at], val, v, b)
    if matched(prep):
        bound[ell > 0.0] = np.inf
    return out, var, stats, bound


def through_airlight(prep, segs: Segments, n_rays: int, stats):
    """The outside medium's air-light (N, 3) of the pieces `segs` whose light crosses index-matched
    interiors (shadow_frusta.split_lit's `behind`): the light attenuated by exp(-(sigma_t inside -
    sigma_t outside) x length inside) of each interior on its straight path, integrated by the
    traced adaptive quadrature (inside_paths.through_quadrature, rtol RTOL) whatever the method,
    counted (THROUGH; integrals short of their tolerance: THROUGH_CAPPED), carried to the camera
    by the outside's transmittance over t0."""
    inner = matched(prep)
    for sid in inner:
        hull_planes(prep, sid)  # fills the convex shapes' planes, which through_quadrature reads
    medium = prep.scene.medium
    kt_in = np.array([prep.scene.shapes[i].interior.sigma_t for i in inner])
    capped = np.zeros(1)
    values = inside_paths.through_quadrature(prep, segs, medium, inner, kt_in, RTOL, capped)
    stats[THROUGH] += len(segs)
    stats[THROUGH_CAPPED] += capped[0]
    return gather(segs, values, n_rays, medium)


def _traced(prep, sid, medium, geo, distant, ell, intensity, mode, rtol, steps, tau_max, keys, dim0, seed, out, var,
            stats):
    """out, var += one light's single scattering over the segments of an index-matched shape (non-convex,
    or handed over by CLOSED), the light's straight paths measured with Embree (inside_paths.py)."""
    ch = np.nonzero((medium.sigma_s > 0.0) & (intensity != 0.0))[0]
    if not len(ch):
        return
    kts, kss, kt_outs = medium.sigma_t[ch], medium.sigma_s[ch], prep.scene.medium.sigma_t[ch]
    args = (prep, sid, geo, distant, ell, kts, kss, medium.phase, medium.g, kt_outs)
    v = np.zeros((len(ell), len(ch)))
    if mode == QUAD:
        capped = np.zeros(1)
        val = inside_paths.segment_quadrature(*args, rtol, capped)
        stats[CAPPED] += capped[0]
    elif mode == MARCH:
        val = inside_paths.segment_march(*args, steps, tau_max)
    else:
        val, v = inside_paths.segment_samples(*args, steps, keys, dim0, seed)
    out[:, ch] += val * intensity[ch]
    var[:, ch] += v * intensity[ch] ** 2


def _surface_inside(prep, p, n, w, prim, ell, medium):
    """Radiance (M, 3) toward the entry points p (outward entry normals n) from the surface points
    q = p + ell w (triangles prim) inside the medium, times exp(-sigma_t ell) along the camera's path.
    Index-matched: the surface term, whose shadow rays leave through the medium with the interior's
    transmittance (`shadow_through`). Refractive: the note's planar boundary, the entry face's plane,
    for directional lights (point lights are refused by `check`): the beam refracted into t through
    it, irradiance E T cos_i / cos_t (eq. 5's E_in), attenuated over the path q - k t back to the plane,
    k = depth / cos_t; an opaque surface on that path shadows (the shape's own boundary does not:
    the plane is the model)."""
    accel = prep.accel
    q = p + ell[:, None] * w
    normals = facing_normals(accel.normals[prim], w)
    refl = prep.reflectance[prim]
    kt = medium.sigma_t[None, :]
    if medium.ior == 1.0:
        lb = surface_radiance(accel, q, normals, refl, prep.lights, prep.scene.medium, shadow_through(prep))
    else:
        lb = np.zeros((len(q), 3))
        lights = prep.lights
        for li in np.nonzero(lights.kind == DIRECTIONAL)[0]:
            axis = np.broadcast_to(lights.axis[li], q.shape)
            cos_i = -(n @ lights.axis[li])
            t, cos_t = _refract(axis, n, medium.ior)
            cos_s = -np.einsum("ij,ij->i", normals, t)
            ok = np.nonzero((cos_i > 0.0) & (cos_t > 0.0) & (cos_s > 0.0))[0]
            k = np.einsum("ij,ij->i", p[ok] - q[ok], n[ok]) / cos_t[ok]
            o = q[ok] + accel.epsilon * normals[ok]
            tb, hit = accel.first_hit(o, -t[ok])
            blocked = (hit >= 0) & (tb < k) & ~enters(prep, hit)
            ok, k = ok[~blocked], k[~blocked]
            e_in = _transmittance(cos_i[ok], medium.ior) * cos_i[ok] / cos_t[ok]
            with np.errstate(over="ignore", invalid="ignore"):
                att = np.where(kt == 0.0, 1.0, np.exp(-kt * k[:, None]))
            lb[ok] += refl[ok] / np.pi * lights.intensity[li] * (e_in * cos_s[ok])[:, None] * att
    with np.errstate(over="ignore", invalid="ignore"):
        return lb * np.where(kt == 0.0, 1.0, np.exp(-kt * ell[:, None]))


def from_inside(prep, method, params, origins, dirs, t, prim, keys, seed, shade, shadows=False):
    """Radiance (N, 3), variance and inside statistics (STATS_SIZE) of camera rays that start inside
    the index-matched shape prep.camera_inside and first meet its boundary or a surface at t (triangle prim): the inside
    single scattering over [0, t] (the light's exact straight paths), then what lies beyond the
    boundary (`shade(origins, dirs, keys, depth)`), or the surface met inside, times exp(-sigma_t t)."""
    sid = prep.camera_inside
    medium = prep.scene.shapes[sid].interior
    accel = prep.accel
    out, var, stats, _ = lit_single_scattering(prep, method, params, sid, origins, -dirs, dirs, t, keys, seed, 0,
                                               shadows)
    exits = np.nonzero((prim >= 0) & (prep.shape_ids[np.maximum(prim, 0)] == sid))[0]
    if len(exits):
        cos = np.abs(np.einsum("ij,ij->i", accel.normals[prim[exits]], dirs[exits]))
        q = origins[exits] + t[exits, None] * dirs[exits]
        start, gap = _leave(prep, q, dirs[exits], cos)
        seen, seen_var, _ = shade(start, dirs[exits], keys[exits], 1)
        with np.errstate(over="ignore", invalid="ignore"):
            tr = np.where(medium.sigma_t[None, :] == 0.0, 1.0,
                          np.exp(-medium.sigma_t[None, :] * t[exits, None])) * gap
        out[exits] += tr * seen
        if seen_var is not None:
            var[exits] += tr * tr * seen_var
    walls = np.nonzero((prim >= 0) & ~enters(prep, prim))[0]
    if len(walls):
        out[walls] += _surface_inside(prep, origins[walls], -dirs[walls], dirs[walls], prim[walls], t[walls], medium)
    return out, var, stats


def radiance(prep, method, params, origins, dirs, t, prim, keys, seed, depth, shade, shadows=False):
    """Radiance (N, 3) arriving back along rays that enter a shape with a medium at t (triangle prim):
    what the inside scatters toward them and what comes through from behind the exit, through the
    boundaries, its variance (N, 3), the inside integrals' statistics (STATS_SIZE; those of the
    rays `shade` follows are the renderer's) and a bound (N, 3) on its error (error_bounds.py: the
    inside's, `single_scattering`, plus what lies behind's; the float64 rounding of the closed forms
    here is the renderer's allowance on the whole). `shade(origins, dirs, keys, depth)` is the
    renderer's radiance, variance (or None) and bound of rays leaving a shape."""
    out = np.zeros((len(origins), 3))
    out_var = np.zeros_like(out)
    out_bound = np.zeros_like(out)
    stats = np.zeros(STATS_SIZE)
    if depth >= MAX_DEPTH:  # black by the model
        return out, out_var, stats, out_bound
    accel = prep.accel
    points = origins + t[:, None] * dirs
    normals = facing_normals(accel.normals[prim], dirs)
    shape = prep.shape_ids[prim]
    for sid in np.unique(shape):
        sel = np.nonzero(shape == sid)[0]
        medium = prep.scene.shapes[sid].interior
        eta = medium.ior
        d, nf, p = dirs[sel], normals[sel], points[sel]
        w, cos_t = _refract(d, nf, eta)
        t_in = _transmittance(-np.einsum("ij,ij->i", d, nf), eta) * (cos_t > 0.0)  # T, 0 on total reflection
        ell, prim2, touch = _inside_hits(prep, p, w, cos_t, prim[sel])
        inner, inner_var, inner_stats, bound = lit_single_scattering(prep, method, params, sid, p, nf, w, ell,
                                                                     keys[sel], seed, depth, shadows)
        stats += inner_stats
        exits = np.nonzero((prim2 >= 0) & (prep.shape_ids[np.maximum(prim2, 0)] == sid))[0]
        behind = np.zeros_like(inner)
        behind_var = np.zeros_like(inner)
        if len(exits):
            q = p[exits] + ell[exits, None] * w[exits]
            m = facing_normals(accel.normals[prim2[exits]], w[exits])
            w_out, cos_o = _refract(w[exits], m, 1.0 / eta)
            t_out = _transmittance(-np.einsum("ij,ij->i", w[exits], m), 1.0 / eta) * (cos_o > 0.0)
            start, gap = _leave(prep, q, w_out, cos_o)
            seen, seen_var, seen_bound = shade(start, w_out, keys[sel][exits], depth + 1)
            on, at = _met_at_once(prep, q, w_out, cos_o, touch[exits])
            rest = np.nonzero(on >= 0)[0]
            if len(rest):
                on = on[rest]
                seen[rest] = surface_radiance(accel, at[rest], facing_normals(accel.normals[on], w_out[rest]),
                                              prep.reflectance[on], prep.lights, prep.scene.medium,
                                              shadow_through(prep))
                gap[rest] = 1.0
                seen_bound[rest] = 0.0  # a float64 closed form
                if seen_var is not None:
                    seen_var[rest] = 0.0
            kt = medium.sigma_t[None, :]
            with np.errstate(over="ignore", invalid="ignore"):
                tr = np.where(kt == 0.0, 1.0, np.exp(-kt * ell[exits, None]))
            f = (t_out * eta * eta)[:, None] * tr * gap
            behind[exits] = f * seen
            bound[exits] += scaled(seen_bound, f)
            if seen_var is not None:
                behind_var[exits] = f * f * seen_var
        walls = np.nonzero((prim2 >= 0) & ~enters(prep, prim2))[0]  # a plain surface inside the medium
        if len(walls):
            behind[walls] = _surface_inside(prep, p[walls], nf[walls], w[walls], prim2[walls], ell[walls], medium)
        f = (t_in / (eta * eta))[:, None]
        out[sel] = f * (inner + behind)
        out_var[sel] = f * f * (inner_var + behind_var)
        out_bound[sel] = scaled(bound, f)
        if eta != 1.0:  # the boundary's mirror reflection, Fresnel's 1 - T (1 on total reflection)
            cos = -np.einsum("ij,ij->i", d, nf)
            mirrored = d + 2.0 * cos[:, None] * nf
            start, gap = _leave(prep, p, mirrored, cos)
            seen, seen_var, seen_bound = shade(start, mirrored, keys[sel], depth + 1)
            r = (1.0 - t_in)[:, None] * gap
            out[sel] += r * seen
            out_bound[sel] += scaled(seen_bound, r)
            if seen_var is not None:
                out_var[sel] += r * r * seen_var
    return out, out_var, stats, out_bound


def scaled(bound, f):
    """bound x f (f >= 0), inf where bound is inf (also where f = 0: nothing known was multiplied)."""
    out = np.full(np.broadcast_shapes(bound.shape, np.shape(f)), np.inf)
    np.multiply(bound, f, out=out, where=~np.isinf(bound))
    return out
