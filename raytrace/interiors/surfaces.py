"""Plain surfaces inside shapes that hold a medium, shaded where camera rays meet them there (`surface_inside`):
through an index-matched interior with its transmittance, through a refractive one on the lights' refracted paths
(every face of a convex shape, every triangle of one that is not convex; in an exact sphere a point or spot light's
exact paths, a directional light through the plane of the face the camera ray entered by)."""
from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from ..lights import falloff
from ..media.nonconvex_directional import lit_pieces
from ..media.nonconvex_refraction import PATH_COLUMNS, face_paths, every
from ..media.phase import ISOTROPIC
from ..media.slab import GEO_COLUMNS, fresnel, surface_through_faces
from ..media.sphere_refraction import MAX_PATHS, U, Outward, about_axis, frame, path_to, paths as sphere_paths
from ..shading import facing_normals, shading_normals, surface_radiance
from . import paths
from .fresnel import refract, refracted_beams, transmittance
from .shapes import enters, matched, nudge, refracting_planes, shadow_through


def surface_inside(prep, sid, p, n, w, prim, ell):
    """Radiance (M, 3) toward the row starts p from the surface points q = p + ell w (triangles prim)
    inside the medium of shape sid, times exp(-sigma_t ell) along the camera's path. Index-matched:
    the surface term, whose shadow rays leave through the medium with the interior's transmittance
    (`shadow_through`). Refractive, in a convex shape: point and spot lights through every face they are
    outside of (`_lit_through_faces`, `refracting_planes`); directional ones (any number of planes) by the
    beam refracted through every face they meet, where q's path back along it leaves through that face
    (`_convex_beams`, `_lit_by_beam`). In a triangle mesh that is not convex: point and spot lights on
    Fermat's path through every triangle whose legs are clear (`_lit_through_triangles`); directional ones
    by every triangle's beam where q's path back leaves through that triangle and both legs are clear
    (`_triangle_beams`). In an exact sphere point and spot lights on their exact refracted paths
    (`_lit_into_sphere`), directional ones by the note's planar boundary, the entry face's plane (outward
    normals n): the beam refracted into t through it, irradiance E T cos_i / cos_t (eq. 5's E_in),
    attenuated over the path q - k t back to the plane, k = depth / cos_t. Opaque surfaces shadow on the
    path inside and on the light's leg outside (`_outside_clear`)."""
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
        meshed = not len(planes) and paths.exact_sphere(prep, sid) is None  # not convex: every triangle
        for li in np.nonzero(~lights.distant)[0]:
            if len(planes):
                lb += _lit_through_faces(prep, sid, q, normals, shading, refl, planes, li, kt)
            elif meshed:
                lb += _lit_through_triangles(prep, sid, q, normals, shading, refl, li, kt)
            else:
                lb += _lit_into_sphere(prep, sid, q, normals, shading, refl, li, kt)
        for li in np.nonzero(lights.distant)[0]:
            axis = lights.axis[li]
            if len(planes):
                beams = _convex_beams(planes, q, axis, medium.ior)
            elif meshed:
                beams = _triangle_beams(prep, sid, q, axis, medium.ior)
            else:
                t, cos_t = refract(np.broadcast_to(axis, q.shape), n, medium.ior)
                cos_i = -(n @ axis)
                k = np.einsum("ij,ij->i", p - q, n) / np.where(cos_t > 0.0, cos_t, 1.0)
                e_in = np.where((cos_i > 0.0) & (cos_t > 0.0), transmittance(np.maximum(cos_i, 0.0), medium.ior)
                                * cos_i / np.where(cos_t > 0.0, cos_t, 1.0), 0.0)
                beams = [(np.ones(len(q), bool), -t, e_in, k, n)]
            for beam in beams:
                lb += _lit_by_beam(prep, sid, q, normals, shading, refl, lights.intensity[li], kt, axis, *beam)
    with np.errstate(over="ignore", invalid="ignore"):
        return lb * np.where(kt == 0.0, 1.0, np.exp(-kt * ell[:, None]))


def _lit_through_faces(prep, sid, q, normals, shading, refl, planes, li, kt):
    """rho / pi I E cos_s exp(-sigma_t k - sigma_out o) (M, 3) at surface points q inside the convex
    refractive shape sid (face `planes`) from point or spot light li, through every face it is outside
    of: Fermat's path, Fresnel's T and the ray tube's irradiance E with the spot's falloff
    (media/slab.py `surface_through_faces`), k and o its lengths inside and outside, shadowed as
    `_along_paths` says."""
    lights = prep.lights
    m, nf = len(q), len(planes)
    value, toward, inside, outside = np.zeros((m, nf)), np.zeros((m, nf, 3)), np.zeros((m, nf)), np.zeros((m, nf))
    surface_through_faces(np.ascontiguousarray(q), planes, lights.position[li], lights.axis[li], lights.cone[li],
                          float(prep.scene.shapes[sid].interior.ior), value, toward, inside, outside)
    out = np.zeros((m, 3))
    every_point = np.arange(m)
    for f in range(nf):
        u = toward[:, f]
        out += _along_paths(prep, sid, q, normals, shading, refl, li, kt, every_point, u, value[:, f], inside[:, f],
                            outside[:, f], q + inside[:, f, None] * u, planes[f, :3])
    return out


def _lit_through_triangles(prep, sid, q, normals, shading, refl, li, kt):
    """rho / pi I E cos_s exp(-sigma_t k - sigma_out o) (M, 3) at surface points q inside the refractive shape
    sid that is not convex from point or spot light li, summed over its triangles: Fermat's path through each
    triangle whose refraction point lies on it (media/nonconvex_refraction.py `face_paths` at the points: its
    value per unit light with an isotropic phase, times 4 pi, is Fresnel's T times the ray tube's irradiance E
    times the spot's falloff) and whose legs are clear of the shape (paths.clear_legs, as the air-light's
    paths.refracted_paths), shadowed as `_along_paths` says."""
    own, tris, planes = paths.shape_faces(prep, sid)
    lights = prep.lights
    m = len(q)
    geo = np.zeros((m, GEO_COLUMNS))  # each point a segment's start; its direction enters the phase alone
    geo[:, :3], geo[:, 3], geo[:, 6:9], geo[:, 9:12] = q, 1.0, lights.position[li], lights.axis[li]
    geo[:, 12:14], geo[:, 17] = lights.cone[li, :2], lights.cone[li, 2]
    starts, stops, faces = every(len(tris))
    eta = float(prep.scene.shapes[sid].interior.ior)
    step = max(1, paths.PATH_CHUNK // max(len(tris), 1))
    found = [np.zeros((0, PATH_COLUMNS))]
    for lo in range(0, m, step):
        seg = np.arange(lo, min(lo + step, m), dtype=np.int64)
        rows = np.empty((len(seg) * len(tris), PATH_COLUMNS))
        count = face_paths(seg, np.zeros(len(seg), np.int64), np.zeros(len(seg)), geo, tris, planes, starts, stops,
                           faces, eta, ISOTROPIC, 0.0, rows)
        rows[:count, 0] += lo
        found.append(rows[:count])
    rows = np.concatenate(found)
    pt, face = rows[:, 0].astype(np.int64), rows[:, 1].astype(np.int64)
    clear = paths.clear_legs(own, prep.accel.scale, q[pt], rows[:, 2:5], geo[pt, 6:9], face, rows[:, 8], rows[:, 9])
    pt, face, rows = pt[clear], face[clear], rows[clear]
    k = rows[:, 6]
    u = (rows[:, 2:5] - q[pt]) / np.maximum(k, 1e-300)[:, None]
    return _along_paths(prep, sid, q, normals, shading, refl, li, kt, pt, u, 4.0 * np.pi * rows[:, 5], k, rows[:, 7],
                        rows[:, 2:5], planes[face, :3])


def _lit_into_sphere(prep, sid, q, normals, shading, refl, li, kt):
    """rho / pi I E cos_s exp(-sigma_t k - sigma_out o) (M, 3) at surface points q inside the refractive exact
    sphere sid from point or spot light li outside it, summed over its refracted paths in (`_into_sphere`: the
    air-light's paths, media/sphere_refraction.py), shadowed as `_along_paths` says; none from a light inside
    the sphere (support.py `check` refuses a shape inside the sphere with it)."""
    sphere = np.asarray(paths.exact_sphere(prep, sid), dtype=np.float64)
    lights, m = prep.lights, len(q)
    value, inside, outside = np.zeros((m, MAX_PATHS)), np.zeros((m, MAX_PATHS)), np.zeros((m, MAX_PATHS))
    toward, boundary = np.zeros((m, MAX_PATHS, 3)), np.zeros((m, MAX_PATHS, 3))
    _into_sphere(np.ascontiguousarray(q, dtype=np.float64), sphere, lights.position[li], lights.axis[li],
                 lights.cone[li], float(prep.scene.shapes[sid].interior.ior), value, toward, inside, outside, boundary)
    pt, k = np.nonzero(value > 0.0)
    return _along_paths(prep, sid, q, normals, shading, refl, li, kt, pt, toward[pt, k], value[pt, k], inside[pt, k],
                        outside[pt, k], boundary[pt, k], (boundary[pt, k] - sphere[:3]) / sphere[3])


@njit
def _into_sphere(q, sphere, light, axis, cone, eta, value, toward, inside, outside, boundary):
    """A unit point or spot light outside the refractive exact sphere (centre, radius; relative index eta inside)
    at the points q (M, 3) inside it, through each of its refracted paths in (up to MAX_PATHS, the columns; value 0:
    no path): media/sphere_refraction.py `paths` in the plane of the light's axis and the point, proven there. Per
    path (`incidence`: P the refraction point, the cosines there, the leg outside o = |P - L|, the unit t inside,
    the leg inside s = |q - P|) value the irradiance across the ray at q, F T cos_i / (o^2 cos_t |(1 - s kappa_t)
    (1 - s kappa_s)|) (the module docstring's ray tube, Coddington's curvatures) with the spot's falloff F toward
    (P - L) / o, toward = -t, inside s, outside o and boundary P. None from a light within the sphere."""
    c, radius = sphere[:3], sphere[3]
    value[:] = 0.0
    ez, d, theta_a, cells = frame(sphere, light, False, eta)
    if not d > radius:
        return
    scan = Outward(radius, d, eta, theta_a, cells)  # `paths`' light and sphere: the light on the axis at d
    found, spread = np.empty(MAX_PATHS), np.empty(MAX_PATHS)
    for i in range(q.shape[0]):
        zx, yx, ey = about_axis(q[i] - c, ez)
        dx = 16.0 * U * (math.sqrt(zx * zx + yx * yx) + 2.0 * radius + d)  # q's plane coordinates' rounding
        m, _ = sphere_paths(scan, zx, yx, dx, found, spread)
        for k in range(m):
            pz, py, tz, ty, cos_i, cos_t, o, s, tube = path_to(found[k], zx, yx, radius, d, eta)
            if math.isnan(tube):
                continue
            c_spot = 0.0
            for j in range(3):
                boundary[i, k, j] = c[j] + pz * ez[j] + py * ey[j]
                toward[i, k, j] = -(tz * ez[j] + ty * ey[j])
                c_spot += (boundary[i, k, j] - light[j]) * axis[j]
            f = falloff(c_spot / o, cone[0], cone[1], int(cone[2]))
            if f == 0.0 or not tube > 0.0:
                continue
            value[i, k] = f * (1.0 - fresnel(cos_i, eta)) * cos_i / (o * o * cos_t * tube)
            inside[i, k], outside[i, k] = s, o


def _along_paths(prep, sid, q, normals, shading, refl, li, kt, pt, u, value, k, o, boundary, normal):
    """rho / pi I value cos_s exp(-sigma_t k - sigma_out o) (M, 3) at the surface points q from point or spot
    light li, summed over its refracted paths: path i reaches q[pt[i]] along the unit u[i] from the boundary
    point boundary[i] (the face's normal normal[i] or (3,)), value[i] its irradiance per unit intensity, k[i]
    and o[i] its lengths inside and outside. Opaque surfaces on the path inside shadow, and opaque surfaces and
    other refractive interiors on its straight leg outside (index-matched interiors there do not attenuate
    it); the geometric side must face u (the terminator)."""
    accel, lights = prep.accel, prep.lights
    cos_s = np.einsum("ij,ij->i", shading[pt], u)
    ok = np.nonzero((value > 0.0) & (cos_s > 0.0) & (np.einsum("ij,ij->i", normals[pt], u) > 0.0))[0]
    tb, hit = accel.first_hit(q[pt[ok]] + accel.epsilon * normals[pt[ok]], u[ok])
    ok = ok[~((hit >= 0) & (tb < k[ok]) & ~enters(prep, hit))]
    leg = lights.position[li] - boundary[ok]
    dist = np.linalg.norm(leg, axis=1)
    leg /= np.maximum(dist, 1e-300)[:, None]
    cos = np.abs(np.einsum("ij,ij->i", leg, np.broadcast_to(normal, boundary.shape)[ok]))
    ok = ok[_outside_clear(prep, sid, boundary[ok], leg, dist, cos)]
    with np.errstate(over="ignore", invalid="ignore"):
        att = np.exp(-kt * k[ok, None] - prep.scene.medium.sigma_t[None, :] * o[ok, None])
    out = np.zeros((len(q), 3))
    np.add.at(out, pt[ok], refl[pt[ok]] / np.pi * lights.intensity[li] * (value[ok] * cos_s[ok])[:, None] * att)
    return out


def _outside_clear(prep, sid, boundary, dirs, dist, cos):
    """Whether the light's straight legs outside shape sid, from the points `boundary` (M, 3) where it
    crosses in (cosine `cos` (M,) to the face) along the unit `dirs` (M, 3) toward the light for
    `dist` (M,; inf for a directional light), meet no opaque surface and no refractive interior but
    the shape's own (index-matched interiors let it through unattenuated)."""
    t, hit = prep.accel.first_hit(nudge(prep.accel, boundary, dirs, cos), dirs)
    return (hit < 0) | (t >= dist) | np.isin(prep.shape_ids[np.maximum(hit, 0)], matched(prep) + [sid])


def _convex_beams(planes, q, axis, eta):
    """`_lit_by_beam`'s beams (lit, toward, e_in, k, entry) of a directional light (direction of travel `axis`)
    in the convex refractive shape of face `planes`: each face's (`refracted_beams`), lighting q where its path
    back along `toward` leaves through that face (k: the distance to it, entry its normal)."""
    for face, toward, e_in in zip(*refracted_beams(planes, axis, eta)):
        toward = np.broadcast_to(toward, q.shape)
        den = toward @ planes[:, :3].T
        with np.errstate(divide="ignore", invalid="ignore"):
            dist = np.where(den > 0.0, np.maximum((planes[None, :, 3] - q @ planes[:, :3].T) / den, 0.0), np.inf)
        yield dist.argmin(axis=1) == face, toward, e_in, dist.min(axis=1), planes[face, :3]


def _triangle_beams(prep, sid, q, axis, eta):
    """`_lit_by_beam`'s beams of a directional light in the refractive shape sid that is not convex: each
    triangle's (`refracted_beams` of its plane turned toward the light), lighting q where its path back leaves
    through that triangle and both legs are clear of the shape (media/nonconvex_directional.py `lit_pieces`, the
    air-light's test, on the points as segments of zero direction over [0, 1]); k: the distance to the triangle's
    plane, entry its normal."""
    _, tris, planes = paths.shape_faces(prep, sid)
    turned = planes * np.where(planes[:, :3] @ axis > 0.0, -1.0, 1.0)[:, None]  # normals toward the light
    faces, towards, scales = refracted_beams(turned, axis, eta)
    q = np.ascontiguousarray(q, dtype=np.float64)
    (beam, src, _, _), _ = lit_pieces(tris, planes, np.zeros((len(tris), 4)), faces, towards, np.zeros(len(faces)),
                                      axis, q, np.zeros_like(q), np.ones(len(q)), bounded=False)  # no errors: no spans
    for i in np.unique(beam).tolist():
        n, toward = turned[faces[i]], towards[i]
        lit = np.zeros(len(q), bool)
        lit[src[beam == i]] = True
        yield lit, toward, scales[i], (n[3] - q @ n[:3]) / (n[:3] @ toward), n[:3]


def _lit_by_beam(prep, sid, q, normals, shading, refl, intensity, kt, axis, lit, toward, e_in, k, entry):
    """rho / pi E e_in cos_s exp(-sigma_t k) (M, 3) at surface points q inside the refractive shape sid
    from one refracted beam of a directional light (direction of travel `axis` outside): `toward` (3,)
    or (M, 3) minus its direction inside, `e_in` its irradiance per unit irradiance outside, lighting the
    points `lit` (M,) over the distances k (M,) back to the boundary it crossed in (normal `entry`, (3,) or
    (M, 3)). Opaque surfaces within k shadow, and so do opaque surfaces and other refractive
    interiors on the light's straight leg outside, from the boundary toward the light (index-matched
    interiors there do not attenuate it)."""
    accel = prep.accel
    toward = np.broadcast_to(toward, q.shape)
    e_in = np.broadcast_to(e_in, (len(q),))
    cos_s = np.einsum("ij,ij->i", shading, toward)
    facing = np.einsum("ij,ij->i", normals, toward) > 0.0  # the terminator: the geometric side faces the beam
    ok = np.nonzero(lit & (e_in > 0.0) & (cos_s > 0.0) & facing)[0]
    tb, hit = accel.first_hit(q[ok] + accel.epsilon * normals[ok], toward[ok])
    blocked = (hit >= 0) & (tb < k[ok]) & ~enters(prep, hit)
    ok = ok[~blocked]
    boundary = q[ok] + k[ok, None] * toward[ok]  # where the light crossed into the shape
    cos_i = np.abs(np.broadcast_to(entry, q.shape)[ok] @ axis)
    ok = ok[_outside_clear(prep, sid, boundary, np.broadcast_to(-axis, boundary.shape), np.inf, cos_i)]
    out = np.zeros((len(q), 3))
    with np.errstate(over="ignore", invalid="ignore"):
        att = np.where(kt == 0.0, 1.0, np.exp(-kt * k[ok, None]))
    out[ok] = refl[ok] / np.pi * intensity * (e_in[ok] * cos_s[ok])[:, None] * att
    return out
