"""Triangles for a scene: meshes through trimesh (OBJ/MTL, PLY, GLB) and procedural primitives.

Everything ends as float64 arrays: triangle corners (T, 3, 3) and a diffuse reflectance per
triangle (T, 3). MTL diffuse colours (Kd) and glTF base colours become reflectances. With
`normals=True`, `scene_triangles` also gives each triangle's corner shading normals (T, 3, 3), on the
side of its winding (the geometric normal's), or None when every shape is flat: a shape's `smooth`
(default true) gives spheres their exact normals (corner - centre) / radius, cylinder sides the radial
direction, meshes the file's vertex normals or, where the file has none, normals smoothed across edges
sharper than CREASE_DEGREES (`crease_normals`), `triangles` their `normals` (pbrt's "N"); boxes, quads,
cylinder caps and `triangles` without normals (as pbrt renders a mesh without "N") stay flat.
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import UserError, counted
from ..geometry.vectors import perpendicular, rotation_matrix
from .assets import find_asset
from .format import Scene, Shape, Transform, apply_transform, world_sphere

DEFAULT_REFLECTANCE = 0.5
CREASE_DEGREES = 30.0  # a mesh without normals is smoothed across edges flatter than this (Blender's auto smooth)


def box_triangles(lo, hi):
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    c = np.array([[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
                  [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]], dtype=np.float64)
    quads = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (3, 7, 6, 2), (0, 4, 7, 3), (1, 2, 6, 5)]
    return np.concatenate([quad_triangles(c[list(q)]) for q in quads])


def quad_triangles(corners):
    c = np.asarray(corners, dtype=np.float64)
    return np.stack([c[[0, 1, 2]], c[[0, 2, 3]]])


def sphere_triangles(center, radius, segments):
    rings = max(2, segments // 2)
    th = np.linspace(0.0, math.pi, rings + 1)
    ph = np.linspace(0.0, 2.0 * math.pi, segments + 1)
    grid = np.stack([np.sin(th)[:, None] * np.cos(ph)[None, :],
                     np.cos(th)[:, None] * np.ones_like(ph)[None, :],
                     np.sin(th)[:, None] * np.sin(ph)[None, :]], axis=-1) * radius + center
    tris = []
    for i in range(rings):
        for j in range(segments):
            a, b, c, d = grid[i, j], grid[i, j + 1], grid[i + 1, j + 1], grid[i + 1, j]
            if i > 0:
                tris.append((a, b, c))
            if i < rings - 1:
                tris.append((a, c, d))
    return np.array(tris)


def cylinder_triangles(base, top, radius, segments):
    axis = top - base
    length = np.linalg.norm(axis)
    if length == 0.0:
        raise ValueError("cylinder base equals top")
    a = axis / length
    u = perpendicular(a)
    w = np.cross(a, u)
    ang = np.linspace(0.0, 2.0 * math.pi, segments + 1)
    ring = radius * (np.cos(ang)[:, None] * u + np.sin(ang)[:, None] * w)
    tris = []
    for j in range(segments):
        p0, p1 = base + ring[j], base + ring[j + 1]
        q0, q1 = top + ring[j], top + ring[j + 1]
        tris += [(p0, p1, q1), (p0, q1, q0), (base, p1, p0), (top, q0, q1)]
    return np.array(tris)


def sphere_normals(tris, center, radius):
    """The exact sphere's unit normals (corner - centre) / radius at the corners (T, 3, 3)."""
    return (tris - center) / radius


def cylinder_normals(tris, base, top):
    """Corner normals of `cylinder_triangles`: the radial direction on the sides, the caps flat."""
    a = (top - base) / np.linalg.norm(top - base)
    rel = tris - base
    out = rel - (rel @ a)[..., None] * a
    caps = np.arange(len(tris)) % 4 >= 2  # (base, p1, p0), (top, q0, q1) of each segment
    out[~caps] /= np.linalg.norm(out[~caps], axis=-1, keepdims=True)
    out[caps] = flat_normals(tris[caps])[:, None, :]
    return out


def flat_normals(tris):
    """Each triangle's unit geometric normal (T, 3) (its winding's; zero for a degenerate one)."""
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.where(length > 0.0, length, 1.0)


def _merged_ids(tris):
    """An id per corner (T * 3,): equal where the corners' coordinates agree to 1e-9 of the soup's size."""
    pts = tris.reshape(-1, 3)
    size = float(np.max(np.abs(pts))) or 1.0
    keys = np.ascontiguousarray(np.round(pts / (1e-9 * size)) + 0.0)  # + 0.0: -0.0 becomes 0.0
    return np.unique(keys.view(np.dtype((np.void, 24))).ravel(), return_inverse=True)[1].ravel()  # rows as bytes


def crease_normals(tris, degrees: float = CREASE_DEGREES):
    """Corner normals (T, 3, 3) of a triangle soup smoothed as Blender's auto smooth: at each corner
    the area-weighted mean of the normals of the triangles that share its vertex (coordinates merged,
    `_merged_ids`) and whose normal is within `degrees` of the corner's own triangle's; a unit vector,
    the triangle's own normal exactly where that mean is it to rounding (flat parts stay flat)."""
    area_n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    unit = flat_normals(tris)
    ids = _merged_ids(tris)
    order = np.argsort(ids, kind="stable")
    _, start, count = np.unique(ids[order], return_index=True, return_counts=True)
    group = np.repeat(np.arange(len(start)), count)  # the vertex of each sorted corner
    per = count[group]  # pairs per sorted corner: every corner of its vertex
    corner = np.repeat(np.arange(len(order)), per)
    first = np.repeat(np.cumsum(per) - per, per)
    partner = start[group][np.repeat(np.arange(len(order)), per)] + np.arange(len(corner)) - first
    f, g = order[corner] // 3, order[partner] // 3
    keep = np.einsum("ij,ij->i", unit[f], unit[g]) >= math.cos(math.radians(degrees))
    acc = np.zeros((len(ids), 3))
    for k in range(3):
        acc[:, k] = np.bincount(order[corner], weights=np.where(keep, area_n[g, k], 0.0), minlength=len(ids))
    acc /= np.maximum(np.linalg.norm(acc, axis=1, keepdims=True), np.finfo(float).tiny)
    own = np.repeat(unit, 3, axis=0)
    flat = np.linalg.norm(acc - own, axis=1) < 1e-12  # a corner amid coplanar triangles: exactly its facet's
    acc[flat] = own[flat]
    return acc.reshape(-1, 3, 3)


def _normal_matrix(t: Transform):
    """What normals (as rows) are multiplied by under `apply_transform`: the inverse transpose of its
    linear part (the scale is never 0: format.py refuses it), up to a positive factor."""
    return (rotation_matrix(t.rotate) / t.scale[None, :]).T


def _mesh_colour(geom) -> np.ndarray | None:
    mat = getattr(getattr(geom, "visual", None), "material", None)
    for attr in ("diffuse", "baseColorFactor", "main_color"):
        c = getattr(mat, attr, None)
        if c is not None:
            c = np.asarray(c, dtype=np.float64)[:3]
            return c / 255.0 if c.max() > 1.0 or np.asarray(getattr(mat, attr)).dtype == np.uint8 else c
    return None


def _first_bad_vertex(path) -> str:
    """", first at line N" for the first OBJ vertex line (v x y z) with a nan or inf, else ""."""
    if path.suffix.lower() != ".obj":
        return ""
    with open(path, "rb") as f:
        for n, line in enumerate(f, 1):
            parts = line.split()
            if parts[:1] == [b"v"]:
                try:
                    values = [float(x) for x in parts[1:4]]
                except ValueError:
                    continue
                if not all(np.isfinite(values)):
                    return f", first at line {n}: {line.decode(errors='replace').strip()}"
    return ""


def load_mesh(shape: Shape, scene: Scene, key: str, normals: bool = True):
    """The mesh's triangles (T, 3, 3), reflectances (T, 3) and corner normals (T, 3, 3; None unless
    `normals`): the file's vertex normals (OBJ `vn`, PLY nx/ny/nz, glTF NORMAL: trimesh keeps them when
    the file has them), else `crease_normals`; each geometry's node transform applied (normals by its
    inverse transpose)."""
    import trimesh

    path = find_asset(shape.params["mesh"], scene.path, f"{key}.mesh")
    try:
        loaded = trimesh.load(str(path), force="scene", process=False)
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise UserError(f"{path}: {key}.mesh: cannot read mesh ({type(exc).__name__}: {exc}); "
                        "export it as OBJ, PLY or GLB") from None
    tris, refl, corners = [], [], []
    for node in loaded.graph.nodes_geometry:
        transform, geom_name = loaded.graph[node]
        geom = loaded.geometry[geom_name]
        if not hasattr(geom, "faces") or len(geom.faces) == 0:
            continue
        v = np.asarray(geom.vertices, dtype=np.float64)
        if not np.all(np.isfinite(v)):
            raise UserError(f"{path}: {key}.mesh: "
                            f"{counted(int(np.sum(~np.all(np.isfinite(v), axis=1))), 'vertex is', 'vertices are')} not "
                            f"finite (nan or inf){_first_bad_vertex(path)}; fix or remove them in the file")
        v = v @ transform[:3, :3].T + transform[:3, 3]
        t = v[np.asarray(geom.faces)]
        tris.append(t)
        if normals and "vertex_normals" in geom._cache:  # from the file (else trimesh computes them lazily)
            vn = np.asarray(geom.vertex_normals, dtype=np.float64) @ np.linalg.pinv(transform[:3, :3])
            corners.append(vn[np.asarray(geom.faces)])
        elif normals:
            corners.append(crease_normals(t))
        colour = _mesh_colour(geom)
        refl.append(np.broadcast_to(colour if colour is not None else DEFAULT_REFLECTANCE, (len(t), 3)))
    if not tris:
        raise UserError(f"{path}: the mesh holds no triangles; check the file or {key}.mesh")
    return np.concatenate(tris), np.concatenate(refl), np.concatenate(corners) if normals else None


def boundary_edges(tris: np.ndarray) -> int:
    """The edges of a triangle soup used by an odd number of triangles (vertices merged where their
    coordinates agree to 1e-9 of the soup's size): 0 for a closed surface."""
    ids = _merged_ids(tris).reshape(-1, 3)
    edges = np.sort(np.concatenate([ids[:, [0, 1]], ids[:, [1, 2]], ids[:, [2, 0]]]), axis=1)
    edges = edges[edges[:, 0] != edges[:, 1]]  # collapsed edges of degenerate triangles (a sphere's poles)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return int(np.sum(counts % 2))


PLANE_DECIMALS = 12  # convex_planes rounds normals and offsets / size to these decimals (so that equal planes merge)


def convex_planes(tris: np.ndarray, normals: np.ndarray, tol: float = 1e-9) -> np.ndarray | None:
    """The distinct face planes (P, 4: outward unit normal, offset) of a closed triangle soup (unit
    `normals`, either orientation) if it bounds a convex solid, else None. Convex means every
    triangle's plane, turned away from the vertices' mean, supports the vertex set: then it is the
    plane of a facet of their convex hull (Qhull through scipy.spatial.ConvexHull), found by a k-d
    tree on (normal, offset / size) to `tol`: time O(T log T) and memory linear in T."""
    from scipy.spatial import ConvexHull, QhullError, cKDTree

    pts = tris.reshape(-1, 3)
    size = float(np.max(np.abs(pts))) or 1.0
    centre = pts.mean(axis=0)
    n = normals * np.where(np.einsum("ij,ij->i", normals, centre - tris[:, 0]) > 0.0, -1.0, 1.0)[:, None]
    faces = np.column_stack([n, np.einsum("ij,ij->i", n, tris[:, 0]) / size])
    try:
        hull = ConvexHull(np.unique(pts, axis=0))
    except (QhullError, ValueError):  # flat or too few points: no solid
        return None
    facets = np.column_stack([hull.equations[:, :3], -hull.equations[:, 3] / size])
    if np.max(cKDTree(facets).query(faces, distance_upper_bound=2.0 * tol)[0]) > tol:
        return None
    planes, which = np.unique(np.round(faces, PLANE_DECIMALS), axis=0, return_inverse=True)
    planes = planes[_first_of_groups(faces, which.ravel(), len(planes), tol)]
    planes[:, 3] *= size
    return np.ascontiguousarray(planes)


def _first_of_groups(faces, which, count: int, tol: float) -> np.ndarray:
    """The rounded planes (indices into `count` of them, `which` each face's) to keep: the first of
    every group of faces joined by chains of faces within `tol` of each other, so that the faces of one
    plane whose rounding falls either side of a last decimal make one plane, not two."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    pairs = cKDTree(faces).query_pairs(tol, output_type="ndarray")
    links = coo_matrix((np.ones(len(pairs)), (which[pairs[:, 0]], which[pairs[:, 1]])), shape=(count, count))
    _, group = connected_components(links, directed=False)
    return np.sort(np.unique(group, return_index=True)[1])


def _oriented(corners, tris):
    """Unit corner normals (T, 3, 3) turned, per triangle, to the side of its winding (where their sum
    points); zero where a corner's normal is zero (then the shading uses the geometric normal)."""
    length = np.linalg.norm(corners, axis=-1, keepdims=True)
    unit = corners / np.where(length > 0.0, length, 1.0)
    side = np.einsum("ij,ij->i", unit.sum(axis=1), np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]))
    return unit * np.where(side < 0.0, -1.0, 1.0)[:, None, None]


def exact_spheres(scene: Scene, shape_ids: np.ndarray):
    """The scene's exact spheres (`exact = true`) in world space: (S, 4) centres and radii (format.py
    admits only uniform scales) and each triangle's sphere (T,) given its shape (`shape_ids`), -1
    where the triangle is intersected as one (accel.py)."""
    which = np.full(len(scene.shapes), -1, dtype=np.int64)
    spheres = []
    for i, shape in enumerate(scene.shapes):
        if shape.kind == "sphere" and shape.params.get("exact", False):
            which[i] = len(spheres)
            centre, radius = world_sphere(shape)
            spheres.append([*centre, radius])
    return np.array(spheres, dtype=np.float64).reshape(-1, 4), which[shape_ids]


def scene_triangles(scene: Scene, shape_ids: bool = False, normals: bool = False):
    """All triangles (T, 3, 3) and reflectances (T, 3) of the scene, in float64 world space; with
    `shape_ids` also each triangle's shape index (T,); with `normals` also the corner shading
    normals (T, 3, 3), or None when no shape is smooth (module docstring). A shape holding an
    interior medium must be closed (`boundary_edges`)."""
    all_tris, all_refl, all_ids, all_normals = [], [], [], []
    for i, shape in enumerate(scene.shapes):
        key = f"shape[{i}]"
        p = shape.params
        corners = None  # flat
        if shape.kind == "mesh":
            tris, refl, corners = load_mesh(shape, scene, key, normals and shape.smooth)
        else:
            if shape.kind == "box":
                tris = box_triangles(p["min"], p["max"])
            elif shape.kind == "quad":
                tris = quad_triangles(p["corners"])
            elif shape.kind == "triangles":
                tris = p["vertices"][p["faces"]]
                corners = p["normals"][p["faces"]] if "normals" in p else None
            elif shape.kind == "sphere":
                tris = sphere_triangles(p["center"], p["radius"], p["segments"])
                corners = sphere_normals(tris, p["center"], p["radius"])
            else:
                if np.allclose(p["base"], p["top"]):
                    raise UserError(f"{scene.path or 'scene'}: {key}.top: equals base; give the cylinder a length")
                tris = cylinder_triangles(p["base"], p["top"], p["radius"], p["segments"])
                corners = cylinder_normals(tris, p["base"], p["top"])
            refl = np.full((len(tris), 3), DEFAULT_REFLECTANCE)
        if shape.reflectance is not None:
            refl = np.broadcast_to(shape.reflectance, (len(tris), 3))
        with np.errstate(over="ignore", invalid="ignore"):  # checked just below
            tris = apply_transform(tris, shape.transform)
        if not np.all(np.isfinite(tris)):
            raise UserError(f"{scene.path or 'scene'}: {key}.transform: makes vertices overflow to inf; "
                            "use a smaller scale or translation (or scale the whole scene down)")
        if shape.interior is not None and (open_edges := boundary_edges(tris)):
            raise UserError(f"{scene.path or 'scene'}: {key}.interior: the shape is not closed ({open_edges} boundary "
                            "edges), so it has no inside; close the mesh (or use a box, sphere or cylinder) or remove "
                            "the interior")
        if shape.interior is not None and not np.any(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])):
            raise UserError(f"{scene.path or 'scene'}: {key}.interior: every triangle of the shape has zero area, so "
                            "it has no inside; give the shape a volume or remove the interior")
        all_tris.append(tris)
        all_refl.append(np.clip(refl, 0.0, 1.0))
        all_ids.append(np.full(len(tris), i, dtype=np.int64))
        if normals:
            smooth = shape.smooth and corners is not None
            all_normals.append(_oriented(corners @ _normal_matrix(shape.transform), tris) if smooth else
                               np.repeat(flat_normals(tris)[:, None, :], 3, axis=1))
    if not all_tris:
        empty = np.zeros((0, 3, 3)), np.zeros((0, 3))
        out = (*empty, np.zeros(0, dtype=np.int64)) if shape_ids else empty
        return (*out, None) if normals else out
    tris = np.ascontiguousarray(np.concatenate(all_tris))
    refl = np.ascontiguousarray(np.concatenate(all_refl))
    area2 = np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)
    keep = area2 > 0.0  # degenerate (zero-area) triangles have no normal and are never hit
    out = (tris[keep], refl[keep]) + ((np.concatenate(all_ids)[keep],) if shape_ids else ())
    if normals:
        smooth = any(s.smooth and (s.kind in ("mesh", "sphere", "cylinder") or "normals" in s.params)
                     for s in scene.shapes)
        out += (np.ascontiguousarray(np.concatenate(all_normals)[keep]) if smooth else None,)
    return out
