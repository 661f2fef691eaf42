"""The sphere area light: a Lambertian sphere (area.py) of `center` and `radius` emitting outward;
its emitter points are the product rule of ORDER Gauss–Legendre nodes in z = cos(theta) times 2 ORDER
equally spaced azimuths. Each point's LAMBERT falloff max(0, n·u) is its own visibility over the
sphere (a point of a convex emitter sees the receiver exactly when the receiver is in front of it).
Penumbrae sample it uniformly in area (`sample_emitter`). Its shape is the exact sphere
(geometry/sphere.py: camera and shadow rays meet it in float64, and it does not shadow its own
emitter points, which lie on it); its mesh of SEGMENTS segments is what exporters write. Surfaces it
lights unshadowed in a homogeneous medium take its irradiance about its centre instead of the rows
(`surface_irradiance`, sphere_irradiance.py).
"""
from __future__ import annotations

import math

import numpy as np

from . import area, sphere_irradiance
from .light import Light
from .sphere_rule import Ball

NAME = "sphere"
CODE = 5
KEYS = (area.COMMON_KEYS - {"two_sided"}) | {"center", "radius"}
ORDER = 8  # nodes in cos(theta) (docs/area_lights.md)
SEGMENTS = 64


def parse(read, key, raw):
    area.required(read, key, raw, (("center", "[1.0, 1.0, 0.0]"), ("radius", "0.1")))
    center = read.vec3(f"{key}.center", raw["center"])
    radius = float(read.number(f"{key}.radius", raw["radius"], positive=True))
    return area.parse_common(read, key, raw, CODE, center, _emitter(radius), sides=False)


def _emitter(radius: float) -> dict:
    return {"radius": radius, "area": 4.0 * math.pi * radius * radius}


def of_shape(center, radius: float, emission) -> Light:
    """The sphere light of an exact `[[shape]]` sphere that emits (scene/format.py): its centre and
    radius in world space, its `emission` the radiance."""
    return Light(np.asarray(center, float), np.asarray(emission, float), CODE, None, emitter=_emitter(float(radius)))


def describe(light) -> str:
    return f"{NAME} at {light.position.tolist()}, radius {light.emitter['radius']:g}, {area.radiance_text(light)}"


def rows(light, order: int | None = None):
    order = order or ORDER
    z, wz = area.gauss_legendre(order)
    z, wz = 2.0 * z - 1.0, 2.0 * wz  # on [-1, 1]
    m = 2 * order
    phi = 2.0 * math.pi * (np.arange(m) + 0.5) / m
    s = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    normals = np.stack([np.outer(s, np.cos(phi)), np.repeat(z[:, None], m, axis=1), np.outer(s, np.sin(phi))],
                       axis=-1).reshape(-1, 3)
    radius = light.emitter["radius"]
    weights = np.repeat(wz * radius * radius * 2.0 * math.pi / m, m)
    return area.emitter_rows(light, light.position + radius * normals, normals, weights)


def sample_emitter(light, u, v):
    """`area.Emitter.sample`: z = 1 - 2 u, azimuth 2 pi v (Archimedes: uniform in area)."""
    z, phi = 1.0 - 2.0 * u, 2.0 * math.pi * v
    s = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    normals = np.stack([s * np.cos(phi), z, s * np.sin(phi)], axis=1)
    points = light.position + light.emitter["radius"] * normals
    return points, normals, area.uniform_density(len(u), light.emitter["area"])


def ball(light) -> Ball:
    """The emitter as the rule about a camera ray's segment needs it (sphere_rule.py)."""
    return Ball(np.asarray(light.position, float), float(light.emitter["radius"]))


def surface_irradiance(light, points, normals, shading, sigma_t, tol, missed=None):
    """`area.Emitter.irradiance`: the sphere's unshadowed irradiance (sphere_irradiance.py) on the
    shading normals `shading` (None: the geometric `normals` are the shading ones); it applies where
    those are the geometric ones or the cap lies wholly above the geometric normal's plane (elsewhere
    that plane, which also bounds what is lit, cuts the cap apart from the shading one's). `missed`:
    as sphere_irradiance.irradiance's."""
    applies = np.ones(len(points), dtype=bool)
    if shading is not None:
        applies = np.all(shading == normals, axis=1) | (sphere_irradiance.cap_cosine(light.position,
                                                                                     light.emitter["radius"], points,
                                                                                     normals) >= 0.0)
    e = sphere_irradiance.irradiance(light.position, light.emitter["radius"], light.intensity, points[applies],
                                     (normals if shading is None else shading)[applies], sigma_t, tol, missed)
    out = np.zeros((len(points), 3))
    out[applies] = e
    return out, applies


def shape(light):
    return "sphere", {"center": light.position, "radius": light.emitter["radius"], "segments": SEGMENTS, "exact": True}
