"""The surface term (paper eq. 5) with shadow-ray visibility, summed over lights.

Lb = sum_lights V (rho / pi) I F exp(-kt d) / d^2 max(0, n·wi), with the geometric normal flipped to
face the incoming ray (two-sided Lambertian surfaces), F a spot light's falloff toward the point
(lights.py, 1 for point lights). The camera sees it attenuated by
exp(-kt t); that factor is applied by the renderer.
"""
from __future__ import annotations

import math

import numpy as np


def facing_normals(normals: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Flip each normal to the side the ray comes from."""
    flip = np.einsum("ij,ij->i", normals, dirs) > 0.0
    return np.where(flip[:, None], -normals, normals)


def surface_radiance(accel, points, normals, reflectance, lights, medium):
    """Reflected radiance (N, 3) at surface points with ray-facing unit normals."""
    out = np.zeros((len(points), 3))
    for li, lp in enumerate(lights.position):
        to_light = lp[None, :] - points
        dist = np.linalg.norm(to_light, axis=1)
        cos = np.einsum("ij,ij->i", normals, to_light) / np.where(dist > 0.0, dist, 1.0)
        lit = (cos > 0.0) & (dist > 0.0)
        if not lit.any():
            continue
        idx = np.nonzero(lit)[0]
        o, d, tmax = accel.shadow_rays(points[idx], normals[idx], lp)
        visible = ~accel.occluded(o, d, tmax)
        idx, dl, cl = idx[visible], dist[idx][visible], cos[idx][visible]
        irradiance = lights.irradiance(li, -to_light[idx], dl) * medium.transmittance(dl) * cl[:, None]
        out[idx] += reflectance[idx] / math.pi * irradiance
    return out
