"""Emissive shapes: `emission` on a [[shape]] makes every triangle of it a Lambertian emitter (area.py)
of that radiance on its winding's side (both with `two_sided`). A rule's `level` is its place on one
ladder: level >= 0 splits each triangle in 4^level (`subdivide`) and takes the 7 emitter points of the
degree-5 rule of Radon (Stroud T2:5-1; Dunavant's 7-point rule) on each, a spot row each (LAMBERT);
level -1 is one row per triangle (its centroid, weight its area), and each level below groups 4 times
as many triangles into one row (`groups`): the group's area-weighted centroid with its vector area
sum(A n), which sends the group's sum(A max(0, n.u)) toward a far point in direction u while no
triangle of the group faces away. The pilot (cubature.py) climbs the ladder (`levels`); other methods
take `default_level`. A shape of more than MAX_TRIANGLES triangles is refused. Penumbrae sample the
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
MAX_TRIANGLES = 1 << 22  # an emissive shape's triangles at most
FIXED = 448  # the rows of `default_level` at most (64 triangles' 7-point rules): each costs a spot light
COARSE = 64  # the rows of the pilot's coarsest level at most

_A, _B = (6.0 - math.sqrt(15.0)) / 21.0, (6.0 + math.sqrt(15.0)) / 21.0
# barycentric nodes and weights (summing to 1) of the 7-point rule, exact for polynomials of degree 5
BARY = np.array([[1 / 3, 1 / 3, 1 / 3], [_A, _A, 1 - 2 * _A], [_A, 1 - 2 * _A, _A], [1 - 2 * _A, _A, _A],
                 [_B, _B, 1 - 2 * _B], [_B, 1 - 2 * _B, _B], [1 - 2 * _B, _B, _B]])
WEIGHTS = np.array([9 / 40] + [(155 - math.sqrt(15.0)) / 1200] * 3 + [(155 + math.sqrt(15.0)) / 1200] * 3)


def rows(triangles, radiance, two_sided: bool, where: str, level: int | None = None):
    """The spot rows of the triangles (T, 3, 3) of one emissive shape (`where`: its key and file, for the
    refusal) at `level` (the module's ladder; None: `default_level`); zero-area triangles give none."""
    if len(triangles) > MAX_TRIANGLES:
        raise UserError(f"{where}.emission: the shape has {len(triangles)} triangles; emissive shapes of more than "
                        f"{MAX_TRIANGLES} are not read; use a coarser mesh")
    triangles, cross, area = _nonzero(triangles)
    light = Light(np.zeros(3), np.asarray(radiance, float), two_sided=two_sided)
    level = default_level(len(triangles)) if level is None else level
    if level < 0:
        points, vector = groups(triangles, cross, area, level)
        weight = np.linalg.norm(vector, axis=1)
        return emitter_rows(light, points, vector / weight[:, None], weight)
    triangles, cross, area = _nonzero(subdivide(triangles, level))
    points = np.einsum("kj,tjc->tkc", BARY, triangles).reshape(-1, 3)
    normals = np.repeat(cross / (2.0 * area)[:, None], len(WEIGHTS), axis=0)
    return emitter_rows(light, points, normals, (area[:, None] * WEIGHTS[None, :]).ravel())


def groups(triangles, cross, area, level: int):
    """(points (G, 3), vector areas (G, 3)) of level < 0: groups of 4^(-1 - level) triangles, each
    triangle's normal class (the sign of its largest component, six classes: no group holds triangles
    facing opposite ways) in Morton order of the centroids, cut in runs; each group's area-weighted
    centroid and sum(A n). The groups of a level are unions of the level above's."""
    size = 4 ** (-1 - level)
    centroid = triangles.mean(axis=1)
    axis = np.argmax(np.abs(cross), axis=1)
    normal_class = 2 * axis + (cross[np.arange(len(cross)), axis] < 0.0)
    order = np.lexsort((_morton(centroid), normal_class))
    cls = normal_class[order]
    rank = np.arange(len(order)) - np.searchsorted(cls, cls)  # the place within its class
    group = np.unique(np.stack([cls, rank // size], axis=1), axis=0, return_inverse=True)[1].ravel()
    weight = np.zeros((group.max() + 1,))
    np.add.at(weight, group, area[order])
    points = np.zeros((len(weight), 3))
    np.add.at(points, group, area[order, None] * centroid[order])
    vector = np.zeros((len(weight), 3))
    np.add.at(vector, group, 0.5 * cross[order])
    return points / weight[:, None], vector


def _morton(points, bits: int = 21):
    """Each point's Morton code (Z order) in the points' bounding box, `bits` per axis."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    cell = np.floor((points - lo) / np.where(hi > lo, hi - lo, 1.0) * ((1 << bits) - 1)).astype(np.uint64)
    code = np.zeros(len(points), np.uint64)
    for b in range(bits):
        for a in range(3):
            code |= ((cell[:, a] >> np.uint64(b)) & np.uint64(1)) << np.uint64(3 * b + a)
    return code


def subdivide(triangles, level: int):
    """The triangles (T, 3, 3) each split 'level' times at its edges' midpoints: (4^level T, 3, 3)."""
    for _ in range(level):
        a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
        ab, bc, ca = 0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a)
        triangles = np.stack([np.stack(t, axis=1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))],
                             axis=1).reshape(-1, 3, 3)
    return triangles


def default_level(n_triangles: int) -> int:
    """The level of a fixed rule (methods without the pilot): the 7-point rule where it has at most FIXED
    rows, else the finest grouping within FIXED rows a side."""
    return 0 if _rows_a_side(n_triangles, 0) <= FIXED else _finest_within(n_triangles, FIXED)


def levels(n_triangles: int, finest: int) -> range:
    """The pilot's ladder up to `finest` (exclusive): from 0 where the 7-point rule has at most FIXED rows
    a side, else from the finest grouping within COARSE rows a side."""
    return range(0 if _rows_a_side(n_triangles, 0) <= FIXED else _finest_within(n_triangles, COARSE), finest)


def _finest_within(n_triangles: int, most: int) -> int:
    """The finest level below 0 whose groups number at most `most` a side (up to one more per normal class)."""
    level = -1
    while _rows_a_side(n_triangles, level) > most:
        level -= 1
    return level


def _rows_a_side(n_triangles: int, level: int) -> int:
    """The rows of one side at `level` but for the classes' partial groups."""
    return len(WEIGHTS) * n_triangles * 4 ** level if level >= 0 else -(-n_triangles // 4 ** (-1 - level))


def count(triangles, two_sided: bool, level) -> int:
    """The rows of `rows` at `level`."""
    triangles, cross, area = _nonzero(triangles)
    one = (_rows_a_side(len(triangles), level) if level >= 0 else len(groups(triangles, cross, area, level)[0]))
    return one * (2 if two_sided else 1)


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
    return Emitter(np.asarray(radiance, float), two_sided, sample, probes, self_shadowing=True, triangles=triangles)


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
