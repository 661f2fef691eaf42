"""Emissive shapes: `emission` on a [[shape]] makes every triangle of it a Lambertian emitter (area.py)
of that radiance on its winding's side (both with `two_sided`). Each triangle is the 7 emitter points of
the degree-5 rule of Radon (Stroud T2:5-1; Dunavant's 7-point rule), a spot row each (LAMBERT); a shape
of more than MAX_TRIANGLES triangles is refused until triangles are grouped.
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import UserError
from .area import emitter_rows
from .light import Light

NAME = "emission"  # its name among a scene's light kinds (`Lights.kinds`), for the methods' refusals
MAX_TRIANGLES = 64  # 448 rows: each row costs what a spot light costs (docs/area_lights.md)

_A, _B = (6.0 - math.sqrt(15.0)) / 21.0, (6.0 + math.sqrt(15.0)) / 21.0
# barycentric nodes and weights (summing to 1) of the 7-point rule, exact for polynomials of degree 5
BARY = np.array([[1 / 3, 1 / 3, 1 / 3], [_A, _A, 1 - 2 * _A], [_A, 1 - 2 * _A, _A], [1 - 2 * _A, _A, _A],
                 [_B, _B, 1 - 2 * _B], [_B, 1 - 2 * _B, _B], [1 - 2 * _B, _B, _B]])
WEIGHTS = np.array([9 / 40] + [(155 - math.sqrt(15.0)) / 1200] * 3 + [(155 + math.sqrt(15.0)) / 1200] * 3)


def rows(triangles, radiance, two_sided: bool, where: str):
    """The spot rows of the triangles (T, 3, 3) of one emissive shape (`where`: its key and file, for the
    refusal); zero-area triangles give none."""
    if len(triangles) > MAX_TRIANGLES:
        raise UserError(f"{where}.emission: the shape has {len(triangles)} triangles; emissive shapes of more than "
                        f"{MAX_TRIANGLES} are not implemented yet (each triangle is 7 emitter points); use a quad, "
                        "disk or sphere light, or a coarser mesh")
    cross = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    keep = area > 0.0
    triangles, cross, area = triangles[keep], cross[keep], area[keep]
    points = np.einsum("kj,tjc->tkc", BARY, triangles).reshape(-1, 3)
    normals = np.repeat(cross / (2.0 * area)[:, None], len(WEIGHTS), axis=0)
    light = Light(np.zeros(3), np.asarray(radiance, float), two_sided=two_sided)
    return emitter_rows(light, points, normals, (area[:, None] * WEIGHTS[None, :]).ravel())
