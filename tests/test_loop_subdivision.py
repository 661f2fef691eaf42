"""Loop subdivision surfaces (raytrace/io/loop.py, pbrt's Shape "loopsubdiv") against independent
references: trimesh's Loop subdivision where its weights are pbrt's (valence 6 everywhere), scipy's
periodic cubic B-spline along a boundary, and the limit's invariance under a further level."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.interpolate import BSpline
from scipy.spatial import cKDTree

from raytrace.api import scene_dict
from raytrace.cli import main
from raytrace.io import loop

# Houdini's test cube (tests/data/corpus/houdini-pbrt-v4/TestShapes/test_loopsubdiv.pbrt): valences 4 to 6
CUBE = np.array([[-0.5, -0.5, -0.5], [0.5, -0.5, -0.5], [0.5, -0.5, 0.5], [-0.5, -0.5, 0.5], [-0.5, 0.5, -0.5],
                 [0.5, 0.5, -0.5], [0.5, 0.5, 0.5], [-0.5, 0.5, 0.5]])
CUBE_FACES = np.array([1, 5, 4, 2, 6, 5, 3, 7, 6, 0, 4, 7, 2, 1, 0, 5, 6, 7, 7, 4, 5, 0, 3, 2, 7, 3, 0, 6, 2, 3, 5, 1, 2,
                       4, 0, 1]).reshape(-1, 3)


def torus(m=8, k=12):
    """A torus grid, every vertex of valence 6."""
    i, j = np.meshgrid(np.arange(m), np.arange(k), indexing="ij")
    th, ph = 2 * np.pi * i / m, 2 * np.pi * j / k
    v = np.stack([(2 + 0.7 * np.cos(th)) * np.cos(ph), (2 + 0.7 * np.cos(th)) * np.sin(ph), 0.7 * np.sin(th)],
                 -1).reshape(-1, 3)
    at = lambda a, b: (a % m) * k + b % k  # noqa: E731
    return v, np.array([f for a in range(m) for b in range(k)
                        for f in ([at(a, b), at(a + 1, b), at(a + 1, b + 1)], [at(a, b), at(a + 1, b + 1), at(a, b + 1)])])


def sheet(g=6):
    """An open g x g height field, its corners of valence 2 and 3, and its boundary loop's vertices in order."""
    x, y = np.meshgrid(np.arange(g), np.arange(g), indexing="ij")
    v = np.stack([x, y, np.sin(x) * np.cos(0.7 * y)], -1).reshape(-1, 3).astype(float)
    at = lambda a, b: a * g + b  # noqa: E731
    faces = np.array([f for a in range(g - 1) for b in range(g - 1)
                      for f in ([at(a, b), at(a + 1, b), at(a + 1, b + 1)], [at(a, b), at(a + 1, b + 1), at(a, b + 1)])])
    rim = ([at(a, 0) for a in range(g - 1)] + [at(g - 1, b) for b in range(g - 1)]
           + [at(a, g - 1) for a in range(g - 1, 0, -1)] + [at(0, b) for b in range(g - 1, 0, -1)])
    return v, faces, np.array(rim)


def test_one_level_matches_trimesh_where_the_weights_agree():
    v, f = torus()
    ours, faces = loop.subdivide(v, f)
    theirs, their_faces = trimesh.remesh.subdivide_loop(v, f, iterations=1)
    assert len(ours) == len(theirs) and len(faces) == len(their_faces) == 4 * len(f)
    assert cKDTree(theirs).query(ours)[0].max() < 1e-12


@pytest.mark.parametrize("mesh", ["cube", "sheet"])
def test_limit_points_and_normals_stay_under_a_further_level(mesh):
    """The limit masks are left eigenvectors of the subdivision: a further level leaves them in place
    (a wrong boundary weight, pbrt's 1/5, moves boundary points by 0.025 here)."""
    v, f = (CUBE, CUBE_FACES) if mesh == "cube" else sheet()[:2]
    for _ in range(3):
        finer, finer_faces = loop.subdivide(v, f)
        assert np.abs(loop.limit_points(finer, finer_faces)[:len(v)] - loop.limit_points(v, f)).max() < 1e-13
        assert np.abs(loop.limit_normals(finer, finer_faces)[:len(v)] - loop.limit_normals(v, f)).max() < 1e-13
        v, f = finer, finer_faces


def test_a_boundary_is_the_cubic_b_spline_of_its_control_polygon():
    v, f, rim = sheet()
    n = len(rim)
    control = np.concatenate([v[rim], v[rim[:3]]])  # periodic: degree 3, uniform knots
    curve = BSpline(np.arange(-3, n + 4, dtype=float), control, 3)
    level = 2
    points, faces = v, f
    for _ in range(level):
        points, faces = loop.subdivide(points, faces)
    limit, normals = loop.limit_points(points, faces), loop.limit_normals(points, faces)
    u = np.arange(n * 2 ** level) / 2 ** level  # the limit boundary at parameter u, vertex at u + ...
    on_curve = curve(u)
    found, where = cKDTree(limit).query(on_curve)
    assert found.max() < 1e-12  # each of the curve's points is a limit vertex
    tangent = curve.derivative()(u)
    assert np.abs(np.einsum("ij,ij->i", normals[where], tangent)).max() < 1e-12 * np.abs(tangent).max()


def test_normals_are_unit_and_on_the_winding_side():
    v, f, n = loop.surface(CUBE, CUBE_FACES, 3)
    assert len(f) == 12 * 64 and np.allclose(np.linalg.norm(n, axis=1), 1.0, rtol=0, atol=1e-15)
    area = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    assert np.all(np.einsum("ij,ij->i", n[f[:, 0]], area) > 0.0)  # Houdini's cube is wound inward


def test_a_control_mesh_that_is_not_a_manifold_is_refused():
    with pytest.raises(loop.NotManifold):
        loop.surface(np.eye(3).tolist() + [[1.0, 1.0, 1.0], [0.0, 0.0, 0.0]],
                     [[0, 1, 2], [1, 0, 3], [0, 1, 4]], 1)  # the edge 0-1 in three faces
    with pytest.raises(loop.NotManifold):
        loop.surface(CUBE, np.concatenate([CUBE_FACES[:1, ::-1], CUBE_FACES[1:]]), 1)  # one face turned over


PBRT = """LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective" "float fov" [ 40 ]
Film "rgb" "integer xresolution" [ 16 ] "integer yresolution" [ 12 ]
WorldBegin
LightSource "point" "rgb I" [ 10 10 10 ] "point3 from" [ 2 2 4 ]
AttributeBegin
  Translate 0.2 0 0
  Scale 1 2 3
  Shape "loopsubdiv" "point3 P" [ {points} ] "integer indices" [ {indices} ] {levels}
AttributeEnd
"""


def pbrt_file(tmp_path, faces=CUBE_FACES, levels='"integer levels" [ 2 ]'):
    path = tmp_path / "s.pbrt"
    path.write_text(PBRT.format(points=" ".join(map(str, CUBE.ravel())), indices=" ".join(map(str, faces.ravel())),
                                levels=levels))
    return path


def test_pbrt_reads_it_in_world_space(tmp_path):
    """Subdivision commutes with the transform (its weights sum to 1); the normals turn by the inverse
    transpose, so they stay normal to the transformed surface."""
    shape = scene_dict(pbrt_file(tmp_path))[0]["shape"][0]
    m = np.diag([-1.0, 2.0, 3.0])  # the importer mirrors pbrt's left-handed x, and turns the winding over
    v, f, n = loop.surface(CUBE @ m.T + [-0.2, 0.0, 0.0], CUBE_FACES, 2)
    assert np.allclose(shape["vertices"], v, rtol=0, atol=1e-14) and np.array_equal(shape["faces"], f[:, ::-1])
    given = np.asarray(shape["normals"])
    given = given / np.linalg.norm(given, axis=1, keepdims=True)
    assert np.abs(given + n).max() < 1e-12  # on the side of the stored winding, turned over with it
    shape = scene_dict(pbrt_file(tmp_path, levels=""))[0]["shape"][0]
    assert len(shape["faces"]) == 12 * 4 ** 3  # pbrt-v4's default: 3 levels


@pytest.mark.parametrize("faces,levels,said", [
    (np.concatenate([CUBE_FACES[:1, ::-1], CUBE_FACES[1:]]), "", "not a consistently wound manifold"),
    (CUBE_FACES, '"integer levels" [ 12 ]', '"integer levels" 12 would make 12 x 4^12 triangles'),
    (CUBE_FACES, '"integer levels" [ -1 ]', '"integer levels" -1'),
])
def test_pbrt_refuses_with_one_line(tmp_path, capsys, faces, levels, said):
    path = pbrt_file(tmp_path, faces, levels)
    out = tmp_path / "x.exr"
    assert main(["render", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert said in err and f"{path}:9" in err and len(err.splitlines()) == 1 and not out.exists()
