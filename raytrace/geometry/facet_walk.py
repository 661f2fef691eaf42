"""The facets through which light paths from a camera segment leave a convex triangle mesh.

From a point x(t) = o + t w inside a convex shape, the straight path toward a light leaves the shape
through one facet. Every such path lies in the plane through the camera line and the light (through
the line along the light's direction, for a directional light). So the exit points trace the
polygon this plane cuts from the mesh, and the exit facet changes exactly where that polygon
crosses a mesh edge. These are the kinks of the inside path length, and so of the integrand.

`walk` (`pieces` runs it) follows the polygon from one known exit facet to the segment's two ends,
through the triangles' edge neighbours (`mesh_links`). The breakpoint of each crossed edge is found in closed
form: the camera-line point whose path toward the light passes through the edge. The cost is one
step per kink, whatever the triangle count. `exit_lengths` measures a path's length inside on the
facet of the piece that holds its point.
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import njit

U = 2.0 ** -53  # unit roundoff of doubles


def mesh_links(tris: np.ndarray, normals: np.ndarray, tol: float = 1e-9):
    """(planes (T, 4): each triangle's outward unit normal and offset, vertices (V, 3), the
    triangles' vertex indices (T, 3), neighbours (T, 3): the triangle across edge k, from vertex k
    to vertex k + 1) of a closed convex triangle soup, its vertices merged within `tol` of its size
    (a sphere's seam repeats vertices a rounding apart); None unless every edge is shared by exactly
    two triangles."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    pts = tris.reshape(-1, 3)
    size = float(np.max(np.abs(pts))) or 1.0
    pairs = cKDTree(pts).query_pairs(tol * size, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(pts), len(pts)))
    _, label = connected_components(graph, directed=False)
    _, first, inv = np.unique(label, return_index=True, return_inverse=True)
    verts = pts[first]
    tv = inv.reshape(-1, 3).astype(np.int64)
    if np.any((tv[:, 0] == tv[:, 1]) | (tv[:, 1] == tv[:, 2]) | (tv[:, 2] == tv[:, 0])):
        return None  # a triangle collapsed to an edge
    n_tri = len(tv)
    a = tv.ravel()
    b = tv[:, [1, 2, 0]].ravel()
    key = np.minimum(a, b) * len(verts) + np.maximum(a, b)
    order = np.argsort(key, kind="stable")
    k = key[order]
    if len(k) % 2 or np.any(k[0::2] != k[1::2]) or np.any(k[1:-1:2] == k[2::2]):
        return None  # an edge met once, or by more than two triangles
    nbr = np.empty(3 * n_tri, dtype=np.int64)
    first, second = order[0::2], order[1::2]
    nbr[first], nbr[second] = second // 3, first // 3
    centre = verts.mean(axis=0)
    n = normals * np.where(np.einsum("ij,ij->i", normals, centre - tris[:, 0]) > 0.0, -1.0, 1.0)[:, None]
    planes = np.column_stack([n, np.einsum("ij,ij->i", n, tris[:, 0])])
    return np.ascontiguousarray(planes), verts, tv, nbr.reshape(n_tri, 3)


def pieces(links, geo, directional, end, start):
    """(offsets (N + 1,), counts (N,), breakpoints bt, facets bf) of `walk` over the segments of `geo`
    (N rows) on the mesh `links` (`mesh_links`), from the facets `start` met at their middles."""
    planes, verts, tv, nbr = links
    n = len(end)
    tm = 0.5 * end
    rows = np.ascontiguousarray(geo[:, :9])
    start = np.where(end > 0.0, start, -1).astype(np.int64)
    counts = np.empty(n, dtype=np.int64)
    offsets = np.zeros(n + 1, dtype=np.int64)
    inside = np.zeros(n, dtype=np.bool_)  # whether each segment's point light lies inside the shape: per
    if not directional and n:  # light, against every face plane (Embree's facet may be a neighbour's)
        lights, which = np.unique(rows[:, 6:9], axis=0, return_inverse=True)
        inside = np.all(lights @ planes[:, :3].T <= planes[:, 3], axis=1)[which.ravel()]
    walk(verts, tv, nbr, planes, rows, directional, end, start, tm, inside, offsets, False, np.empty(0),
         np.empty(0, np.int64), counts)
    offsets[1:] = np.cumsum(np.maximum(counts, 0))
    bt = np.empty(offsets[-1])
    bf = np.empty(offsets[-1] + n, dtype=np.int64)
    walk(verts, tv, nbr, planes, rows, directional, end, start, tm, inside, offsets, True, bt, bf, counts)
    return offsets, counts, bt, bf


@njit
def _frame(g, tm, directional):
    """The constants of one segment's walk (a `geo` row g, its middle tm): the entry point o, the
    direction w, the light l (a position, or the unit direction toward it), the cutting plane's
    normal n (w x l, or (o - l) x w) and, for a point light, the direction a from the light to the
    middle; and whether the plane exists (not when the light lies on the camera line: then every
    path leaves through one point)."""
    o = (g[0], g[1], g[2])
    w = (g[3], g[4], g[5])
    light = (g[6], g[7], g[8])
    v = (-light[0], -light[1], -light[2]) if directional else (o[0] - light[0], o[1] - light[1], o[2] - light[2])
    n = _cross(v, w)
    a = (o[0] + tm * w[0] - light[0], o[1] + tm * w[1] - light[1], o[2] + tm * w[2] - light[2])
    return (o, w, light, n, a), math.sqrt(_dot(n, n)) > 1e-12 * math.sqrt(_dot(v, v))


@njit(inline="always")
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(inline="always")
def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit
def _place(q, frame, directional):
    """(key, t) of the point q of the cut polygon: t, the camera-line parameter whose light path
    passes through q, and a key that grows along the polygon as t does. For a directional light
    the key is t. For a point light t wraps through infinity along the polygon (where the path
    from the light runs parallel to the camera line), so the key is the angle at the light from
    the direction a to the segment's middle: within the light's view of the shape it never wraps."""
    o, w, light, n, a = frame
    if directional:  # q = o + t w + s l: t = ((q - o) x l) . n / |n|^2
        t = _dot(_cross((q[0] - o[0], q[1] - o[1], q[2] - o[2]), light), n) / _dot(n, n)
        return t, t
    # l + s (q - l) = o + t w: t = ((l - o) x u) . n / ((w x u) . n), u = q - l
    u = (q[0] - light[0], q[1] - light[1], q[2] - light[2])
    den = _dot(_cross(w, u), n)
    if den == 0.0 or _dot(u, u) == 0.0:  # the light on the polygon, or the path parallel to the line
        return math.nan, math.nan  # the walk is not sound there (`_step`)
    t = _dot(_cross((light[0] - o[0], light[1] - o[1], light[2] - o[2]), u), n) / den
    return math.atan2(_dot(_cross(a, u), n) / math.sqrt(_dot(n, n)), _dot(a, u)), t


@njit
def _sides(verts, tv, tri, frame, side):
    """side[v] for the vertices of tri: on the positive side of the cutting plane (0 counts as +)."""
    o, n = frame[0], frame[3]
    for k in range(3):
        v = tv[tri, k]
        side[v] = n[0] * (verts[v, 0] - o[0]) + n[1] * (verts[v, 1] - o[1]) + n[2] * (verts[v, 2] - o[2]) >= 0.0


@njit
def _faces(planes, tri, light, directional):
    """Whether facet tri faces the light: every exit toward it lies on such a facet."""
    n = (planes[tri, 0], planes[tri, 1], planes[tri, 2])
    return _dot(n, light) > 0.0 if directional else _dot(n, light) > planes[tri, 3]


@njit
def _is_cut(verts, tv, planes, tri, frame, directional, side):
    """Whether the cutting plane cuts tri, and tri faces the light (the exits lie on that side of
    the cut polygon; the other side is where paths from the light would leave)."""
    if not _faces(planes, tri, frame[2], directional):
        return False
    _sides(verts, tv, tri, frame, side)
    return not (side[tv[tri, 0]] == side[tv[tri, 1]] == side[tv[tri, 2]])


@njit
def _cut_near(verts, tv, nbr, planes, tri, frame, directional, side):
    """`tri` if the cutting plane cuts it on the light's side, else the first of its neighbours and
    theirs that it cuts there (a facet found beside an edge or vertex the plane passes near, or the
    coplanar twin of the facet the plane cuts); -1 if none is."""
    if _is_cut(verts, tv, planes, tri, frame, directional, side):
        return tri
    for k in range(3):
        if _is_cut(verts, tv, planes, nbr[tri, k], frame, directional, side):
            return nbr[tri, k]
    for k in range(3):
        for m in range(3):
            b = nbr[nbr[tri, k], m]
            if b != tri and _is_cut(verts, tv, planes, b, frame, directional, side):
                return b
    return -1


@njit
def _step(verts, tv, nbr, tri, came, direction, frame, directional, side):
    """(key, t, edge) of the edge of tri through which the cut polygon leaves it in `direction` of
    the key (+1: toward the segment's end), not back into `came`; edge -1 if the plane cuts none."""
    o, n = frame[0], frame[3]
    _sides(verts, tv, tri, frame, side)
    best, best_t, edge = math.nan, math.nan, -1
    for k in range(3):
        if nbr[tri, k] == came:
            continue
        i, j = tv[tri, k], tv[tri, (k + 1) % 3]
        if side[i] == side[j]:
            continue
        si = n[0] * (verts[i, 0] - o[0]) + n[1] * (verts[i, 1] - o[1]) + n[2] * (verts[i, 2] - o[2])
        sj = n[0] * (verts[j, 0] - o[0]) + n[1] * (verts[j, 1] - o[1]) + n[2] * (verts[j, 2] - o[2])
        f = si / (si - sj)
        q = (verts[i, 0] + f * (verts[j, 0] - verts[i, 0]), verts[i, 1] + f * (verts[j, 1] - verts[i, 1]),
             verts[i, 2] + f * (verts[j, 2] - verts[i, 2]))
        key, t = _place(q, frame, directional)
        if not math.isfinite(key):
            return math.nan, math.nan, -1
        if edge < 0 or direction * key > direction * best:
            best, best_t, edge = key, t, k
    return best, best_t, edge


END = 1e-12  # a crossing this close to a segment's end, relative to its length, is its end
SEEK = 64  # steps along the cut polygon from the facet found to the one that holds the middle's exit


@njit
def _locate(verts, tv, nbr, planes, tri, target, frame, directional, side):
    """The facet of the cut polygon whose stretch of keys holds `target` (the key of the middle's
    exit point), walked to from the cut facet tri (Embree's facet may be a neighbour, or the coplanar
    twin cut elsewhere); -1 if not reached within SEEK steps."""
    for _ in range(SEEK):
        if not _faces(planes, tri, frame[2], directional):
            return -1  # stepped off the arc of exits (keys tie where the plane touches a vertex)
        lo, _, e_lo = _step(verts, tv, nbr, tri, -1, -1.0, frame, directional, side)
        hi, _, e_hi = _step(verts, tv, nbr, tri, -1, 1.0, frame, directional, side)
        if e_lo < 0:
            return -1
        if lo <= target <= hi:
            return tri
        tri = nbr[tri, e_lo] if target < lo else nbr[tri, e_hi]
    return -1


@njit
def walk(verts, tv, nbr, planes, geo, directional, ell, start, tm, inside, offsets, fill, bt, bf, counts):
    """The exit facets along each camera segment s of `geo` (rows: entry point, direction w, the
    light's position or, with `directional`, the unit direction toward it) over [0, ell[s]], from
    the facet start[s] met at tm[s] (inside[s]: the point light lies inside the shape): the
    ascending breakpoints in (0, ell) go to bt and the facets of the pieces between them to bf, from
    offsets[s] (bf holds one more per segment, at offsets[s] + s), when `fill`; counts[s] gets the
    number of breakpoints, or -1 where the walk is not sound (no facet cut by the plane near the
    start, no neighbour, breakpoints out of order, a facet that does not face the light, the light
    on the cut polygon): that segment keeps its exits from Embree. Called twice: to count (not
    `fill`), then, with the offsets of those counts, to fill the segments counted."""
    side = np.zeros(verts.shape[0], dtype=np.bool_)
    for s in range(geo.shape[0]):
        if fill and counts[s] < 0:
            continue
        counts[s] = -1
        if start[s] < 0:
            continue
        frame, cut = _frame(geo[s], tm[s], directional)
        if not cut:
            counts[s] = 0
            if fill:
                bf[offsets[s] + s] = start[s]
            continue
        o, w = frame[0], frame[1]
        k0 = _place(o, frame, directional)[0]
        k1 = _place((o[0] + ell[s] * w[0], o[1] + ell[s] * w[1], o[2] + ell[s] * w[2]), frame, directional)[0]
        sense = 1.0 if k1 >= k0 else -1.0  # the key's direction toward the segment's end
        st = start[s]
        if inside[s]:
            counts[s] = 0  # the light is inside: no path leaves, any facet's plane lies beyond it
            if fill:
                bf[offsets[s] + s] = st
            continue
        first = _cut_near(verts, tv, nbr, planes, st, frame, directional, side)
        if first >= 0:
            first = _locate(verts, tv, nbr, planes, first, tm[s] if directional else 0.0, frame, directional, side)
        if first < 0:
            continue
        n_back, n_fwd = 0, 0
        sound = True
        for direction in (-1.0, 1.0):  # backward first, so that bt fills in ascending order
            tri, came, last = first, -1, math.nan
            stop = k0 if direction < 0.0 else k1
            while True:
                key, t, edge = _step(verts, tv, nbr, tri, came, direction * sense, frame, directional, side)
                if edge < 0:
                    sound = False
                    break
                if direction * sense * (key - stop) >= 0.0 or (t <= END * ell[s] if direction < 0.0
                                                               else t >= (1.0 - END) * ell[s]):
                    break  # past the end, or on it within rounding (an edge through the entry point)
                if direction * sense * (key - last) < 0.0 or not _faces(planes, nbr[tri, edge], frame[2], directional):
                    sound = False  # breakpoints out of order, or off the arc of exits
                    break
                if direction > 0.0:
                    if fill:
                        at = offsets[s] + n_back + n_fwd
                        bt[at] = t
                        bf[at + s + 1] = nbr[tri, edge]
                    n_fwd += 1
                else:
                    n_back += 1
                last, came, tri = key, tri, nbr[tri, edge]
            if not sound:
                break
            if direction < 0.0 and fill:  # the backward steps again, written in ascending order
                tri, came = first, -1
                bf[offsets[s] + s + n_back] = first
                for step in range(n_back):
                    key, t, edge = _step(verts, tv, nbr, tri, came, -sense, frame, directional, side)
                    at = offsets[s] + n_back - 1 - step
                    bt[at] = t
                    came, tri = tri, nbr[tri, edge]
                    bf[at + s] = tri
        if sound:
            counts[s] = n_back + n_fwd


@njit
def exit_lengths(seg, x, p, to, dist, offsets, counts, bt, bf, planes, reach, out, err):
    """out[i] = the length of the path from p[i] (at x[i] on segment seg[i]) along the unit to[i]
    to where it leaves the convex mesh, at most dist[i]: the least distance to the planes of the
    facet of the piece holding x[i] and of its neighbours in the walk (`walk`'s bt, bf), which
    contain the exit plane (a convex shape's exit is the nearest plane ahead; a node a rounding
    away from a breakpoint finds it among the neighbours). err[i] bounds its rounding: the plane's
    offset and the dot products, and the plane's normal (a few u off its triangle's) tilted about a
    vertex within `reach` (the largest vertex norm) of the origin, 16u (|p| + k + reach) / cos with
    cos the exit plane's cosine to the path (0 where the path ends at dist first)."""
    for i in range(seg.shape[0]):
        s = seg[i]
        lo, m = offsets[s], counts[s]
        j = np.searchsorted(bt[lo:lo + m], x[i])
        k = dist[i]
        at = 0.0
        for c in range(max(j - 1, 0), min(j + 2, m + 1)):
            f = bf[lo + s + c]
            cos = planes[f, 0] * to[i, 0] + planes[f, 1] * to[i, 1] + planes[f, 2] * to[i, 2]
            if cos > 0.0:
                h = planes[f, 3] - planes[f, 0] * p[i, 0] - planes[f, 1] * p[i, 1] - planes[f, 2] * p[i, 2]
                if max(h, 0.0) / cos < k:
                    k, at = max(h, 0.0) / cos, cos
        out[i] = k
        norm = math.sqrt(p[i, 0] * p[i, 0] + p[i, 1] * p[i, 1] + p[i, 2] * p[i, 2])
        err[i] = 16.0 * U * (norm + k + reach) / at if at > 0.0 else 0.0
