"""The shapes that hold a medium: which they are (`interiors`, `matched`: index-matched ones, `enters`), whether a
point lies inside one (`inside_of`), their face planes, cached per shape (`hull_planes` of a convex shape,
`convex_planes` for media/slab.py's convex kernel, `refracting_planes` of a convex refractive one, the faces'
`triangle_planes` and `plane_neighbours`, and how far the planes may be from the faces: `plane_errors`,
`measured_plane_errors`), what stops and what attenuates light among their triangles (`blockers`,
`attenuators`, `shadow_through`), and the step off a face a ray leaves by (`nudge`)."""
from __future__ import annotations

import math

import numpy as np

from ..scene.meshes import PLANE_DECIMALS
from ..scene.meshes import convex_planes as hull_of
from . import paths

# face planes of a convex shape up to which media/slab.py's kernel (every plane at every evaluation) is
# used; beyond, Embree's batched exits are faster (equal at ~120 planes: benchmarks/interiors_scale.py)
KERNEL_PLANES = 64


def interiors(scene) -> list:
    """The interior medium of each shape (None for plain surfaces)."""
    return [s.interior for s in scene.shapes]


def matched(prep) -> list[int]:
    """The shapes whose interior is index-matched (ior = 1): light crosses them straight, attenuated."""
    if prep.interior_shapes is None:
        return []
    return [int(i) for i in prep.interior_shapes if prep.scene.shapes[i].interior.ior == 1.0]


def enters(prep, prim) -> np.ndarray:
    """Which first hits `prim` (triangle ids, -1 for a miss) are on a shape holding a medium."""
    if prep.interior_shapes is None or not len(prep.interior_shapes):
        return np.zeros(len(prim), dtype=bool)
    return (prim >= 0) & np.isin(prep.shape_ids[np.maximum(prim, 0)], prep.interior_shapes)


def blockers(prep) -> np.ndarray | None:
    """The triangles that stop light (a mask over prep.accel.triangles; None: all of them): opaque
    surfaces and refractive interiors' boundaries (a refracted shadow would be a caustic, beyond
    single scattering), not index-matched interiors' boundaries, which attenuate it (`attenuators`)."""
    inner = matched(prep)
    return ~np.isin(prep.shape_ids, inner) if inner else None


def attenuators(prep) -> np.ndarray | None:
    """The index-matched interiors' triangles (a mask; None where the outside air-light never needs
    them: no such interior, or an outside medium that does not scatter)."""
    inner = matched(prep)
    if not inner or not prep.scene.medium.scatters:
        return None
    return np.isin(prep.shape_ids, inner)


def inside_of(prep, o, inner) -> int | None:
    """The first shape of `inner` that contains the point o (`paths.contains`), else None."""
    return next((i for i in inner if paths.contains(prep, o, i)), None)


def hull_planes(prep, sid):
    """The face planes (P, 4) of shape sid if it is convex (scene/meshes.py convex_planes), else
    None; cached on `prep` (paths.py reads the cache for index-matched shapes). An exact
    sphere has none: its light paths are its closed-form chords (paths.boundary, media/convex_chords.py),
    without facet kinks."""
    cache = prep.interior_planes
    if sid not in cache:
        sel = prep.shape_ids == sid
        exact = paths.exact_sphere(prep, sid) is not None
        cache[sid] = None if exact else hull_of(prep.accel.triangles[sel], prep.accel.normals[sel])
    return cache[sid]


def convex_planes(prep, sid):
    """The face planes (P, 4: outward unit normal, offset) of shape `sid` for media/slab.py's convex
    kernel, which tests every plane at every integrand evaluation: those of a convex shape with at
    most KERNEL_PLANES of them, else an empty (0, 4) array (then an index-matched shape's light paths
    are measured with Embree, paths.py: batched exits for convex shapes, walks for others; a
    refractive one's lights take `refracting_planes`)."""
    planes = hull_planes(prep, sid)
    return planes if planes is not None and len(planes) <= KERNEL_PLANES else np.zeros((0, 4))


def refracting_planes(prep, sid):
    """The face planes of a convex refractive shape sid, any number of them, else an empty (0, 4)
    array: point and spot lights reach its inside through every face they are outside of on Fermat's
    paths (media/slab.py `faces_point`), each segment's faces culled to those whose refraction point
    can lie on them (`reachable_faces`) and the planes those need; beyond KERNEL_PLANES planes a
    directional light through every face it meets, each beam over the interval its face's neighbours
    leave lit (interiors/rows.py `_face_beams`)."""
    planes = hull_planes(prep, sid)
    refractive = prep.scene.shapes[sid].interior.ior != 1.0
    return planes if planes is not None and refractive else np.zeros((0, 4))


def triangle_planes(tris, planes):
    """The triangles (T, 3, 3) of nonzero area among `tris`, their unit normals turned outward (away
    from the vertices' mean, inside a convex shape) and the row of `planes` (P, 4) each lies in: the
    nearest by normal and offset / size (a k-d tree, as scene/meshes.py convex_planes finds them)."""
    from scipy.spatial import cKDTree

    tris = np.asarray(tris, dtype=np.float64)
    cross = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    area = np.linalg.norm(cross, axis=1)
    tris, n = tris[area > 0.0], cross[area > 0.0] / area[area > 0.0, None]
    size = max(float(np.abs(tris).max(initial=0.0)), 1e-300)
    centre = tris.reshape(-1, 3).mean(axis=0) if len(tris) else np.zeros(3)
    n *= np.where(np.einsum("ij,ij->i", n, tris[:, 0] - centre) < 0.0, -1.0, 1.0)[:, None]
    if not len(tris) or not len(planes):
        return tris, n, np.zeros(len(tris), np.int64)
    keys = np.column_stack([n, np.einsum("ij,ij->i", n, tris[:, 0]) / size])
    return tris, n, cKDTree(np.column_stack([planes[:, :3], planes[:, 3] / size])).query(keys)[1].astype(np.int64)


def plane_neighbours(prep, sid):
    """For each face plane f of the convex shape sid (`hull_planes`), the other planes through a corner
    of its face, packed in one int64 array `near`: near[near[f]:near[f + 1]] (starts offset by P + 1);
    empty where the shape has none. They are the planes of the triangles that share a vertex (within
    1e-9 of the shape's size) with a triangle of plane f (a triangle lies in every plane within 1e-9 of
    its normal and offset / size: planes that differ by rounding alone share its corners). The face is
    its plane's points inside the planes of its edges, each through two of its corners: the face test
    needs these alone, and media/slab.py `reachable_faces` reads no other plane (a plane with fewer
    than three of them, which no face of a closed solid has, takes every plane)."""
    def build():
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components
        from scipy.spatial import cKDTree

        planes = hull_planes(prep, sid)
        if planes is None or not len(planes):
            return np.zeros(0, np.int64)
        tris, n, _ = triangle_planes(prep.accel.triangles[prep.shape_ids == sid], planes)
        pts = tris.reshape(-1, 3)
        size = max(float(np.abs(pts).max(initial=0.0)), 1e-300)
        keys = np.column_stack([n, np.einsum("ij,ij->i", n, tris[:, 0]) / size])
        tree = cKDTree(np.column_stack([planes[:, :3], planes[:, 3] / size]))
        lists = tree.query_ball_point(keys, 1e-9)  # every plane a triangle lies in (planes equal but for rounding)
        tri = np.repeat(np.arange(len(tris)), [len(ids) for ids in lists])
        plane = np.concatenate([np.asarray(ids, np.int64) for ids in lists] + [np.zeros(0, np.int64)])
        pairs = cKDTree(pts).query_pairs(1e-9 * size, output_type="ndarray")
        same = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(pts), len(pts)))
        corner = connected_components(same, directed=False)[1].reshape(-1, 3)
        touch = coo_matrix((np.ones(3 * len(tri)), (corner[tri].ravel(), np.repeat(plane, 3))),
                           shape=(corner.max() + 1, len(planes))).tocsr()
        touch.data[:] = 1.0
        adj = (touch.T @ touch).tolil()
        adj.setdiag(0.0)
        adj = adj.tocsr()
        adj.eliminate_zeros()
        lists = [np.sort(adj.indices[adj.indptr[f]:adj.indptr[f + 1]]) for f in range(len(planes))]
        every = np.arange(len(planes))
        lists = [every[every != f] if len(ids) < 3 else ids for f, ids in enumerate(lists)]
        starts = len(planes) + 1 + np.concatenate([[0], np.cumsum([len(ids) for ids in lists])])
        return np.concatenate([starts] + lists).astype(np.int64)
    return prep.memo(("plane neighbours", sid), build)


def shadow_through(prep):
    """The shading's `through(li, points)` for a scene with index-matched interiors (else None): the
    transmittance toward light li of the interiors the straight shadow path crosses,
    exp(-(sigma_t inside - sigma_t outside) x length inside) each (the outside's own transmittance is
    the shading's); 0 where an opaque surface or a refractive interior blocks it (a refracted shadow
    would be a caustic, beyond single scattering). A light inside an interior: the path's length in it
    runs from the light."""
    inner = matched(prep)
    if not inner:
        return None
    kt = np.array([prep.scene.shapes[i].interior.sigma_t for i in inner]) - prep.scene.medium.sigma_t[None, :]
    lights = prep.lights

    def through(li, points):
        if lights.distant[li]:
            dirs = np.broadcast_to(-lights.axis[li], points.shape)
            dist = np.full(len(points), np.inf)
        else:
            rel = lights.position[li] - points
            dist = np.linalg.norm(rel, axis=1)
            dirs = rel / dist[:, None]
        holds = prep.memo(("holding light", li), lambda: np.array(
            [not lights.distant[li] and inside_of(prep, lights.position[li], [sid]) is not None for sid in inner]))
        lengths, blocked = paths.inside_lengths(prep, points, dirs, dist, inner, block=True, margin=prep.accel.epsilon,
                                                far_inside=np.broadcast_to(holds, (len(points), len(inner))))
        return np.where(blocked[:, None], 0.0, np.exp(-lengths @ kt))
    return through


def nudge(accel, points, dirs, cos):
    """Points moved along their rays (cosine `cos` to the face they leave) to about accel.epsilon off
    the face: the ray's line is kept, so what it meets beyond is exactly what the unmoved ray meets."""
    return points + (accel.epsilon / np.maximum(cos, 1e-2))[:, None] * dirs


def plane_errors(prep, sid):
    """(dn, dc): how far the convex planes of shape sid (scene/meshes.py convex_planes: normals and
    offsets / size rounded to PLANE_DECIMALS, size the largest coordinate) may be from its faces' own
    planes, on the normals (each of three components) and on the offsets, with a few ulps more."""
    half = 0.5 * 10.0 ** -PLANE_DECIMALS
    size = float(np.max(np.abs(prep.accel.triangles[prep.shape_ids == sid]), initial=0.0))
    return np.array([math.sqrt(3.0) * half + 1e-15, (half + 1e-15) * size])


def measured_plane_errors(prep, sid):
    """(dn, dc) as `plane_errors`, measured on the shape's triangles (the planes' errors in every convex
    kernel's bound: media/slab.py, media/fermat_rounding.py, shadows/through_others.py): each triangle's unit
    normal (its cross product's, a few ulps off: + 8u) and vertices against the plane of `hull_planes` it lies in
    (the nearest by normal and offset); dn the largest difference of a normal component, dc the largest |n·v - c|
    plus sqrt(3) dn |v| (the plane turned about the origin) and 8u (|c| + |v|) (shapes.py
    `triangle_planes`: the normal turned outward, as the planes'), for index-matched and refractive
    shapes alike. `plane_errors` where the shape has no convex planes. The measured errors may exceed
    `plane_errors` (which bounds the rounding of one triangle's plane alone): the hull keeps one plane for
    faces within 1e-9 of each other (the two triangles of a quad whose corners round off one plane:
    1.2e-12 on a 256-segment UV sphere, 1.7e-12 on a 320-face icosphere)."""
    def measure():
        planes = hull_planes(prep, sid)
        bound = plane_errors(prep, sid)
        if planes is None:
            return bound
        tris, n, best = triangle_planes(prep.accel.triangles[prep.shape_ids == sid], planes)
        if not len(planes) or not len(tris):
            return bound
        off = np.abs(np.einsum("tvk,tk->tv", tris, planes[best, :3]) - planes[best, 3, None]).max(axis=1)
        u = 2.0 ** -53
        dn_f = np.abs(n - planes[best, :3]).max(axis=1) + 8.0 * u
        norms = np.linalg.norm(tris, axis=2).max(axis=1)
        dc_f = off + math.sqrt(3.0) * dn_f * norms + 8.0 * u * (np.abs(planes[best, 3]) + norms)
        return np.array([dn_f.max(), dc_f.max()])
    return prep.memo(("measured plane errors", sid), measure)
