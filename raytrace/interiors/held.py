"""Point and spot lights inside refractive shapes (a convex mesh of at most KERNEL_PLANES faces or an exact sphere;
support.py `check` refuses the rest): which they are (`held_lights`), the scattering outside medium they light
through the boundary (`held_airlight`) and the surfaces outside they light (`lit_from_inside`), on each of their
paths out (Fermat's path, Fresnel's T, the ray tube's irradiance: media/slab.py, media/sphere_refraction.py)."""
from __future__ import annotations

import numpy as np

from ..media.globe_shadows import patches, shadow_pieces
from ..media.mesh_lamp_shadows import face_pieces
from ..media.slab import GEO_COLUMNS, STREAM, out_of_faces, surface_out_of_faces
from ..media.sphere_refraction import MAX_PATHS, out_of_sphere, surface_out_of_sphere
from ..methods import Segments
from . import paths
from .shapes import KERNEL_PLANES, blockers, convex_planes, inside_of, matched, measured_plane_errors
from .support import STATS_SIZE


def held_airlight(prep, method, params, segs: Segments, n_rays: int, depth: int, shadows: bool):
    """The segments of `segs` (whole camera rays) whose light is not held in a refractive shape, and of the others
    (`held_lights`: inside a convex refractive mesh or an exact sphere) the outside medium's air-light (N, 3), its
    variance (N, 3; 0 but for a stochastic rule), bound (N, 3; quadrature's, else inf where lit) and the kernels'
    statistics (STATS_SIZE, support.py's slots: the exact sphere's unbounded segments): the light refracted out
    through every face of a convex mesh (media/slab.py `out_of_faces`, relative index 1 / ior) or out of an exact
    sphere (media/sphere_refraction.py `out_of_sphere`), with volumetric shadows on the pieces that other shapes'
    triangles leave lit (`occluders`; media/mesh_lamp_shadows.py per face, media/globe_shadows.py for the sphere),
    integrated by the method's inside rule (`check` refuses a shape reaching into the lamp's shape, and in an exact
    sphere a light beyond radius / ior of its centre)."""
    held = dict(held_lights(prep))
    mine = np.isin(segs.light, list(held))
    val, var, bound = np.zeros((n_rays, 3)), np.zeros((n_rays, 3)), np.zeros((n_rays, 3))
    medium, lights, sup = prep.scene.medium, prep.lights, method.supports.interiors
    rule = sup.rule(params)
    stats = np.zeros(STATS_SIZE)
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
        rest = (rule, segs.keys[sel], dim0, np.uint64(segs.seed), out, v, err, stats)
        near = occluders(prep, sid) if shadows else patches(np.zeros((0, 3, 3)), np.zeros(0))
        with np.errstate(divide="ignore"):  # where `out_of_faces` and `out_of_sphere` stop integrating
            reach = np.minimum(args[0], 745.0 / args[1].min())
        if sphere is None:
            lit = (face_pieces(geo, planes, reach, 1.0 / inner.ior, _ball(prep, sid), *near),) if len(near[0]) else ()
            out_of_faces(geo, planes, *args, 1.0 / inner.ior, *rest, measured_plane_errors(prep, sid), *lit)
        else:
            ball = np.asarray(sphere, dtype=np.float64)
            out_of_sphere(geo, ball, *args, float(inner.ior), *rest,
                          *shadow_pieces(geo, ball, reach, float(inner.ior), *near))
        inten = lights.intensity[li, ch]
        for acc, part in ((val, out * inten), (var, v * inten * inten), (bound, err * inten)):
            whole = np.zeros((len(sel), 3))
            whole[:, ch] = part
            np.add.at(acc, segs.ray[sel], whole)
    return segs.take(np.nonzero(~mine)[0]), val, var, bound, stats


def _ball(prep, sid):
    """(centre, radius) (4,) of a ball holding shape sid's triangles."""
    corners = prep.accel.triangles[prep.shape_ids == sid].reshape(-1, 3).astype(np.float64)
    centre = 0.5 * (corners.min(axis=0) + corners.max(axis=0))
    return np.append(centre, np.linalg.norm(corners - centre, axis=1).max() * (1.0 + 1e-12))


def occluders(prep, sid):
    """The triangles that shadow the light refracted out of shape sid (`blockers` but sid's own) in planar patches
    (media/globe_shadows.py `patches`)."""
    def build():
        mask = prep.shape_ids != sid
        stop = blockers(prep)
        mask = mask if stop is None else mask & stop
        return patches(prep.accel.triangles[mask].astype(np.float64), prep.shape_ids[mask])
    return prep.memo(("occluders", sid), build)


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
    surfaces.py `_outside_clear`)."""
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
