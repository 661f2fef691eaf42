"""interiors/shapes.py `plane_neighbours`: the planes media/slab.py `reachable_faces` reads for each
face of a convex refractive shape. A point of a face's plane is on the face iff it lies inside every
other plane; the test checks, from the geometry alone, that the listed planes decide the same: on
points of each plane sampled over a disk around its face (the face's own triangles' extent, doubled)
and on its triangles,
those inside the listed planes are exactly those inside all planes (points within 1e-9 of an edge
line, where both tests are decided by rounding, left out). Shapes: UV spheres, an icosphere, a box, a
cylinder."""
import numpy as np
import pytest
import trimesh

from raytrace.interiors import shapes
from raytrace.rendering.renderer import prepare
from raytrace.scene.format import scene_from_text

from .conftest import to_toml

INTERIOR = {"sigma_a": 0.1, "sigma_s": 0.2, "ior": 1.5}
CAMERA = {"position": [0.0, 0.0, 5.0], "look_at": [0.0, 0.0, 0.0], "fov": 30.0, "width": 2, "height": 2, "spp": 1}


def prep_of(shape):
    sc = {"camera": CAMERA, "shape": [shape | {"interior": INTERIOR}],
          "light": [{"type": "point", "position": [2.0, 2.0, 2.0], "intensity": 1.0}]}
    return prepare(scene_from_text(to_toml(sc), "neighbours"))


def ico():
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    return {"primitive": "triangles", "vertices": mesh.vertices.tolist(), "faces": mesh.faces.tolist()}


SHAPES = {"uv10": {"primitive": "sphere", "center": [0.0, 0.0, 0.0], "radius": 1.0, "segments": 10},
          "uv48": {"primitive": "sphere", "center": [0.2, -0.1, 0.3], "radius": 2.0, "segments": 48},
          "ico320": ico(), "box": {"primitive": "box", "min": [-1.0, -0.5, 0.0], "max": [1.0, 0.5, 0.3]},
          "cylinder": {"primitive": "cylinder", "base": [0.0, -1.0, 0.0], "top": [0.0, 1.0, 0.0], "radius": 0.5,
                       "segments": 24}}


@pytest.mark.parametrize("name", SHAPES)
def test_the_listed_planes_decide_the_face(name):
    prep = prep_of(SHAPES[name])
    planes = shapes.refracting_planes(prep, 0)
    near = shapes.plane_neighbours(prep, 0)
    P = len(planes)
    assert P > 0 and len(near) > P + 1 and near[0] == P + 1 and near[P] == len(near)
    tris = prep.accel.triangles[prep.shape_ids == 0].astype(float)
    rng = np.random.default_rng(7)
    counts = []
    for f in range(P):
        n, c = planes[f, :3], planes[f, 3]
        on = np.abs(tris.reshape(-1, 3) @ n - c).reshape(-1, 3).max(axis=1) < 1e-9
        corners = tris[on].reshape(-1, 3)
        centre = corners.mean(axis=0)
        radius = 2.0 * np.linalg.norm(corners - centre, axis=1).max()
        u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(n, u)
        ab = rng.uniform(-radius, radius, size=(400, 2))
        bary = rng.dirichlet(np.ones(3), size=100)
        inner = np.einsum("tk,tkj->tj", bary, tris[on][rng.integers(on.sum(), size=100)])
        pts = np.vstack([centre + ab[:, :1] * u + ab[:, 1:] * v, inner])
        ids = near[near[f]:near[f + 1]]
        assert f not in ids
        counts.append(len(ids))
        d = pts @ planes[:, :3].T - planes[:, 3]
        same = np.nonzero((np.abs(planes[:, :3] - n).max(axis=1) < 1e-9) & (np.abs(planes[:, 3] - c) < 1e-9))[0]
        assert set(same.tolist()) - {f} <= set(ids.tolist())  # planes equal but for rounding: listed, and
        d[:, same] = -1.0  # decided by rounding alone on this face: left out
        clear = np.all(np.abs(d) > 1e-9, axis=1)
        every = np.all(d <= 0.0, axis=1)
        listed = np.all(d[:, ids] <= 0.0, axis=1)
        assert np.array_equal(every[clear], listed[clear]), (f, np.nonzero(every != listed)[0][:5])
        assert every[clear].any() and (~every[clear]).any()
    assert np.median(counts) <= 12, np.median(counts)  # a face's edges and corners: few planes, not all
