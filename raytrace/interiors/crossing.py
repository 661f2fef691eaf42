"""Media inside shapes (after the analytic note on single scattering in homogeneous slabs): the
boundary crossing. Camera rays whose first hit is a shape holding an `interior` medium are taken
across its boundary (`cross`; a camera inside a shape: `start_inside`): refracted in
(Snell, smooth dielectric; straight when ior = 1) with Fresnel's transmittance T, followed inside to
their exit (Embree; `_inside_hits`), refracted out, and mirrored by a refractive boundary with 1 - T.
What comes of it is a `Crossing`: one inside `Segments` row per ray, which carries its medium (the
shape) and how light reaches it (`STRAIGHT` to a convex index-matched shape's faces, `TRACED` through
a non-convex one or an exact sphere (paths.py: Embree walks, or the sphere's closed-form chords in
media/slab.py's kernel), `REFRACTED` through a refractive boundary), the rays that go on beyond the exit or
the mirror, which the renderer shades like camera rays (up to MAX_DEPTH boundaries deep; deeper ones
are black), and the factors that carry what they see back (`combine`). The rows are integrated by
the method's inside rule (interiors/rows.py); a plain surface met inside is shaded here
(`_surface_inside`). Shadow rays pass through index-matched interiors (`shadow_through`).
Radiance crossing into a denser medium is multiplied by T eta^2 and back out by T / eta^2 (the
invariance of L / n^2, as pbrt-v4 and Mitsuba 3 scale it); reflections inside a shape are not
followed: total internal reflection at an exit ends the path.

Each method's `Supports.interiors` (methods/__init__.py) says how it integrates the inside rows and
what it takes there (`check` refuses the rest in one line): `quadrature` (adaptive, the reference),
`analytic` (directional lights only: the exact closed form in convex index-matched shapes of at most
MAX_FACES planes, with an error bound; the adaptive quadrature in other index-matched shapes, counted;
the refracted beams in convex refractive shapes, bounded; the adaptive quadrature in a refractive exact
sphere, counted; eq. 5 through other refractive boundaries),
`slab_approx` (eq. 5 and the note's separable approximation for point lights, not spots), `raymarch`
(its `steps` midpoints per inside row) and `montecarlo` (`samples` free-path samples per inside row
and light, whatever its --sampling; variance kept); `lecocq` and `sun` are refused for scenes with
interiors, in one line.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import UserError
from ..lights import Lights, is_spot
from ..media.adaptive import CAPPED
from ..media.inside_rule import QUAD
from ..media.slab import (GEO_COLUMNS, STREAM, out_of_faces, refract_rays, surface_out_of_faces,
                          surface_through_faces, transmittances)
from ..media.sphere_refraction import MAX_PATHS, UNBOUNDED, out_of_sphere, surface_out_of_sphere
from ..methods import INSIDE_RTOL, Segments, registry
from ..scene.meshes import convex_planes as hull_of
from ..shading import facing_normals, shading_normals, surface_radiance
from . import paths

# the inside integrals' statistics: media/adaptive.py's slots (EVALS, INTERVALS, CAPPED), the segments a method with
# closed forms (methods/ `Interiors.closed_forms`) hands to its rule (`single_scattering`); with volumetric shadows
# the inside segments rendered unshadowed (refractive or planar-model interiors: `lit_single_scattering`), the lit
# pieces of the others, and the outside air-light's pieces whose light crosses index-matched interiors
# (`through_airlight`) and those of their integrals that fell short of their tolerance; the segments of refractive
# exact spheres whose quadrature bound is infinite (media/sphere_refraction.py UNBOUNDED, which writes that slot
# itself), and the refracted point- and spot-light segments whose shadow breaks could not be located (their bound
# inf: rows.py `_lit_point`)
HANDED, UNSHADOWED, LIT_PIECES, THROUGH, THROUGH_CAPPED = range(3, 8)
SPHERE_UNBOUNDED = UNBOUNDED  # 8
UNLOCATED = 9
STATS_SIZE = 10
MAX_DEPTH = 4  # boundaries a camera path crosses into bounded media; deeper ones are black
RTOL = INSIDE_RTOL  # the inside quadrature's relative accuracy (`quadrature`: its own rtol)
STRAIGHT, TRACED, REFRACTED = range(3)  # how light reaches an inside row (`Segments.reach`)
# face planes of a convex shape up to which media/slab.py's kernel (every plane at every evaluation) is
# used; beyond, Embree's batched exits are faster (equal at ~120 planes: benchmarks/interiors_scale.py)
KERNEL_PLANES = 64


def summarize(prep, method, stats, shadows: bool = False) -> dict:
    """The render statistics of the inside integrals (`single_scattering`'s) in a scene with media
    inside shapes: the adaptive integrator's integrals that fell short of their tolerance (a piece
    accepted at a cap), as quadrature reports its own outside; for a method with closed forms also the
    segments (one per ray and light) it handed to its rule; nothing for the other inside rules, which
    have no caps, nor for the entry plane's model. With volumetric shadows also the inside segments rendered
    unshadowed, the lit pieces of the others, the outside pieces integrated through interiors, and the
    refracted segments whose shadow breaks were not located (shadows/fermat_legs.py: their bound is inf)."""
    sup = method.supports.interiors
    if prep.interior_shapes is None or not len(prep.interior_shapes) or sup is None:
        return {}
    out = {}
    if sup.kind == QUAD and not sup.entry_plane:
        out["inside: integrals not converged"] = int(stats[CAPPED])
        if stats[SPHERE_UNBOUNDED]:
            out["inside: refracted sphere segments unbounded"] = int(stats[SPHERE_UNBOUNDED])
    if sup.closed_forms:
        out["inside: segments handed to quadrature"] = int(stats[HANDED])
    if shadows:
        out.update({"inside: segments unshadowed (refractive or planar model)": int(stats[UNSHADOWED]),
                    "inside: lit pieces": int(stats[LIT_PIECES]),
                    f"shadows: pieces through interiors ({'quadrature' if sup.through == 'quadrature' else method.name})":
                        int(stats[THROUGH]),
                    "shadows: through-interior integrals not converged": int(stats[THROUGH_CAPPED]),
                    "inside: segments with shadow breaks not located (bound inf)": int(stats[UNLOCATED])})
    return out


def interiors(scene) -> list:
    """The interior medium of each shape (None for plain surfaces)."""
    return [s.interior for s in scene.shapes]


def outside_lights(prep):
    """The lights whose air-light outside the shapes a method must integrate: none when the scene has
    interior media and the outside does not scatter (then only interiors/crossing.py's kernels see them)."""
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


def check(prep, method, method_params, source: str, shadows: bool):
    """Refuse, in one line, what this first cut, or the method (its `Supports.interiors`), does not
    render in a scene with interior media (`shadows`: volumetric shadows on)."""
    inner = [i for i, m in enumerate(interiors(prep.scene)) if m is not None]
    if not inner:
        return
    key = f"shape[{inner[0]}].interior"
    sup = method.supports.interiors
    if sup is None:
        raise UserError(f"{source}: --method {method.name}: it does not integrate media inside shapes ({key}); use "
                        f"--method {', '.join(_takers())}")
    kinds = prep.lights.kinds()
    near = bool(np.any(~prep.lights.distant))  # rows with a position (point and spot lights, emitters' nodes)
    fixed = [k for k in sup.fixed if method_params.get(k, method.params[k].default) != method.params[k].default]
    if fixed:
        raise UserError(f"{source}: {' / '.join('--' + k.replace('_', '-') for k in fixed)} "
                        f"({', '.join('render.' + k for k in fixed)}): not implemented inside bounded media ({key}) "
                        f"yet; remove {'it' if len(fixed) == 1 else 'them'}")
    for kind in sorted(kinds - set(sup.lights)):
        takers = _takers(lambda s: kind in s.lights)
        why = f"{kind} lights into a bounded medium ({key})" + (f": {sup.limits}" if sup.limits else "")
        raise UserError(f"{source}: --method {method.name}: {why}; " + (
            f"use --method {', '.join(takers)}" if takers else
            "no method renders them yet (remove the shape's interior, or use point, spot or directional lights)"))
    if method.samples_shadows(method_params):
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
            takers = _takers(lambda s: kind in s.refracted)
            why = f": {sup.limits}" if kind in sup.lights and sup.limits else ""
            raise UserError(f"{source}: shape[{i}].interior.ior: --method {method.name}: {kind} lights through a "
                            f"refractive boundary{why}; use ior = 1" + (f", or --method {', '.join(takers)}" if takers else ""))
    if near:
        for i in inner:
            if prep.scene.shapes[i].interior.ior == 1.0 or len(refracting_planes(prep, i)):
                continue
            for j in range(len(prep.scene.shapes)):
                first = prep.accel.triangles[prep.shape_ids == j]
                if j != i and len(first) and inside_of(prep, first[0, 0], [i]) is not None:
                    raise UserError(f"{source}: shape[{j}]: lies inside shape[{i}], whose interior is refractive "
                                    f"(ior {prep.scene.shapes[i].interior.ior:g}) and not convex; surfaces inside "
                                    "such a medium are lit by directional lights only; use ior = 1, a convex shape "
                                    "or a directional light")
    inside = prep.camera_inside
    if inside is not None and (not sup.camera_inside or (prep.scene.shapes[inside].interior.ior != 1.0 and not len(
            refracting_planes(prep, inside)) and paths.exact_sphere(prep, inside) is None)):
        raise UserError(f"{source}: camera.position: inside shape[{inside}], which holds a medium; a camera inside a "
                        "bounded medium needs an index-matched interior (ior = 1), a convex shape or an exact sphere, "
                        f"and --method {', '.join(_takers(lambda s: s.camera_inside))}; move the camera out of the "
                        "shape or change them")
    for li in np.nonzero(~prep.lights.distant)[0]:
        inside = inside_of(prep, prep.lights.position[li], inner)
        if inside is not None and prep.lights.cubature[li]:
            raise UserError(f"{source}: light[{prep.lights.owner[li]}].position: inside shape[{inside}], which holds a "
                            "medium; an emitter inside a bounded medium is not implemented; move the light out of "
                            "the shape")
        why = _not_held(prep, inside, li, shadows) if inside is not None else None
        if why:
            raise UserError(f"{source}: light[{prep.lights.owner[li]}].position: inside shape[{inside}], which holds a "
                            f"medium of ior {prep.scene.shapes[inside].interior.ior:g}; a point or spot light inside "
                            f"a refractive medium {why}; move the light out of the shape or set its ior = 1")
        if inside is not None and sup.entry_plane:
            raise UserError(f"{source}: --method {method.name}: light[{prep.lights.owner[li]}].position inside "
                            f"shape[{inside}]: its inside model sees the light through the plane of the face a camera "
                            f"ray enters by; use --method {', '.join(_takers(lambda s: s.exact_paths))}")


def _not_held(prep, sid, li, shadows) -> str | None:
    """Why light li inside the interior of shape sid is refused, None where it is taken:
    index-matched, or a convex refractive mesh of at most KERNEL_PLANES faces or an exact sphere
    (`lit_from_inside`) with no other shape inside, the camera outside and no other shape holding a medium; in a
    scattering outside medium (`held_airlight`) a point or spot light in a convex mesh or a point light well inside
    an exact sphere (`_globe_fog`), and with volumetric shadows no other shape."""
    if prep.scene.shapes[sid].interior.ior == 1.0:
        return None
    sphere = paths.exact_sphere(prep, sid) is not None
    if not sphere and not len(convex_planes(prep, sid)):
        return f"needs a convex shape of at most {KERNEL_PLANES} faces or an exact sphere"
    if prep.scene.medium.scatters:  # lights the fog outside (`held_airlight`)
        why = _globe_fog(prep, sid, li) if sphere else None
        if why:
            return why
        if shadows and len(np.unique(prep.shape_ids)) > 1:
            return ("lights the scattering [medium] outside, where the other shapes' volumetric shadows on its "
                    "refracted light are not implemented yet; use --no-volumetric-shadows, or a [medium] that does "
                    "not scatter")
    if prep.camera_inside == sid:
        return "is not implemented with the camera inside the same shape yet"
    media = [int(j) for j in prep.interior_shapes if j != sid]
    if media:  # the light refracted out into another medium
        return f"is not implemented with another shape holding a medium (shape[{media[0]}]) yet"
    for j in range(len(prep.scene.shapes)):
        first = prep.accel.triangles[prep.shape_ids == j]
        if j != sid and len(first) and inside_of(prep, first[0, 0], [sid]) is not None:
            return f"is not implemented with another shape inside it (shape[{j}]) yet"
    return None


def _globe_fog(prep, sid, li) -> str | None:
    """Why point light li inside the refractive exact sphere sid is refused with a scattering outside medium (None
    where taken: ior > 1 and the light closer to the centre than radius / ior, where each point outside has one
    path, media/sphere_refraction.py `out_of_sphere`)."""
    sphere = paths.exact_sphere(prep, sid)
    centre, radius = sphere[:3], float(sphere[3])
    ior = prep.scene.shapes[sid].interior.ior
    if is_spot(prep.lights.cone[li, 1]):
        return ("as a spot in an exact sphere lights the scattering [medium] outside, where the cuts at its cone's "
                "refracted edges are not implemented yet; use a point light, or a [medium] that does not scatter")
    if ior < 1.0 or np.linalg.norm(prep.lights.position[li] - centre) >= radius / ior:
        return (f"in an exact sphere lights the scattering [medium] outside only from within radius / ior "
                f"({radius / ior:g}) of its centre, with ior > 1; beyond, the breaks where its paths out change (the "
                "critical angle's cones, the caustic) are not implemented yet; move the light closer to the centre, "
                "or use a [medium] that does not scatter")
    return None


def held_airlight(prep, method, params, segs: Segments, n_rays: int, depth: int):
    """The outside medium's air-light (N, 3) of the segments `segs` (whole camera rays) whose light lies inside a
    convex refractive shape or an exact sphere (`held_lights`), its variance (N, 3; 0 but for a stochastic rule)
    and bound (N, 3; inf where lit), and the other segments: the light refracted out through every face
    (media/slab.py `out_of_faces`, relative index 1 / ior) or out of an exact sphere (media/sphere_refraction.py
    `out_of_sphere`), integrated by the method's inside rule (`check` refuses volumetric shadows with another shape
    in the scene, and in an exact sphere a spot or a light beyond radius / ior of its centre)."""
    held = dict(held_lights(prep))
    mine = np.isin(segs.light, list(held))
    val, var, bound = np.zeros((n_rays, 3)), np.zeros((n_rays, 3)), np.zeros((n_rays, 3))
    medium, lights, sup = prep.scene.medium, prep.lights, method.supports.interiors
    rule = sup.rule(params)
    for li, sid in held.items():
        sel = np.nonzero((segs.light == li) & (prep.lights_on is None or prep.lights_on[li]))[0]
        ch = np.nonzero((medium.sigma_s != 0.0) & (lights.intensity[li] != 0.0))[0]
        if not len(sel) or not len(ch):
            continue
        planes = convex_planes(prep, sid)
        geo = np.zeros((len(sel), GEO_COLUMNS))
        geo[:, :3], geo[:, 3:6], geo[:, 6:9] = segs.origins[sel], segs.dirs[sel], lights.position[li]
        geo[:, 9:12], geo[:, 12:14], geo[:, 17] = lights.axis[li], lights.cone[li, :2], lights.cone[li, 2]
        out, v, err = (np.zeros((len(sel), len(ch))) for _ in range(3))
        inner = prep.scene.shapes[sid].interior
        dim0 = np.uint64((2 * KERNEL_PLANES + 2) * STREAM + (depth * len(lights) + li) * rule.steps)
        sphere = paths.exact_sphere(prep, sid)
        args = (np.ascontiguousarray(segs.length[sel]), medium.sigma_t[ch].astype(float),
                medium.sigma_s[ch].astype(float), medium.phase, medium.g, inner.sigma_t[ch].astype(float))
        rest = (rule, segs.keys[sel], dim0, np.uint64(segs.seed), out, v, err, np.zeros(STATS_SIZE))
        if sphere is None:
            out_of_faces(geo, planes, *args, 1.0 / inner.ior, *rest)
        else:
            out_of_sphere(geo, np.asarray(sphere, dtype=np.float64), *args, float(inner.ior), *rest)
        inten = lights.intensity[li, ch]
        for acc, part in ((val, out * inten), (var, v * inten * inten), (bound, err * inten)):
            whole = np.zeros((len(sel), 3))
            whole[:, ch] = part
            np.add.at(acc, segs.ray[sel], whole)
    return segs.take(np.nonzero(~mine)[0]), val, var, bound


def held_lights(prep) -> list[tuple[int, int]]:
    """(light, shape): the point and spot lights inside refractive interiors (`check` takes convex meshes' and
    exact spheres' alone), each with its shape."""
    def build():
        inner = [int(i) for i in prep.interior_shapes if prep.scene.shapes[i].interior.ior != 1.0]
        found = [(int(li), inside_of(prep, prep.lights.position[li], inner))
                 for li in np.nonzero(~prep.lights.distant)[0]]
        return [(li, sid) for li, sid in found if sid is not None]
    return [] if prep.interior_shapes is None else prep.memo("held lights", build)


def lit_from_inside(prep, q, normals, shading, refl):
    """rho / pi I E cos_s exp(-sigma_t k - sigma_out o) (M, 3) at surface points q outside the shapes from the
    point and spot lights inside refractive ones (`held_lights`; their straight shadow rays stop at the
    boundary, `blockers`) on each of their paths out (`_paths_out`): Fermat's path with Fresnel's T and the ray
    tube's irradiance E with the spot's falloff, k and o its lengths inside and outside. Opaque surfaces and
    other refractive interiors on the leg outside shadow (index-matched interiors there do not attenuate it, as
    `_outside_clear`)."""
    out = np.zeros((len(q), 3))
    lights, accel = prep.lights, prep.accel
    for li, sid in held_lights(prep):
        value, toward, inside, outside = _paths_out(prep, li, sid, q)
        kt = prep.scene.shapes[sid].interior.sigma_t[None, :]
        for f in range(value.shape[1]):
            u = toward[:, f]
            cos_s = np.einsum("ij,ij->i", shading, u)
            ok = np.nonzero((value[:, f] > 0.0) & (cos_s > 0.0) & (np.einsum("ij,ij->i", normals, u) > 0.0))[0]
            t, hit = accel.first_hit(q[ok] + accel.epsilon * normals[ok], u[ok])
            clear = np.isin(prep.shape_ids[np.maximum(hit, 0)], matched(prep) + [sid])
            ok = ok[(hit < 0) | (t >= outside[ok, f]) | clear]
            with np.errstate(over="ignore", invalid="ignore"):
                att = np.exp(-kt * inside[ok, f, None] - prep.scene.medium.sigma_t[None, :] * outside[ok, f, None])
            out[ok] += refl[ok] / np.pi * lights.intensity[li] * (value[ok, f] * cos_s[ok])[:, None] * att
    return out


def _paths_out(prep, li, sid, q):
    """(value, toward, inside, outside) of point or spot light li inside the refractive shape sid at the points q
    (M, 3) outside it, one column per path out (M, K; toward (M, K, 3)): through each face of a convex mesh
    (media/slab.py `surface_out_of_faces`), or each refracted path out of an exact sphere (media/sphere_refraction.py
    `surface_out_of_sphere`); value the irradiance across the ray per unit intensity (0: no path), toward the unit
    direction from q to where the path crosses the boundary, inside and outside its lengths."""
    lights, sphere = prep.lights, paths.exact_sphere(prep, sid)
    planes = convex_planes(prep, sid)
    m, k = len(q), MAX_PATHS if sphere is not None else len(planes)
    value, toward, inside, outside = np.zeros((m, k)), np.zeros((m, k, 3)), np.zeros((m, k)), np.zeros((m, k))
    rest = (lights.position[li], lights.axis[li], lights.cone[li], float(prep.scene.shapes[sid].interior.ior), value,
            toward, inside, outside)
    if sphere is None:
        surface_out_of_faces(np.ascontiguousarray(q), planes, *rest)
    else:
        surface_out_of_sphere(np.ascontiguousarray(q), np.asarray(sphere, dtype=np.float64), *rest)
    return value, toward, inside, outside


def _takers(test=lambda interiors: True) -> list[str]:
    """The methods that integrate media inside shapes and whose `Supports.interiors` passes `test`."""
    return [m.name for m in registry().values() if m.supports.interiors is not None and test(m.supports.interiors)]


def inside_of(prep, o, inner) -> int | None:
    """The first shape of `inner` that contains the point o (`paths.contains`), else None."""
    return next((i for i in inner if paths.contains(prep, o, i)), None)


def hull_planes(prep, sid):
    """The face planes (P, 4) of shape sid if it is convex (scene/meshes.py convex_planes), else
    None; cached on `prep` (paths.py reads the cache for index-matched shapes). An exact
    sphere has none: its light paths are its closed-form chords (paths.boundary, media/convex_chords.py),
    without facet kinks."""
    cache = prep.interior_planes
    if sid not in cache:
        sel = prep.shape_ids == sid
        exact = paths.exact_sphere(prep, sid) is not None
        cache[sid] = None if exact else hull_of(prep.accel.triangles[sel], prep.accel.normals[sel])
    return cache[sid]


def convex_planes(prep, sid):
    """The face planes (P, 4: outward unit normal, offset) of shape `sid` for media/slab.py's convex
    kernel, which tests every plane at every integrand evaluation: those of a convex shape with at
    most KERNEL_PLANES of them, else an empty (0, 4) array (then an index-matched shape's light paths
    are measured with Embree, paths.py: batched exits for convex shapes, walks for others; a
    refractive one's lights take `refracting_planes`)."""
    planes = hull_planes(prep, sid)
    return planes if planes is not None and len(planes) <= KERNEL_PLANES else np.zeros((0, 4))


def refracting_planes(prep, sid):
    """The face planes of a convex refractive shape sid, any number of them, else an empty (0, 4)
    array: point and spot lights reach its inside through every face they are outside of on Fermat's
    paths (media/slab.py `faces_point`), each segment's faces culled to those whose refraction point
    can lie on them (`reachable_faces`) and the planes those need; beyond KERNEL_PLANES planes a
    directional light through every face it meets, each beam over the interval its face's neighbours
    leave lit (interiors/rows.py `_face_beams`)."""
    planes = hull_planes(prep, sid)
    refractive = prep.scene.shapes[sid].interior.ior != 1.0
    return planes if planes is not None and refractive else np.zeros((0, 4))


def triangle_planes(tris, planes):
    """The triangles (T, 3, 3) of nonzero area among `tris`, their unit normals turned outward (away
    from the vertices' mean, inside a convex shape) and the row of `planes` (P, 4) each lies in: the
    nearest by normal and offset / size (a k-d tree, as scene/meshes.py convex_planes finds them)."""
    from scipy.spatial import cKDTree

    tris = np.asarray(tris, dtype=np.float64)
    cross = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    area = np.linalg.norm(cross, axis=1)
    tris, n = tris[area > 0.0], cross[area > 0.0] / area[area > 0.0, None]
    size = max(float(np.abs(tris).max(initial=0.0)), 1e-300)
    centre = tris.reshape(-1, 3).mean(axis=0) if len(tris) else np.zeros(3)
    n *= np.where(np.einsum("ij,ij->i", n, tris[:, 0] - centre) < 0.0, -1.0, 1.0)[:, None]
    if not len(tris) or not len(planes):
        return tris, n, np.zeros(len(tris), np.int64)
    keys = np.column_stack([n, np.einsum("ij,ij->i", n, tris[:, 0]) / size])
    return tris, n, cKDTree(np.column_stack([planes[:, :3], planes[:, 3] / size])).query(keys)[1].astype(np.int64)


def plane_neighbours(prep, sid):
    """For each face plane f of the convex shape sid (`hull_planes`), the other planes through a corner
    of its face, packed in one int64 array `near`: near[near[f]:near[f + 1]] (starts offset by P + 1);
    empty where the shape has none. They are the planes of the triangles that share a vertex (within
    1e-9 of the shape's size) with a triangle of plane f (a triangle lies in every plane within 1e-9 of
    its normal and offset / size: planes that differ by rounding alone share its corners). The face is
    its plane's points inside the planes of its edges, each through two of its corners: the face test
    needs these alone, and media/slab.py `reachable_faces` reads no other plane (a plane with fewer
    than three of them, which no face of a closed solid has, takes every plane)."""
    def build():
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components
        from scipy.spatial import cKDTree

        planes = hull_planes(prep, sid)
        if planes is None or not len(planes):
            return np.zeros(0, np.int64)
        tris, n, _ = triangle_planes(prep.accel.triangles[prep.shape_ids == sid], planes)
        pts = tris.reshape(-1, 3)
        size = max(float(np.abs(pts).max(initial=0.0)), 1e-300)
        keys = np.column_stack([n, np.einsum("ij,ij->i", n, tris[:, 0]) / size])
        tree = cKDTree(np.column_stack([planes[:, :3], planes[:, 3] / size]))
        lists = tree.query_ball_point(keys, 1e-9)  # every plane a triangle lies in (planes equal but for rounding)
        tri = np.repeat(np.arange(len(tris)), [len(ids) for ids in lists])
        plane = np.concatenate([np.asarray(ids, np.int64) for ids in lists] + [np.zeros(0, np.int64)])
        pairs = cKDTree(pts).query_pairs(1e-9 * size, output_type="ndarray")
        same = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(pts), len(pts)))
        corner = connected_components(same, directed=False)[1].reshape(-1, 3)
        touch = coo_matrix((np.ones(3 * len(tri)), (corner[tri].ravel(), np.repeat(plane, 3))),
                           shape=(corner.max() + 1, len(planes))).tocsr()
        touch.data[:] = 1.0
        adj = (touch.T @ touch).tolil()
        adj.setdiag(0.0)
        adj = adj.tocsr()
        adj.eliminate_zeros()
        lists = [np.sort(adj.indices[adj.indptr[f]:adj.indptr[f + 1]]) for f in range(len(planes))]
        every = np.arange(len(planes))
        lists = [every[every != f] if len(ids) < 3 else ids for f, ids in enumerate(lists)]
        starts = len(planes) + 1 + np.concatenate([[0], np.cumsum([len(ids) for ids in lists])])
        return np.concatenate([starts] + lists).astype(np.int64)
    return prep.memo(("plane neighbours", sid), build)


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
    would be a caustic, beyond single scattering). A light inside an interior: the path's length in it
    runs from the light."""
    inner = matched(prep)
    if not inner:
        return None
    kt = np.array([prep.scene.shapes[i].interior.sigma_t for i in inner]) - prep.scene.medium.sigma_t[None, :]
    lights = prep.lights

    def through(li, points):
        if lights.distant[li]:
            dirs = np.broadcast_to(-lights.axis[li], points.shape)
            dist = np.full(len(points), np.inf)
        else:
            rel = lights.position[li] - points
            dist = np.linalg.norm(rel, axis=1)
            dirs = rel / dist[:, None]
        holds = prep.memo(("holding light", li), lambda: np.array(
            [not lights.distant[li] and inside_of(prep, lights.position[li], [sid]) is not None for sid in inner]))
        lengths, blocked = paths.inside_lengths(prep, points, dirs, dist, inner, block=True, margin=prep.accel.epsilon,
                                                far_inside=np.broadcast_to(holds, (len(points), len(inner))))
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


def _skip(prep, cos):
    """The step (N,) past which the first hit of a ray leaving a shape (cosine `cos` to the face it
    leaves) is asked (`_nudge`'s), so that Embree does not report the face left; the ray itself goes on
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
    start = _nudge(accel, p, w, cos)
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


def _surface_inside(prep, sid, p, n, w, prim, ell):
    """Radiance (M, 3) toward the row starts p from the surface points q = p + ell w (triangles prim)
    inside the medium of shape sid, times exp(-sigma_t ell) along the camera's path. Index-matched:
    the surface term, whose shadow rays leave through the medium with the interior's transmittance
    (`shadow_through`). Refractive, in a convex shape: point and spot lights through every face they are
    outside of (`_lit_through_faces`, `refracting_planes`); directional ones, in a convex shape (any
    number of planes), by the beam refracted through every face they meet, where q's path back
    along it leaves through that face (`refracted_beams`, `_lit_by_beam`); in another shape directional
    lights only (`check` refuses the rest) by the note's planar boundary, the entry face's plane
    (outward normals n): the beam refracted into t through it, irradiance E T cos_i / cos_t (eq. 5's
    E_in), attenuated over the path q - k t back to the plane, k = depth / cos_t. Opaque surfaces shadow on the path inside and on the light's
    leg outside (`_outside_clear`)."""
    accel = prep.accel
    medium = prep.scene.shapes[sid].interior
    q = p + ell[:, None] * w
    normals = facing_normals(accel.hit_normals(prim, q), w)
    shading = shading_normals(accel, prep.corner_normals, prim, q, normals)
    refl = prep.reflectance[prim]
    kt = medium.sigma_t[None, :]
    if medium.ior == 1.0:
        lb = surface_radiance(accel, q, normals, refl, prep.lights, prep.scene.medium, shadow_through(prep), shading)
    else:
        lb = np.zeros((len(q), 3))
        lights = prep.lights
        planes = refracting_planes(prep, sid)
        for li in np.nonzero(~lights.distant)[0] if len(planes) else ():
            lb += _lit_through_faces(prep, sid, q, normals, shading, refl, planes, li, kt)
        for li in np.nonzero(lights.distant)[0]:
            if len(planes):
                beams = zip(*refracted_beams(planes, lights.axis[li], medium.ior))
            else:
                t, cos_t = _refract(np.broadcast_to(lights.axis[li], q.shape), n, medium.ior)
                cos_i = -(n @ lights.axis[li])
                k = np.einsum("ij,ij->i", p - q, n) / np.where(cos_t > 0.0, cos_t, 1.0)
                e_in = np.where((cos_i > 0.0) & (cos_t > 0.0), _transmittance(np.maximum(cos_i, 0.0), medium.ior)
                                * cos_i / np.where(cos_t > 0.0, cos_t, 1.0), 0.0)
                beams = [(-1, -t, e_in, k, n)]
            for beam in beams:
                lb += _lit_by_beam(prep, sid, q, normals, shading, refl, planes, lights.intensity[li], kt,
                                   lights.axis[li], *beam)
    with np.errstate(over="ignore", invalid="ignore"):
        return lb * np.where(kt == 0.0, 1.0, np.exp(-kt * ell[:, None]))


def _lit_through_faces(prep, sid, q, normals, shading, refl, planes, li, kt):
    """rho / pi I E cos_s exp(-sigma_t k - sigma_out o) (M, 3) at surface points q inside the convex
    refractive shape sid (face `planes`) from point or spot light li, through every face it is outside
    of: Fermat's path, Fresnel's T and the ray tube's irradiance E with the spot's falloff
    (media/slab.py `surface_through_faces`), k and o its lengths inside and outside. Opaque surfaces
    on the path inside shadow, and opaque surfaces and other refractive interiors on its straight leg
    outside (index-matched interiors there do not attenuate it)."""
    accel, lights = prep.accel, prep.lights
    m, nf = len(q), len(planes)
    value, toward, inside, outside = np.zeros((m, nf)), np.zeros((m, nf, 3)), np.zeros((m, nf)), np.zeros((m, nf))
    surface_through_faces(np.ascontiguousarray(q), planes, lights.position[li], lights.axis[li], lights.cone[li],
                          float(prep.scene.shapes[sid].interior.ior), value, toward, inside, outside)
    out = np.zeros((m, 3))
    for f in range(nf):
        u = toward[:, f]
        cos_s = np.einsum("ij,ij->i", shading, u)
        ok = np.nonzero((value[:, f] > 0.0) & (cos_s > 0.0) & (np.einsum("ij,ij->i", normals, u) > 0.0))[0]
        tb, hit = accel.first_hit(q[ok] + accel.epsilon * normals[ok], u[ok])
        ok = ok[~((hit >= 0) & (tb < inside[ok, f]) & ~enters(prep, hit))]
        boundary = q[ok] + inside[ok, f, None] * u[ok]
        leg = lights.position[li] - boundary
        dist = np.linalg.norm(leg, axis=1)
        leg /= np.maximum(dist, 1e-300)[:, None]
        ok = ok[_outside_clear(prep, sid, boundary, leg, dist, leg @ planes[f, :3])]
        with np.errstate(over="ignore", invalid="ignore"):
            att = np.exp(-kt * inside[ok, f, None] - prep.scene.medium.sigma_t[None, :] * outside[ok, f, None])
        out[ok] += refl[ok] / np.pi * lights.intensity[li] * (value[ok, f] * cos_s[ok])[:, None] * att
    return out


def _outside_clear(prep, sid, boundary, dirs, dist, cos):
    """Whether the light's straight legs outside shape sid, from the points `boundary` (M, 3) where it
    crosses in (cosine `cos` (M,) to the face) along the unit `dirs` (M, 3) toward the light for
    `dist` (M,; inf for a directional light), meet no opaque surface and no refractive interior but
    the shape's own (index-matched interiors let it through unattenuated)."""
    t, hit = prep.accel.first_hit(_nudge(prep.accel, boundary, dirs, cos), dirs)
    return (hit < 0) | (t >= dist) | np.isin(prep.shape_ids[np.maximum(hit, 0)], matched(prep) + [sid])


def _lit_by_beam(prep, sid, q, normals, shading, refl, planes, intensity, kt, axis, face, toward, e_in, k=None,
                 entry=None):
    """rho / pi E e_in cos_s exp(-sigma_t k) (M, 3) at surface points q inside the refractive shape sid
    from one refracted beam of a directional light (direction of travel `axis` outside): `toward` (3,)
    or (M, 3) minus its direction inside, `e_in` its irradiance per unit irradiance outside; a convex
    shape's face `face`: q lit where its path back along `toward` leaves through that face (k: the
    distance to it), else the beam through the entry planes (normals `entry`, the note's model) with
    its distances `k`. Opaque surfaces within k shadow, and so do opaque surfaces and other refractive
    interiors on the light's straight leg outside, from the boundary toward the light (index-matched
    interiors there do not attenuate it)."""
    accel = prep.accel
    toward = np.broadcast_to(toward, q.shape)
    if face >= 0:
        den = toward @ planes[:, :3].T
        with np.errstate(divide="ignore", invalid="ignore"):
            dist = np.where(den > 0.0, np.maximum((planes[None, :, 3] - q @ planes[:, :3].T) / den, 0.0), np.inf)
        k = dist.min(axis=1)
        through = dist.argmin(axis=1) == face
    else:
        through = np.ones(len(q), bool)
    e_in = np.broadcast_to(e_in, (len(q),))
    cos_s = np.einsum("ij,ij->i", shading, toward)
    facing = np.einsum("ij,ij->i", normals, toward) > 0.0  # the terminator: the geometric side faces the beam
    ok = np.nonzero(through & (e_in > 0.0) & (cos_s > 0.0) & facing)[0]
    tb, hit = accel.first_hit(q[ok] + accel.epsilon * normals[ok], toward[ok])
    blocked = (hit >= 0) & (tb < k[ok]) & ~enters(prep, hit)
    ok = ok[~blocked]
    boundary = q[ok] + k[ok, None] * toward[ok]  # where the light crossed into the shape
    cos_i = np.abs(np.broadcast_to(planes[face, :3] if face >= 0 else entry, q.shape)[ok] @ axis)
    ok = ok[_outside_clear(prep, sid, boundary, np.broadcast_to(-axis, boundary.shape), np.inf, cos_i)]
    out = np.zeros((len(q), 3))
    with np.errstate(over="ignore", invalid="ignore"):
        att = np.where(kt == 0.0, 1.0, np.exp(-kt * k[ok, None]))
    out[ok] = refl[ok] / np.pi * intensity * (e_in[ok] * cos_s[ok])[:, None] * att
    return out


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
    w, cos_t = _refract(d, nf, eta)
    t_in = _transmittance(-np.einsum("ij,ij->i", d, nf), eta) * (cos_t > 0.0)  # T, 0 on total reflection
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
        direct[walls] = _surface_inside(prep, sid, p[walls], nf[walls], w[walls], prim2[walls], ell[walls])
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
    w_out, cos_o = _refract(w, m, 1.0 / eta)
    t_out = _transmittance(-np.einsum("ij,ij->i", w, m), 1.0 / eta) * (cos_o > 0.0)
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
        direct[walls] = _surface_inside(prep, sid, origins[walls], normals[walls], dirs[walls], prim[walls], t[walls])
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
