"""The surface term (paper eq. 5) with shadow-ray visibility, summed over lights.

Lb = sum_lights V (rho / pi) I F T / d^2 max(0, n·wi), with the geometric normal flipped to face
the incoming ray (two-sided Lambertian surfaces), F a spot light's falloff toward the point
(lights.py, 1 for point lights) and T the medium's transmittance from the point to the light
(exp(-kt d) when homogeneous, the closed-form optical depth in a height fog). A directional light
gives V (rho / pi) E T max(0, n·wi) with wi against its direction of travel and T the
transmittance to infinity toward it (seed 004, eq. 34 with t1 = inf). The camera sees Lb
attenuated by its own transmittance; that factor is applied by the renderer. An atmosphere's
planet (media/atmosphere.py) is a sphere the medium intersects in float64 (`planet_hits`), a diffuse
ground of the medium's reflectance (`ground_radiance`); its shadow is in the transmittance (0 to a
light behind it).
"""
from __future__ import annotations

import math

import numpy as np

from .lights import DIRECTIONAL


def facing_normals(normals: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Flip each normal to the side the ray comes from."""
    flip = np.einsum("ij,ij->i", normals, dirs) > 0.0
    return np.where(flip[:, None], -normals, normals)


def surface_radiance(accel, points, normals, reflectance, lights, medium, through=None):
    """Reflected radiance (N, 3) at surface points with ray-facing unit normals. `through(li, points)`,
    if given, is the transmittance (M, 3) toward light li of points whose shadow ray is occluded (0
    where truly blocked; bounded.py's shadows through index-matched interiors)."""
    out = np.zeros((len(points), 3))
    for li, lp in enumerate(lights.position):
        if lights.kind[li] == DIRECTIONAL:
            _add_directional(out, accel, points, normals, reflectance, lights, li, medium, through)
            continue
        to_light = lp[None, :] - points
        dist = np.linalg.norm(to_light, axis=1)
        cos = np.einsum("ij,ij->i", normals, to_light) / np.where(dist > 0.0, dist, 1.0)
        lit = (cos > 0.0) & (dist > 0.0)
        if not lit.any():
            continue
        idx = np.nonzero(lit)[0]
        o, d, tmax = accel.shadow_rays(points[idx], normals[idx], lp)
        idx, part = _unblocked(accel, o, d, tmax, idx, points, li, through)
        dl, cl = dist[idx], cos[idx]
        tr = medium.transmittance_on(points[idx], to_light[idx] / dl[:, None], 0.0, dl) * part
        irradiance = lights.irradiance(li, -to_light[idx], dl) * tr * cl[:, None]
        out[idx] += reflectance[idx] / math.pi * irradiance
    return out


def _unblocked(accel, o, d, tmax, idx, points, li, through):
    """The points idx whose shadow rays (o, d, tmax) reach light li, and the transmittance (M, 3) of the
    shapes they pass through (1 unless `through` lets an occluded ray through)."""
    occ = accel.occluded(o, d, tmax)
    part = np.ones((len(idx), 3))
    if through is not None and occ.any():
        part[occ] = through(li, points[idx[occ]])
        occ = ~np.any(part > 0.0, axis=1)
    return idx[~occ], part[~occ]


def _add_directional(out, accel, points, normals, reflectance, lights, li, medium, through=None):
    """out += the directional light li's reflected radiance (shadow rays to infinity toward it)."""
    wi = -lights.axis[li]
    cos = normals @ wi
    idx = np.nonzero(cos > 0.0)[0]
    if not len(idx):
        return
    o = points[idx] + accel.epsilon * normals[idx]
    d = np.broadcast_to(wi, o.shape)
    idx, part = _unblocked(accel, o, d, np.full(len(idx), np.inf), idx, points, li, through)
    tr = medium.transmittance_on(points[idx], np.broadcast_to(wi, (len(idx), 3)), 0.0, np.inf) * part
    out[idx] += reflectance[idx] / math.pi * lights.intensity[li] * tr * cos[idx, None]


def planet_hits(medium, origins, dirs, t):
    """(ground, t): where rays meet the medium's own ground (an atmosphere's planet) before the mesh
    hit at t, and t with those distances (float64, the numbers the transmittance compares with)."""
    if not medium.has_ground:
        return np.zeros(len(t), dtype=bool), t
    tg = medium.ground_hits(origins, dirs)
    ground = tg < t
    return ground, np.where(ground, tg, t)


def ground_radiance(accel, origins, dirs, t, lights, medium):
    """Reflected radiance (N, 3) of the medium's ground where rays origins + t dirs meet it."""
    points = origins + t[:, None] * dirs
    normals, refl = medium.ground_surface(points)
    return surface_radiance(accel, points, facing_normals(normals, dirs), refl, lights, medium)
