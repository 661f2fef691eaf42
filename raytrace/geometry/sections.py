"""The kinks of the light paths from a camera segment through a closed triangle mesh, convex or not.

From a point X(x) = o + x w, the straight path toward a light lies in the plane through the camera
line and the light (through the line along the light's direction, for a directional light). That
plane cuts the mesh in a set of polygons, the section, whose vertices are the points where mesh edges
cross the plane. The path's length inside the mesh is the sum of its stretches between crossings of
the section's sides. Each crossing moves smoothly with x while the path meets the same side (the same
triangle), so the length is smooth in x except where the path passes through a vertex of the section.
These are the kinks of the inside integrand (paper eq. 7 with that length), and a Gauss-Legendre rule
that does not start its panels there converges slowly or accepts a panel across one.

`section_breaks` finds them in closed form, edge by edge: an edge (A, B) that crosses the plane gives
the vertex V = A + s (B - A), s = n·(L - A) / n·(B - A) for a point light L (n the plane's normal), and
the camera-line point whose path passes through V is where the line from L through V meets the camera
line. Only vertices between X and the light count (the path runs from X toward L). Each edge is
evaluated once, with its ends in a fixed order, so a break is the same double from both triangles that
share the edge. The same construction on the planes of a convex shape is media/convex_chords.py
`section_kinks`; this one needs no convexity.
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import njit


def mesh_edges(triangles: np.ndarray) -> np.ndarray:
    """(E, 2, 3) the distinct edges of a triangle soup (T, 3, 3), each with its ends in lexicographic
    order (an edge shared by two triangles, as in a closed mesh, appears once)."""
    return np.ascontiguousarray(np.unique(_ordered_edges(triangles), axis=0).reshape(-1, 2, 3))


def edge_neighbours(triangles: np.ndarray) -> np.ndarray:
    """(T, 3) int64: the triangle across edge k (from vertex k to vertex k + 1) of each triangle of the
    soup (T, 3, 3), where exactly one other triangle has that edge (the same two ends, bit for bit);
    else -1."""
    _, edge = np.unique(_ordered_edges(triangles), axis=0, return_inverse=True)
    edge = edge.ravel()
    order = np.argsort(edge, kind="stable")
    e = edge[order]
    start = np.searchsorted(e, e, side="left")
    count = np.searchsorted(e, e, side="right") - start
    pair = count == 2
    other = np.where(order == order[start], order[np.minimum(start + 1, len(e) - 1)], order[start])
    out = np.full(len(edge), -1, dtype=np.int64)
    out[order[pair]] = other[pair] // 3
    return out.reshape(-1, 3)


def _ordered_edges(triangles):
    """(3T, 6) each triangle's edges k -> k + 1, their ends in lexicographic order."""
    a = triangles.reshape(-1, 3)
    b = triangles[:, [1, 2, 0]].reshape(-1, 3)
    first = _lex_less(a, b)
    return np.concatenate([np.where(first[:, None], a, b), np.where(first[:, None], b, a)], axis=1)


def _lex_less(a, b):
    """a < b lexicographically, row by row (N,)."""
    out = np.zeros(len(a), dtype=bool)
    decided = np.zeros(len(a), dtype=bool)
    for k in range(3):
        less, more = a[:, k] < b[:, k], a[:, k] > b[:, k]
        out |= ~decided & less
        decided |= less | more
    return out


def section_breaks(edges, geo, directional, end):
    """(offsets (N + 1,), breaks): the parameters in (0, end[i]) along each segment i (origin geo[i, :3],
    unit direction geo[i, 3:6]) where the path toward the light (geo[i, 6:9]: a point light's position,
    or the unit direction toward a directional light) passes through a vertex of the mesh's section,
    breaks[offsets[i]:offsets[i + 1]] ascending."""
    counts = np.zeros(len(end) + 1, dtype=np.int64)
    _breaks(edges, geo, directional, end, counts, np.empty(0), np.zeros(1, dtype=np.int64))
    offsets = np.cumsum(counts)
    out = np.empty(offsets[-1])
    counts[:] = 0
    _breaks(edges, geo, directional, end, counts, out, offsets)
    return offsets, out


@njit
def _breaks(edges, geo, directional, end, counts, out, offsets):
    """Count (out empty) or write (out[offsets[i]:...], sorted) each segment's breaks: `section_breaks`."""
    fill = out.shape[0] > 0
    for i in range(geo.shape[0]):
        if not end[i] > 0.0:
            continue
        ox, oy, oz, wx, wy, wz = geo[i, 0], geo[i, 1], geo[i, 2], geo[i, 3], geo[i, 4], geo[i, 5]
        if directional:
            vx, vy, vz = geo[i, 6], geo[i, 7], geo[i, 8]
        else:
            vx, vy, vz = geo[i, 6] - ox, geo[i, 7] - oy, geo[i, 8] - oz
        lx = vx * wx + vy * wy + vz * wz  # the light (or its direction) in the plane's frame: (lx, ly)
        px, py, pz = vx - lx * wx, vy - lx * wy, vz - lx * wz
        ly = math.sqrt(px * px + py * py + pz * pz)
        if not ly > 1e-12 * math.sqrt(vx * vx + vy * vy + vz * vz):
            continue  # the light on the camera line (or along it): no plane, no kinks
        ex, ey, ez = px / ly, py / ly, pz / ly
        nx, ny, nz = wy * ez - wz * ey, wz * ex - wx * ez, wx * ey - wy * ex  # the plane's normal
        start = offsets[i] if fill else 0
        k = 0
        for e in range(edges.shape[0]):
            ax, ay, az = edges[e, 0, 0] - ox, edges[e, 0, 1] - oy, edges[e, 0, 2] - oz
            bx, by, bz = edges[e, 1, 0] - ox, edges[e, 1, 1] - oy, edges[e, 1, 2] - oz
            da = nx * ax + ny * ay + nz * az
            db = nx * bx + ny * by + nz * bz
            if (da > 0.0 and db > 0.0) or (da < 0.0 and db < 0.0) or da == db:
                continue  # the edge does not cross the plane (or lies in it: its ends are other edges')
            s = da / (da - db)
            qx, qy, qz = ax + s * (bx - ax), ay + s * (by - ay), az + s * (bz - az)
            u = qx * wx + qy * wy + qz * wz  # the section's vertex in the frame: (u, v)
            v = qx * ex + qy * ey + qz * ez
            if directional:
                if not v > 0.0:
                    continue  # behind the line, away from the light
                x = u - v * lx / ly
            else:
                if not (0.0 < v < ly):
                    continue  # not between the line and the light
                x = lx - (u - lx) * ly / (v - ly)
            if 0.0 < x < end[i]:
                if fill:
                    out[start + k] = x
                k += 1
        counts[i + 1] = k
        if fill:
            out[start:start + k].sort()
