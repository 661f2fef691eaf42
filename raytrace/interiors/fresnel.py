"""Snell's refraction and Fresnel's transmittance at a smooth dielectric boundary, for arrays of rays (media/slab.py's
kernels), and the beams a directional light makes inside a convex refractive shape (`refracted_beams`)."""
from __future__ import annotations

import numpy as np

from ..media.slab import refract_rays, transmittances


def refract(d, n, eta):
    """The unit directions (N, 3) of rays along d (N, 3) refracted through a boundary of unit normals n (N, 3)
    facing them into relative index eta, and the cosines (N,) of the refracted rays to -n (<= 0 on total
    internal reflection: media/slab.py `refract_rays`)."""
    out, cos_t = np.empty_like(d), np.empty(len(d))
    refract_rays(np.ascontiguousarray(d), np.ascontiguousarray(n), float(eta), out, cos_t)
    return out, cos_t


def transmittance(cos_i, eta):
    """Fresnel's transmittance T (N,) of unpolarised light at incidence cosines cos_i (N,) into relative index eta
    (media/slab.py `transmittances`; 0 on total internal reflection)."""
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
    t, cos_t = refract(np.broadcast_to(axis, (len(faces), 3)).copy(), planes[faces, :3], eta)
    ok = cos_t > 0.0
    faces, t, cos_i, cos_t = faces[ok], t[ok], cos_i[faces[ok]], cos_t[ok]
    return faces, -t, transmittance(cos_i, eta) * cos_i / cos_t
