"""The disk area light: a Lambertian disk (area.py) of `center`, unit `normal` (its emitting side) and
`radius`; its emitter points are a polar rule, Gauss–Legendre of ORDER nodes in the radius r (weight
r dr) times 2 ORDER equally spaced angles (exact for trigonometric polynomials of degree < 2 ORDER).
Penumbrae sample it uniformly in area (`sample_emitter`).
Its shape is a fan of SEGMENTS triangles inscribed in the circle.
"""
from __future__ import annotations

import math

import numpy as np

from . import area
from .planar import disk as planar_disk

NAME = "disk"
CODE = 4
KEYS = area.COMMON_KEYS | {"center", "normal", "radius"}
ORDER = 6  # radial nodes: 72 rows (docs/area_lights.md)
# (u, v) of the probes: 16 points of the rim, PROBE_INSET of the radius inside it
CORNERS = (np.full(16, (1.0 - area.PROBE_INSET) ** 2), np.arange(16) / 16.0)
SEGMENTS = 128  # the emitter shape's triangles: its area is within 0.04 % of pi r^2


def parse(read, key, raw):
    area.required(read, key, raw, (("center", "[0.0, 2.99, 0.0]"), ("normal", "[0.0, -1.0, 0.0] (the emitting side)"),
                                   ("radius", "0.3")))
    center = read.vec3(f"{key}.center", raw["center"])
    normal = read.vec3(f"{key}.normal", raw["normal"])
    norm = float(np.linalg.norm(normal))
    if not norm > 0.0:
        read.fail(f"{key}.normal", "is zero", "give the direction the disk emits toward, e.g. [0.0, -1.0, 0.0]")
    radius = float(read.number(f"{key}.radius", raw["radius"], positive=True))
    return area.parse_common(read, key, raw, CODE, center, {"radius": radius, "area": math.pi * radius * radius},
                             normal / norm)


def describe(light) -> str:
    return (f"{NAME} at {light.position.tolist()}, normal {light.axis.round(6).tolist()}, radius "
            f"{light.emitter['radius']:g}, {area.radiance_text(light)}")


def rows(light, order: int | None = None):
    order = order or ORDER
    r, wr = area.gauss_legendre(order)
    r, wr = r * light.emitter["radius"], wr * light.emitter["radius"]
    m = 2 * order
    phi = 2.0 * math.pi * (np.arange(m) + 0.5) / m
    t1, t2 = area.frame(light.axis)
    ring = np.cos(phi)[:, None] * t1 + np.sin(phi)[:, None] * t2  # (m, 3)
    points = light.position + (r[:, None, None] * ring[None, :, :]).reshape(-1, 3)
    weights = np.repeat(r * wr * 2.0 * math.pi / m, m)
    return area.emitter_rows(light, points, np.tile(light.axis, (len(weights), 1)), weights)


def sample_emitter(light, u, v):
    """`area.Emitter.sample`: radius R sqrt(u), angle 2 pi v (uniform in area)."""
    t1, t2 = area.frame(light.axis)
    r, phi = light.emitter["radius"] * np.sqrt(u), 2.0 * math.pi * v
    points = light.position + r[:, None] * (np.cos(phi)[:, None] * t1 + np.sin(phi)[:, None] * t2)
    return points, np.tile(light.axis, (len(u), 1)), area.uniform_density(len(u), light.emitter["area"])


def shape(light):
    """The emitter as `triangles`: a fan about the centre, wound so that its normal is the disk's."""
    t1, t2 = area.frame(light.axis)
    phi = 2.0 * math.pi * np.arange(SEGMENTS) / SEGMENTS
    rim = light.position + light.emitter["radius"] * (np.cos(phi)[:, None] * t1 + np.sin(phi)[:, None] * t2)
    k = np.arange(SEGMENTS)
    faces = np.stack([np.zeros(SEGMENTS, dtype=np.int64), 1 + k, 1 + (k + 1) % SEGMENTS], axis=1)
    return "triangles", {"vertices": np.concatenate([light.position[None, :], rim]), "faces": faces}


def planar(light):
    """The emitter as a flat disk (planar.py): the rule about a camera ray's foot point."""
    return planar_disk(light.position, light.axis, *area.frame(light.axis), light.emitter["radius"])
