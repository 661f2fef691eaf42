"""Plain surfaces inside shapes that hold a medium, shaded where camera rays meet them there (`surface_inside`):
through an index-matched interior with its transmittance, through a refractive one on the lights' refracted paths
(every face of a convex shape, or the plane of the face the camera ray entered by)."""
from __future__ import annotations

import numpy as np

from ..media.slab import surface_through_faces
from ..shading import facing_normals, shading_normals, surface_radiance
from .fresnel import refract, refracted_beams, transmittance
from .shapes import enters, matched, nudge, refracting_planes, shadow_through


def surface_inside(prep, sid, p, n, w, prim, ell):
    """Radiance (M, 3) toward the row starts p from the surface points q = p + ell w (triangles prim)
    inside the medium of shape sid, times exp(-sigma_t ell) along the camera's path. Index-matched:
    the surface term, whose shadow rays leave through the medium with the interior's transmittance
    (`shadow_through`). Refractive, in a convex shape: point and spot lights through every face they are
    outside of (`_lit_through_faces`, `refracting_planes`); directional ones, in a convex shape (any
    number of planes), by the beam refracted through every face they meet, where q's path back
    along it leaves through that face (`refracted_beams`, `_lit_by_beam`); in another shape directional
    lights only (`check` refuses the rest) by the note's planar boundary, the entry face's plane
    (outward normals n): the beam refracted into t through it, irradiance E T cos_i / cos_t (eq. 5's
    E_in), attenuated over the path q - k t back to the plane, k = depth / cos_t. Opaque surfaces shadow on the
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
        for li in np.nonzero(~lights.distant)[0] if len(planes) else ():
            lb += _lit_through_faces(prep, sid, q, normals, shading, refl, planes, li, kt)
        for li in np.nonzero(lights.distant)[0]:
            if len(planes):
                beams = zip(*refracted_beams(planes, lights.axis[li], medium.ior))
            else:
                t, cos_t = refract(np.broadcast_to(lights.axis[li], q.shape), n, medium.ior)
                cos_i = -(n @ lights.axis[li])
                k = np.einsum("ij,ij->i", p - q, n) / np.where(cos_t > 0.0, cos_t, 1.0)
                e_in = np.where((cos_i > 0.0) & (cos_t > 0.0), transmittance(np.maximum(cos_i, 0.0), medium.ior)
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
    t, hit = prep.accel.first_hit(nudge(prep.accel, boundary, dirs, cos), dirs)
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
