"""Triangles for a scene: meshes through trimesh (OBJ/MTL, PLY, GLB) and procedural primitives.

Everything ends as float64 arrays: triangle corners (T, 3, 3) and a diffuse reflectance per
triangle (T, 3). MTL diffuse colours (Kd) and glTF base colours become reflectances.
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import UserError, counted
from .assets import find_asset
from .format import Scene, Shape, Transform

DEFAULT_REFLECTANCE = 0.5


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
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(a, helper)
    u /= np.linalg.norm(u)
    w = np.cross(a, u)
    ang = np.linspace(0.0, 2.0 * math.pi, segments + 1)
    ring = radius * (np.cos(ang)[:, None] * u + np.sin(ang)[:, None] * w)
    tris = []
    for j in range(segments):
        p0, p1 = base + ring[j], base + ring[j + 1]
        q0, q1 = top + ring[j], top + ring[j + 1]
        tris += [(p0, p1, q1), (p0, q1, q0), (base, p1, p0), (top, q0, q1)]
    return np.array(tris)


def rotation_matrix(degrees):
    rx, ry, rz = np.radians(degrees)
    cx, sx, cy, sy, cz, sz = math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry), math.cos(rz), math.sin(rz)
    mx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    my = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    mz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return mz @ my @ mx


def apply_transform(tris, t: Transform):
    """Scale, then rotate about x, y, z (degrees), then translate."""
    m = rotation_matrix(t.rotate) * t.scale[None, :]
    return tris @ m.T + t.translate


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


def load_mesh(shape: Shape, scene: Scene, key: str):
    import trimesh

    path = find_asset(shape.params["mesh"], scene.path, f"{key}.mesh")
    try:
        loaded = trimesh.load(str(path), force="scene", process=False)
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise UserError(f"{path}: {key}.mesh: cannot read mesh ({type(exc).__name__}: {exc}); "
                        "export it as OBJ, PLY or GLB") from None
    tris, refl = [], []
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
        colour = _mesh_colour(geom)
        refl.append(np.broadcast_to(colour if colour is not None else DEFAULT_REFLECTANCE, (len(t), 3)))
    if not tris:
        raise UserError(f"{path}: the mesh holds no triangles; check the file or {key}.mesh")
    return np.concatenate(tris), np.concatenate(refl)


def boundary_edges(tris: np.ndarray) -> int:
    """The edges of a triangle soup used by an odd number of triangles (vertices merged where their
    coordinates agree to 1e-9 of the soup's size): 0 for a closed surface."""
    pts = tris.reshape(-1, 3)
    size = float(np.max(np.abs(pts))) or 1.0
    _, ids = np.unique(np.round(pts / (1e-9 * size)), axis=0, return_inverse=True)
    ids = ids.reshape(-1, 3)
    edges = np.sort(np.concatenate([ids[:, [0, 1]], ids[:, [1, 2]], ids[:, [2, 0]]]), axis=1)
    edges = edges[edges[:, 0] != edges[:, 1]]  # collapsed edges of degenerate triangles (a sphere's poles)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return int(np.sum(counts % 2))


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
    planes = np.unique(np.round(faces, 12), axis=0)
    planes[:, 3] *= size
    return np.ascontiguousarray(planes)


def scene_triangles(scene: Scene, shape_ids: bool = False):
    """All triangles (T, 3, 3) and reflectances (T, 3) of the scene, in float64 world space; with
    `shape_ids` also each triangle's shape index (T,). A shape holding an interior medium must be
    closed (`boundary_edges`)."""
    all_tris, all_refl, all_ids = [], [], []
    for i, shape in enumerate(scene.shapes):
        key = f"shape[{i}]"
        p = shape.params
        if shape.kind == "mesh":
            tris, refl = load_mesh(shape, scene, key)
        else:
            if shape.kind == "box":
                tris = box_triangles(p["min"], p["max"])
            elif shape.kind == "quad":
                tris = quad_triangles(p["corners"])
            elif shape.kind == "triangles":
                tris = p["vertices"][p["faces"]]
            elif shape.kind == "sphere":
                tris = sphere_triangles(p["center"], p["radius"], p["segments"])
            else:
                if np.allclose(p["base"], p["top"]):
                    raise UserError(f"{scene.path or 'scene'}: {key}.top: equals base; give the cylinder a length")
                tris = cylinder_triangles(p["base"], p["top"], p["radius"], p["segments"])
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
    if not all_tris:
        empty = np.zeros((0, 3, 3)), np.zeros((0, 3))
        return (*empty, np.zeros(0, dtype=np.int64)) if shape_ids else empty
    tris = np.ascontiguousarray(np.concatenate(all_tris))
    refl = np.ascontiguousarray(np.concatenate(all_refl))
    area2 = np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)
    keep = area2 > 0.0  # degenerate (zero-area) triangles have no normal and are never hit
    if shape_ids:
        return tris[keep], refl[keep], np.concatenate(all_ids)[keep]
    return tris[keep], refl[keep]
