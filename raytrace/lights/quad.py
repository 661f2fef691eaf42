"""The quad area light: a Lambertian parallelogram (area.py) of corners c0..c3, emitting toward the
side of its normal (c1 - c0) x (c3 - c0); its emitter points are the tensor Gauss–Legendre rule of
ORDER x ORDER nodes over y = c0 + u (c1 - c0) + v (c3 - c0), (u, v) in [0, 1]^2 (the same map samples
it in penumbrae: `sample_emitter`).
"""
from __future__ import annotations

import numpy as np

from . import area
from .planar import polygon

NAME = "quad"
CODE = 3
KEYS = area.COMMON_KEYS | {"corners"}
ORDER = 8  # nodes per side (docs/area_lights.md: the twin's error against the order)
_IN = (area.PROBE_INSET, 1.0 - area.PROBE_INSET)
CORNERS = (np.array([_IN[0], _IN[1], _IN[1], _IN[0]]), np.array([_IN[0], _IN[0], _IN[1], _IN[1]]))  # the probes' (u, v)
FLAT_TOL = 1e-9  # relative to the quad's size: how far c2 may lie from c1 + c3 - c0


def parse(read, key, raw):
    area.required(read, key, raw, (("corners", "[[x, y, z], [x, y, z], [x, y, z], [x, y, z]]"),))
    c = raw["corners"]
    if not isinstance(c, list) or len(c) != 4:
        read.fail(f"{key}.corners", "expected four [x, y, z] corners in order around the quad",
                  "write corners = [[..], [..], [..], [..]]")
    c = np.array([read.vec3(f"{key}.corners[{j}]", p) for j, p in enumerate(c)])
    e1, e3 = c[1] - c[0], c[3] - c[0]
    cross = np.cross(e1, e3)
    size = max(np.linalg.norm(e1), np.linalg.norm(e3))
    if not np.linalg.norm(cross) > 1e-12 * size * size:
        read.fail(f"{key}.corners", "the corners have no area (collinear or repeated)",
                  "give four corners of a parallelogram in order around it")
    if np.linalg.norm(c[2] - (c[1] + e3)) > FLAT_TOL * size:
        read.fail(f"{key}.corners[2]", f"is not c1 + c3 - c0 = {(c[1] + e3).tolist()}: the quad is not a "
                  "parallelogram", "give the corners of a parallelogram in order (or use a [[shape]] with emission)")
    normal = cross / np.linalg.norm(cross)
    return area.parse_common(read, key, raw, CODE, c.mean(axis=0), {"corners": c, "area": float(np.linalg.norm(cross))},
                             normal)


def describe(light) -> str:
    return (f"{NAME} of corners {light.emitter['corners'].tolist()}, normal {light.axis.round(6).tolist()}, "
            f"area {light.emitter['area']:g}, {area.radiance_text(light)}")


def rows(light, order: int | None = None):
    order = order or ORDER
    c = light.emitter["corners"]
    u, w = area.gauss_legendre(order)
    uu, vv = np.meshgrid(u, u, indexing="ij")
    points = c[0] + uu.reshape(-1, 1) * (c[1] - c[0]) + vv.reshape(-1, 1) * (c[3] - c[0])
    weights = np.outer(w, w).ravel() * light.emitter["area"]
    return area.emitter_rows(light, points, np.tile(light.axis, (len(weights), 1)), weights)


def sample_emitter(light, u, v):
    """`area.Emitter.sample`: y = c0 + u (c1 - c0) + v (c3 - c0), uniform in area."""
    c = light.emitter["corners"]
    points = c[0] + u[:, None] * (c[1] - c[0]) + v[:, None] * (c[3] - c[0])
    return points, np.tile(light.axis, (len(u), 1)), area.uniform_density(len(u), light.emitter["area"])


def shape(light):
    """The emitter as a `quad` primitive (scene/meshes.py: its triangles wind like the corners)."""
    return "quad", {"corners": light.emitter["corners"]}


def planar(light):
    """The emitter as a flat polygon (planar.py): the rule about a camera ray's foot point."""
    return polygon(light.emitter["corners"], light.axis)
