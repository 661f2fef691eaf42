"""Loop subdivision surfaces, as pbrt-v4's Shape "loopsubdiv" makes them: each level splits every triangle
in four (Loop 1987) with Warren's weights (beta = 3/16 at valence 3, else 3/(8 n)) inside and the
cubic B-spline rules (1/8, 3/4, 1/8; 1/2, 1/2) on boundaries; the last level's vertices are then moved
to the limit surface, and its normals are the cross product of the two limit tangents (Hoppe et al.
1994: the cos / sin masks of the ring inside, the boundary masks by valence on the boundary), turned
to the faces' winding side. Verified in tests/test_loop_subdivision.py: one level against trimesh's
Loop subdivision where both use the same weights, and limit points and normals unchanged by a further
level (they are the subdivision matrix's left eigenvectors)."""
from __future__ import annotations

import numpy as np


class NotManifold(ValueError):
    """The control mesh has an edge of more than two faces, or faces wound inconsistently."""


def surface(points, faces, levels: int):
    """The limit-surface mesh of `levels` subdivisions of the triangles `faces` (F, 3) over `points`
    (V, 3): (vertices, faces, unit normals); points on no face are left out."""
    used, faces = np.unique(np.asarray(faces, np.int64), return_inverse=True)  # points on no face go
    points, faces = np.asarray(points, float)[used], faces.reshape(-1, 3)
    for _ in range(levels):
        points, faces = subdivide(points, faces)
    return limit_points(points, faces), faces, limit_normals(points, faces)


def subdivide(points, faces):
    """One level of Loop subdivision: (4 F faces, V + E points), the old vertices first, each edge's new
    vertex after them in the order of `_edges`; every face split in four with its winding kept."""
    edge, unique, count = _edges(faces)
    a, b = unique[:, 0], unique[:, 1]
    opposite = np.zeros((len(unique), 3))
    np.add.at(opposite, edge[:, 0], points[faces[:, 2]])
    np.add.at(opposite, edge[:, 1], points[faces[:, 0]])
    np.add.at(opposite, edge[:, 2], points[faces[:, 1]])
    inner = (count == 2)[:, None]
    odd = np.where(inner, 0.375 * (points[a] + points[b]) + 0.125 * opposite, 0.5 * (points[a] + points[b]))
    n, ring, boundary, ring_boundary = _rings(len(points), unique, count)
    beta = np.where(n == 3, 3.0 / 16.0, 3.0 / (8.0 * np.maximum(n, 1)))
    even = np.where(boundary[:, None], 0.75 * points + 0.125 * ring_boundary(points),
                    (1.0 - n * beta)[:, None] * points + beta[:, None] * ring(points))
    e = edge + len(points)
    v0, v1, v2 = faces[:, 0], faces[:, 1], faces[:, 2]
    e01, e12, e20 = e[:, 0], e[:, 1], e[:, 2]
    new = np.stack([np.stack(t, axis=1) for t in ((v0, e01, e20), (v1, e12, e01), (v2, e20, e12), (e01, e12, e20))],
                   axis=1).reshape(-1, 3)
    return np.concatenate([even, odd]), new


def limit_points(points, faces):
    """Each vertex moved to the limit surface: inside (1 - n g) v + g (sum of the ring), g = 1 / (n + 3 /
    (8 beta)); on a boundary, the cubic B-spline's (4 v + the two boundary neighbours) / 6 (pbrt-v4
    weighs them 3 : 1 : 1, which is not the limit: a level further moves it)."""
    edge, unique, count = _edges(faces)
    n, ring, boundary, ring_boundary = _rings(len(points), unique, count)
    beta = np.where(n == 3, 3.0 / 16.0, 3.0 / (8.0 * np.maximum(n, 1)))
    g = 1.0 / (n + 3.0 / (8.0 * beta))
    return np.where(boundary[:, None], (4.0 * points + ring_boundary(points)) / 6.0,
                    (1.0 - n * g)[:, None] * points + g[:, None] * ring(points))


def limit_normals(points, faces):
    """Unit limit normals: S x T of the limit tangents over each vertex's ring in order (`_ordered_rings`),
    on the side of the faces' winding."""
    rings, is_boundary = _ordered_rings(len(points), faces)
    out = np.zeros((len(points), 3))
    for v, (ring, on_edge) in enumerate(zip(rings, is_boundary)):
        p, k = points[ring], len(ring)
        if not on_edge:
            ang = 2.0 * np.pi * np.arange(k) / k
            s, t = np.cos(ang) @ p, np.sin(ang) @ p
        else:
            s = p[-1] - p[0]
            if k == 2:
                t = p[0] + p[1] - 2.0 * points[v]
            elif k == 3:
                t = p[1] - points[v]
            elif k == 4:
                t = -p[0] + 2.0 * p[1] + 2.0 * p[2] - p[3] - 2.0 * points[v]
            else:
                th = np.pi / (k - 1)
                w = (2.0 * np.cos(th) - 2.0) * np.sin(np.arange(1, k - 1) * th)
                t = -(np.sin(th) * (p[0] + p[-1]) + w @ p[1:-1])
        out[v] = np.cross(s, t)
    side = np.zeros((len(points), 3))
    area = np.cross(points[faces[:, 1]] - points[faces[:, 0]], points[faces[:, 2]] - points[faces[:, 0]])
    for c in range(3):
        np.add.at(side, faces[:, c], area)
    out *= np.where(np.einsum("ij,ij->i", out, side) < 0.0, -1.0, 1.0)[:, None]
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def _edges(faces):
    """(edge index of each face's sides (v0 v1, v1 v2, v2 v0): (F, 3), the unique edges (E, 2) with their
    ends sorted, the faces on each (E,)); raises NotManifold for an edge of more than two faces."""
    sides = np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2)
    unique, inverse, count = np.unique(np.sort(sides, axis=1), axis=0, return_inverse=True, return_counts=True)
    if np.any(count > 2):
        raise NotManifold(f"{int(np.sum(count > 2))} edges are shared by more than two faces")
    return inverse.reshape(-1, 3), unique, count


def _rings(n_points, unique, count):
    """(valence (V,), the sum over each vertex's neighbours as a function of the points, the boundary
    vertices (V,), the sum over each boundary vertex's two boundary neighbours likewise)."""
    a, b = unique[:, 0], unique[:, 1]
    n = np.bincount(a, minlength=n_points) + np.bincount(b, minlength=n_points)
    edge = count == 1
    boundary = np.zeros(n_points, bool)
    boundary[a[edge]] = boundary[b[edge]] = True

    def ring(points, a=a, b=b):
        s = np.zeros_like(points)
        np.add.at(s, a, points[b])
        np.add.at(s, b, points[a])
        return s

    return n, ring, boundary, lambda points: ring(points, a[edge], b[edge])


def _ordered_rings(n_points, faces):
    """Each vertex's neighbours in the order of the faces' winding around it, a boundary vertex's from
    one boundary neighbour to the other, and whether it is on a boundary; raises NotManifold where the
    faces around a vertex are not one consistently wound fan."""
    after = [dict() for _ in range(n_points)]
    for f in faces.tolist():
        for i in range(3):
            v, b, c = f[i], f[(i + 1) % 3], f[(i + 2) % 3]
            if b in after[v]:
                raise NotManifold(f"the faces around vertex {v} are wound inconsistently")
            after[v][b] = c
    rings, boundary = [], []
    for v, nxt in enumerate(after):
        starts = list(set(nxt) - set(nxt.values()))  # an open fan begins at its one boundary neighbour
        ring = starts[:1] or [next(iter(nxt))]
        while len(ring) <= len(nxt) and ring[-1] in nxt and nxt[ring[-1]] != ring[0]:
            ring.append(nxt[ring[-1]])
        if len(starts) > 1 or len(ring) != len(nxt) + len(starts):
            raise NotManifold(f"the faces around vertex {v} are not one fan")
        rings.append(np.array(ring, np.int64))
        boundary.append(bool(starts))
    return rings, boundary
