"""Area lights, emissive shapes and the environment in the scene dict, as the importers write them and
the exporters read them (the keys pinned in docs/scene_format.md: `quad`, `disk`, `sphere` and
`environment` lights, `emission` and `two_sided` on any [[shape]]).

Every emitter is Lambertian on its front side: a quad's normal is (c1 - c0) x (c3 - c0), a triangle's
(v1 - v0) x (v2 - v0) (its winding), a disk's `normal`, a sphere's outward normal. The importers turn
each format's emitting side into this winding (`oriented`); the exporters take the emitters out of the
dict before the rest is read by scene/format.py (`split`) and write them themselves.
"""
from __future__ import annotations

import copy
import math

import numpy as np

from ..errors import UserError

AREA = ("quad", "disk", "sphere")  # light types that are shapes (formats write them as emitting geometry)
ENVIRONMENT = "environment"


def oriented(faces, vertices, normals) -> np.ndarray:
    """`faces` with each triangle whose winding normal points away from its vertex normals' sum reversed,
    so that the winding gives the side the normals (a format's emitting side) point to."""
    faces = np.array(faces, dtype=np.int64)
    v, n = np.asarray(vertices, float), np.asarray(normals, float)
    tri = v[faces]
    wind = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    back = np.einsum("ij,ij->i", wind, n[faces].sum(axis=1)) < 0.0
    faces[back] = faces[back][:, ::-1]
    return faces


def quad_frame(corners, key: str, source: str):
    """(centre, half edge c1 - c0 over 2, half edge c3 - c0 over 2, unit normal) of a quad light's corners;
    UserError unless they are a parallelogram of non-zero area."""
    c = vector(corners, key, source, rows=4)
    x, y = (c[1] - c[0]) / 2.0, (c[3] - c[0]) / 2.0
    n = np.cross(x, y)
    size = float(np.abs(c).max()) or 1.0
    if not np.allclose(c[0] + c[2], c[1] + c[3], rtol=0.0, atol=1e-9 * size) or not np.linalg.norm(n) > 0.0:
        raise UserError(f"{source}: {key}: the four corners are not a parallelogram of non-zero area; give them "
                        "in order around it")
    return (c[0] + c[2]) / 2.0, x, y, n / np.linalg.norm(n)


def perpendicular(n) -> np.ndarray:
    """A unit vector perpendicular to the unit vector n: the first axis of the orthonormal basis of Duff
    et al., "Building an Orthonormal Basis, Revisited" (JCGT 6(1), 2017), Mitsuba's coordinate_system(n)."""
    sign = 1.0 if n[2] >= 0.0 else -1.0
    a = -1.0 / (sign + n[2])
    return np.array([1.0 + sign * n[0] * n[0] * a, sign * n[0] * n[1] * a, -sign * n[0]])


def disk_frame(light: dict, key: str, source: str) -> tuple[np.ndarray, float]:
    """(a 4 x 4 rotation and translation taking +z to a disk light's unit normal and the origin to its
    centre, its radius)."""
    n = vector(light.get("normal"), f"{key}.normal", source)
    if not np.linalg.norm(n) > 0.0:
        raise UserError(f"{source}: {key}.normal: the normal is zero; give the side the disk emits to")
    n = n / np.linalg.norm(n)
    u = perpendicular(n)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2] = u, np.cross(n, u), n
    m[:3, 3] = vector(light.get("center"), f"{key}.center", source)
    return m, positive(light.get("radius"), f"{key}.radius", source)


def vector(value, key: str, source: str, rows: int | None = None) -> np.ndarray:
    """A finite [x, y, z] (or `rows` of them) from the dict; UserError naming the key otherwise."""
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        v = np.zeros(0)
    shape = (3,) if rows is None else (rows, 3)
    if v.shape != shape or not np.all(np.isfinite(v)):
        what = "[x, y, z]" if rows is None else f"{rows} [x, y, z] points"
        raise UserError(f"{source}: {key}: expected {what} of finite numbers, got {value!r}")
    return v


def colour(value, key: str, source: str) -> np.ndarray:
    """An [r, g, b] or one number (all three) >= 0 from the dict."""
    v = np.broadcast_to(np.asarray(value, dtype=float), 3) if np.ndim(value) == 0 else np.asarray(value, float)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.any(v < 0.0):
        raise UserError(f"{source}: {key}: expected a radiance [r, g, b] (or one number) >= 0, got {value!r}")
    return np.array(v, float)


def constant_environment(light: dict, key: str, source: str) -> np.ndarray:
    """The radiance of a constant environment light: its `radiance` times its `scale` (default 1)."""
    scale = light.get("scale", 1.0)
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not 0.0 <= scale < math.inf:
        raise UserError(f"{source}: {key}.scale: expected a number >= 0, got {scale!r}")
    return colour(light.get("radiance"), f"{key}.radiance", source) * scale


def positive(value, key: str, source: str) -> float:
    v = float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else math.nan
    if not v > 0.0 or not math.isfinite(v):
        raise UserError(f"{source}: {key}: expected a number > 0, got {value!r}")
    return v


def split(raw: dict) -> tuple[dict, list[tuple[int, dict]], dict[int, dict]]:
    """(a copy of `raw` without the emitters, [(i, light)] of its area and environment lights, {shape index:
    {"emission": rgb, "two_sided": bool}}): what scene/format.py reads is exported through it, the
    emitters by the format's own code."""
    rest = copy.deepcopy(raw)
    lights = rest.get("light", [])
    emitters = [(i, light) for i, light in enumerate(lights) if light.get("type") in (*AREA, ENVIRONMENT)]
    if "light" in rest:
        rest["light"] = [light for light in lights if light.get("type") not in (*AREA, ENVIRONMENT)]
    emission = {}
    for i, shape in enumerate(rest.get("shape", [])):
        if "emission" in shape:
            emission[i] = {"emission": shape.pop("emission"), "two_sided": shape.pop("two_sided", False)}
    return rest, emitters, emission


def emission_of(raw_shape: dict, key: str, source: str) -> tuple[np.ndarray, bool]:
    """(radiance, two_sided) of a shape's `emission`."""
    two = raw_shape.get("two_sided", False)
    if not isinstance(two, bool):
        raise UserError(f"{source}: {key}.two_sided: expected true or false, got {two!r}")
    return colour(raw_shape["emission"], f"{key}.emission", source), two
