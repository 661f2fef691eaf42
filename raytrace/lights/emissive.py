"""Emissive shapes: `emission` on a [[shape]] makes every triangle of it a Lambertian emitter (area.py)
of that radiance on its winding's side (both with `two_sided`). Each triangle is the 7 emitter points of
the degree-5 rule of Radon (Stroud T2:5-1; Dunavant's 7-point rule), a spot row each (LAMBERT); a shape
of more than MAX_TRIANGLES triangles is refused until triangles are grouped; the pilot
(cubature.py) may split each triangle in 4^level (`subdivide`). Penumbrae sample the
shape uniformly in area (`emitter`).
"""
from __future__ import annotations

import functools
import math

import numpy as np

from ..errors import UserError
from .area import PROBE_INSET, Emitter, emitter_rows, uniform_density
from .light import Light

NAME = "emission"  # its name among a scene's light kinds (`Lights.kinds`), for the methods' refusals
MAX_TRIANGLES = 64  # 448 rows: each row costs what a spot light costs (docs/area_lights.md)

_A, _B = (6.0 - math.sqrt(15.0)) / 21.0, (6.0 + math.sqrt(15.0)) / 21.0
# barycentric nodes and weights (summing to 1) of the 7-point rule, exact for polynomials of degree 5
BARY = np.array([[1 / 3, 1 / 3, 1 / 3], [_A, _A, 1 - 2 * _A], [_A, 1 - 2 * _A, _A], [1 - 2 * _A, _A, _A],
                 [_B, _B, 1 - 2 * _B], [_B, 1 - 2 * _B, _B], [1 - 2 * _B, _B, _B]])
WEIGHTS = np.array([9 / 40] + [(155 - math.sqrt(15.0)) / 1200] * 3 + [(155 + math.sqrt(15.0)) / 1200] * 3)


def rows(triangles, radiance, two_sided: bool, where: str, level: int | None = None):
    """The spot rows of the triangles (T, 3, 3) of one emissive shape (`where`: its key and file, for the
    refusal), each triangle split in 4^level (`subdivide`; None: 0) before its 7-point rule; zero-area
    triangles give none."""
    if len(triangles) > MAX_TRIANGLES:
        raise UserError(f"{where}.emission: the shape has {len(triangles)} triangles; emissive shapes of more than "
                        f"{MAX_TRIANGLES} are not implemented yet (each triangle is 7 emitter points); use a quad, "
                        "disk or sphere light, or a coarser mesh")
    triangles, cross, area = _nonzero(subdivide(triangles, level or 0))
    points = np.einsum("kj,tjc->tkc", BARY, triangles).reshape(-1, 3)
    normals = np.repeat(cross / (2.0 * area)[:, None], len(WEIGHTS), axis=0)
    light = Light(np.zeros(3), np.asarray(radiance, float), two_sided=two_sided)
    return emitter_rows(light, points, normals, (area[:, None] * WEIGHTS[None, :]).ravel())


def subdivide(triangles, level: int):
    """The triangles (T, 3, 3) each split 'level' times at its edges' midpoints: (4^level T, 3, 3)."""
    for _ in range(level):
        a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
        ab, bc, ca = 0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a)
        triangles = np.stack([np.stack(t, axis=1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))],
                             axis=1).reshape(-1, 3, 3)
    return triangles


def count(triangles, two_sided: bool, level) -> int:
    """The rows of `rows` at `level`: 7 per nonzero triangle and per side."""
    return len(WEIGHTS) * len(_nonzero(triangles)[2]) * 4 ** level * (2 if two_sided else 1)


def _nonzero(triangles):
    """The triangles (T, 3, 3) of nonzero area, their winding's cross products (T, 3) and areas (T,)."""
    cross = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    keep = area > 0.0
    return triangles[keep], cross[keep], area[keep]


def emitter(triangles, radiance, two_sided: bool, where: str = "") -> Emitter:
    """The `Emitter` of one emissive shape (`rows`' arguments; `where` unused: the rows refuse)."""
    triangles, cross, area = _nonzero(triangles)
    normals = cross / (2.0 * area)[:, None]
    corners = (1.0 - PROBE_INSET) * triangles + PROBE_INSET * triangles.mean(axis=1, keepdims=True)  # the probes
    sample = functools.partial(_sample, triangles, normals, np.cumsum(area))
    probes = (corners.reshape(-1, 3), np.repeat(normals, 3, axis=0))
    return Emitter(np.asarray(radiance, float), two_sided, sample, probes)


def _sample(triangles, normals, cumulative, u, v):
    """`Emitter.sample` of a triangle mesh: u picks the triangle by area (the cumulative areas) and,
    rescaled within its share, with v the point by the square-to-triangle map
    y = (1 - s) a + s (1 - v) b + s v c, s = sqrt(u') (uniform in area: density 1 / A)."""
    total = cumulative[-1]
    x = u * total
    k = np.minimum(np.searchsorted(cumulative, x, side="right"), len(cumulative) - 1)
    lo = np.where(k > 0, cumulative[np.maximum(k - 1, 0)], 0.0)
    s = np.sqrt(np.clip((x - lo) / (cumulative[k] - lo), 0.0, 1.0))
    t = triangles[k]
    points = ((1.0 - s)[:, None] * t[:, 0] + (s * (1.0 - v))[:, None] * t[:, 1] + (s * v)[:, None] * t[:, 2])
    return points, normals[k], uniform_density(len(u), total)
