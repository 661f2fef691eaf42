"""Scene files (SCENE_FORMAT.md): valid scenes parse into the right values, --set overrides, the asset
search path, meshes through trimesh (OBJ+MTL, PLY, GLB) and the procedural primitives."""
from __future__ import annotations

import math
import os
import sys
from pathlib import Path

import numpy as np
import pytest

from raytrace.errors import UserError
from raytrace.media.phase import HG, ISOTROPIC, RAYLEIGH
from raytrace.scene import assets
from raytrace.scene.format import load_scene, scene_from_text
from raytrace.scene.meshes import (apply_transform, box_triangles, cylinder_triangles, quad_triangles,
                                   rotation_matrix, scene_triangles, sphere_triangles)
from raytrace.scene.format import Transform

CAMERA = """\
[camera]
position = [1.0, 2.0, 3.0]
look_at = [0.0, 0.5, -1.0]
"""


def parse(text, overrides=(), path=None):
    return scene_from_text(text, "test.toml", path, overrides)


def tri_area(tris):
    return 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)


# --- parsing ---------------------------------------------------------------------------------------------

def test_full_scene_values(tmp_path):
    text = """
name = "hall"
[camera]
type = "perspective"
position = [0.0, 1.0, 4.0]
look_at = [0.0, 1.0, 0.0]
up = [0.0, 1.0, 0.5]
fov = 45.0
width = 32
height = 24
spp = 16

[[shape]]
primitive = "box"
min = [-1.0, -2.0, -3.0]
max = [1.0, 2.0, 3.0]
reflectance = [0.1, 0.2, 0.3]
transform = { scale = 2.0, rotate = [0.0, 90.0, 0.0], translate = [1.0, 0.0, -1.0] }

[[shape]]
primitive = "sphere"
center = [0.0, 1.0, 0.0]
radius = 0.5

[[light]]
position = [1.0, 0.5, 0.0]
intensity = [10.0, 20.0, 30.0]

[[light]]
type = "point"
position = [-1.0, 0.5, 0.0]
intensity = 5

[medium]
sigma_a = [0.05, 0.06, 0.07]
sigma_s = 0.15
phase = { type = "hg", g = -0.4 }

[background]
radiance = [0.25, 0.5, 1.0]

[render]
seed = 3
"""
    p = tmp_path / "hall_file.toml"
    p.write_text(text)
    s = load_scene(p)
    assert s.name == "hall" and s.path == p
    c = s.camera
    assert c.type == "perspective"
    np.testing.assert_array_equal(c.position, [0.0, 1.0, 4.0])
    np.testing.assert_array_equal(c.look_at, [0.0, 1.0, 0.0])
    np.testing.assert_array_equal(c.up, [0.0, 1.0, 0.5])
    assert (c.fov, c.width, c.height, c.spp) == (45.0, 32, 24, 16)
    assert isinstance(c.width, int) and isinstance(c.spp, int)
    assert len(s.shapes) == 2
    box, sph = s.shapes
    assert box.kind == "box"
    np.testing.assert_array_equal(box.params["min"], [-1.0, -2.0, -3.0])
    np.testing.assert_array_equal(box.reflectance, [0.1, 0.2, 0.3])
    np.testing.assert_array_equal(box.transform.scale, [2.0, 2.0, 2.0])
    np.testing.assert_array_equal(box.transform.rotate, [0.0, 90.0, 0.0])
    np.testing.assert_array_equal(box.transform.translate, [1.0, 0.0, -1.0])
    assert sph.kind == "sphere" and sph.params["radius"] == 0.5 and sph.reflectance is None
    np.testing.assert_array_equal(sph.transform.scale, [1.0, 1.0, 1.0])
    np.testing.assert_array_equal(sph.transform.translate, [0.0, 0.0, 0.0])
    assert len(s.lights) == 2
    np.testing.assert_array_equal(s.lights[0].intensity, [10.0, 20.0, 30.0])
    np.testing.assert_array_equal(s.lights[1].intensity, [5.0, 5.0, 5.0])  # one number → three channels
    np.testing.assert_array_equal(s.lights[1].position, [-1.0, 0.5, 0.0])
    m = s.medium
    np.testing.assert_array_equal(m.sigma_a, [0.05, 0.06, 0.07])
    np.testing.assert_array_equal(m.sigma_s, [0.15, 0.15, 0.15])
    np.testing.assert_allclose(m.sigma_t, [0.20, 0.21, 0.22], rtol=1e-15)
    assert m.phase == HG and m.g == -0.4
    np.testing.assert_array_equal(s.background, [0.25, 0.5, 1.0])
    assert s.render == {"seed": 3}


def test_defaults():
    s = parse(CAMERA)
    np.testing.assert_array_equal(s.camera.up, [0.0, 1.0, 0.0])  # documented default
    assert s.camera.type == "perspective"
    assert isinstance(s.camera.spp, int) and s.camera.spp >= 1
    assert isinstance(s.camera.width, int) and s.camera.width >= 1
    assert isinstance(s.camera.height, int) and s.camera.height >= 1
    assert 0.0 < s.camera.fov < 180.0
    np.testing.assert_array_equal(s.background, [0.0, 0.0, 0.0])
    assert s.background.shape == (3,)
    assert s.shapes == [] and s.lights == []
    np.testing.assert_array_equal(s.medium.sigma_t, [0.0, 0.0, 0.0])  # no [medium] = vacuum
    assert s.medium.phase == ISOTROPIC
    assert s.render == {}
    assert s.name == "scene"  # no file, no name


def test_name_defaults_to_file_stem(tmp_path):
    p = tmp_path / "my_fog.toml"
    p.write_text(CAMERA)
    assert load_scene(p).name == "my_fog"


def test_integer_coefficients_are_accepted():
    s = parse(CAMERA + "[medium]\nsigma_a = 0\nsigma_s = [1, 2, 3]\n")
    np.testing.assert_array_equal(s.medium.sigma_s, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(s.medium.sigma_a, [0.0, 0.0, 0.0])


@pytest.mark.parametrize("phase,code,g", [
    ('"isotropic"', ISOTROPIC, 0.0),
    ('"rayleigh"', RAYLEIGH, 0.0),
    ('{ type = "hg", g = 0.5 }', HG, 0.5),
    ('{ type = "hg", g = -0.99 }', HG, -0.99),
    ('{ g = 0.25 }', HG, 0.25),  # a table is HG unless it says otherwise
    ('{ type = "isotropic" }', ISOTROPIC, 0.0),
    ('{ type = "rayleigh" }', RAYLEIGH, 0.0),
])
def test_phase(phase, code, g):
    m = parse(CAMERA + f"[medium]\nsigma_s = 0.1\nphase = {phase}\n").medium
    assert m.phase == code and m.g == g


def test_environment_camera():
    s = parse(CAMERA.replace("[camera]", '[camera]\ntype = "environment"'))
    assert s.camera.type == "environment"


def test_primitive_defaults_and_mesh_shape():
    s = parse(CAMERA + '[[shape]]\nprimitive = "cylinder"\nbase = [0.0, 0.0, 0.0]\ntop = [0.0, 2.0, 0.0]\n'
              'radius = 0.5\n[[shape]]\nmesh = "a/b.obj"\nreflectance = 0.3\n')
    cyl, mesh = s.shapes
    assert cyl.params["segments"] >= 3 and cyl.params["radius"] == 0.5
    assert mesh.kind == "mesh" and mesh.params == {"mesh": "a/b.obj"}
    np.testing.assert_array_equal(mesh.reflectance, [0.3, 0.3, 0.3])


def test_transform_scale_vector():
    s = parse(CAMERA + '[[shape]]\nprimitive = "quad"\ncorners = [[0.0,0,0],[1.0,0,0],[1.0,1,0],[0.0,1,0]]\n'
              'transform = { scale = [1.0, 2.0, -3.0] }\n')
    t = s.shapes[0].transform
    np.testing.assert_array_equal(t.scale, [1.0, 2.0, -3.0])
    np.testing.assert_array_equal(t.rotate, [0.0, 0.0, 0.0])


# --- --set overrides -------------------------------------------------------------------------------------

SCENE = CAMERA + """
[[shape]]
primitive = "box"
min = [-1.0, -1.0, -1.0]
max = [1.0, 1.0, 1.0]
reflectance = 0.7

[[light]]
position = [0.0, 0.5, 0.0]
intensity = 1.0

[medium]
sigma_a = 0.01
sigma_s = 0.1
"""


def test_set_scalar_becomes_three_channels():
    s = parse(SCENE, ["medium.sigma_s=0.2"])
    np.testing.assert_array_equal(s.medium.sigma_s, [0.2, 0.2, 0.2])
    np.testing.assert_array_equal(s.medium.sigma_a, [0.01, 0.01, 0.01])  # untouched


def test_set_shape_reflectance():
    s = parse(SCENE, ["shape.0.reflectance=0.2"])
    np.testing.assert_array_equal(s.shapes[0].reflectance, [0.2, 0.2, 0.2])
    _, refl = scene_triangles(s)
    assert refl.shape == (12, 3)
    np.testing.assert_array_equal(refl, 0.2)


def test_set_phase_table():
    s = parse(SCENE, ['medium.phase={type="hg",g=0.3}'])
    assert s.medium.phase == HG and s.medium.g == 0.3


def test_set_phase_string_and_vectors():
    s = parse(SCENE, ["medium.phase=rayleigh", "camera.position=[4.0, 5.0, 6.0]", "light.0.intensity=[1, 2, 3]",
                      "camera.width=8", "camera.up=[0,0,1]", "medium.phase=isotropic"])
    assert s.medium.phase == ISOTROPIC  # later overrides win
    np.testing.assert_array_equal(s.camera.position, [4.0, 5.0, 6.0])
    np.testing.assert_array_equal(s.lights[0].intensity, [1.0, 2.0, 3.0])
    assert s.camera.width == 8 and isinstance(s.camera.width, int)
    np.testing.assert_array_equal(s.camera.up, [0.0, 0.0, 1.0])


def test_set_creates_missing_tables():
    s = parse(CAMERA, ["background.radiance=0.5", "medium.sigma_s=[0.1, 0.2, 0.3]"])
    np.testing.assert_array_equal(s.background, [0.5, 0.5, 0.5])
    np.testing.assert_array_equal(s.medium.sigma_s, [0.1, 0.2, 0.3])


def test_set_vector_component_and_bare_string():
    s = parse(SCENE, ["camera.position.1=7.5", "name=foggy hall"])
    np.testing.assert_array_equal(s.camera.position, [1.0, 7.5, 3.0])
    assert s.name == "foggy hall"


def test_set_does_not_touch_the_file(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text(SCENE)
    assert load_scene(p, ["medium.sigma_s=0.5"]).medium.sigma_s[0] == 0.5
    assert p.read_text() == SCENE
    assert load_scene(p).medium.sigma_s[0] == 0.1


# --- asset search path -----------------------------------------------------------------------------------

@pytest.fixture
def folders(tmp_path, monkeypatch):
    scene_dir, a, b = tmp_path / "scene", tmp_path / "a", tmp_path / "b"
    for d in (scene_dir, a, b):
        (d / "sub").mkdir(parents=True)
    monkeypatch.setenv("RAYTRACE_ASSETS", os.pathsep.join([str(a), "", str(b)]))
    return scene_dir / "s.toml", a, b


def test_search_folders_order(folders):
    scene, a, b = folders
    assert assets.search_folders(scene) == [scene.parent, a, b]
    assert assets.search_folders(None) == [a, b]


def test_search_prefers_scene_folder_then_env_in_order(folders):
    scene, a, b = folders
    for d in (scene.parent, a, b):
        (d / "sub" / "m.obj").write_text("x")
    assert assets.find_asset("sub/m.obj", scene, "k") == scene.parent / "sub" / "m.obj"
    (scene.parent / "sub" / "m.obj").unlink()
    assert assets.find_asset("sub/m.obj", scene, "k") == a / "sub" / "m.obj"
    (a / "sub" / "m.obj").unlink()
    assert assets.find_asset("sub/m.obj", scene, "k") == b / "sub" / "m.obj"
    (b / "sub" / "m.obj").unlink()
    with pytest.raises(UserError) as exc:
        assets.find_asset("sub/m.obj", scene, "shape[0].mesh")
    msg = str(exc.value)
    assert "shape[0].mesh" in msg and "sub/m.obj" in msg and "RAYTRACE_ASSETS" in msg
    pos = [msg.find(str(d)) for d in (scene.parent, a, b)]
    assert min(pos) >= 0 and pos == sorted(pos)


def test_search_skips_folders_with_same_name_directory(folders):
    scene, a, b = folders
    (scene.parent / "sub" / "m.obj").mkdir()  # a folder, not a file
    (b / "sub" / "m.obj").write_text("x")
    assert assets.find_asset("sub/m.obj", scene, "k") == b / "sub" / "m.obj"


def test_absolute_mesh_path(folders, tmp_path):
    scene, _, _ = folders
    f = tmp_path / "abs.obj"
    f.write_text("x")
    assert assets.find_asset(str(f), scene, "k") == f
    with pytest.raises(UserError, match="not found"):
        assets.find_asset(str(tmp_path / "nope.obj"), scene, "k")


def test_no_env_means_scene_folder_then_user_data_folder(tmp_path, monkeypatch):
    """Without RAYTRACE_ASSETS, the folder `render.py assets` downloads into is searched after the
    scene's own (docs/assets.md); on Linux it follows XDG_DATA_HOME."""
    monkeypatch.delenv("RAYTRACE_ASSETS", raising=False)
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    assert assets.search_folders(tmp_path / "s.toml") == [tmp_path, assets.data_folder()]
    if sys.platform.startswith("linux"):
        assert assets.data_folder() == tmp_path / "xdg" / "raytrace-media"


# --- meshes through trimesh -------------------------------------------------------------------------------

OBJ = """\
mtllib two.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 2
v 3 0 2
v 0 3 2
usemtl red
f 1 2 3
f 1 3 4
usemtl blue
f 5 6 7
"""
MTL = """\
newmtl red
Kd 0.8 0.2 0.1
newmtl blue
Kd 0.1 0.3 0.9
"""


def mesh_scene(folder, mesh, extra=""):
    p = folder / "s.toml"
    p.write_text(CAMERA + f'[[shape]]\nmesh = "{mesh}"\n{extra}')
    return load_scene(p)


def _sorted_by_z(tris, refl):
    order = np.argsort(tris[:, :, 2].mean(axis=1), kind="stable")
    return tris[order], refl[order]


def test_obj_mtl_kd_becomes_per_triangle_reflectance(tmp_path):
    (tmp_path / "two.obj").write_text(OBJ)
    (tmp_path / "two.mtl").write_text(MTL)
    tris, refl = scene_triangles(mesh_scene(tmp_path, "two.obj"))
    assert tris.shape == (3, 3, 3) and refl.shape == (3, 3)
    assert tris.dtype == np.float64 and refl.dtype == np.float64
    tris, refl = _sorted_by_z(tris, refl)
    # the two red triangles at z = 0 cover the unit square, the blue one at z = 2 has area 4.5
    np.testing.assert_allclose(tri_area(tris), [0.5, 0.5, 4.5], rtol=1e-12)
    np.testing.assert_allclose(tris[:2, :, 2], 0.0)
    np.testing.assert_allclose(tris[2, :, 2], 2.0)
    # MTL colours may pass through 8 bits inside trimesh: allow half a step of 1/255
    np.testing.assert_allclose(refl[:2], [[0.8, 0.2, 0.1]] * 2, atol=0.5 / 255 + 1e-12)
    np.testing.assert_allclose(refl[2], [0.1, 0.3, 0.9], atol=0.5 / 255 + 1e-12)


def test_obj_reflectance_override_and_transform(tmp_path):
    (tmp_path / "two.obj").write_text(OBJ)
    (tmp_path / "two.mtl").write_text(MTL)
    s = mesh_scene(tmp_path, "two.obj", 'reflectance = [0.3, 0.4, 0.5]\n'
                   'transform = { scale = 2.0, translate = [10.0, 0.0, 0.0] }\n')
    tris, refl = scene_triangles(s)
    np.testing.assert_array_equal(refl, [[0.3, 0.4, 0.5]] * 3)
    tris, _ = _sorted_by_z(tris, refl)
    np.testing.assert_allclose(tri_area(tris), [2.0, 2.0, 18.0], rtol=1e-12)  # areas scale by 2^2
    np.testing.assert_allclose(tris.reshape(-1, 3).min(axis=0), [10.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(tris.reshape(-1, 3).max(axis=0), [16.0, 6.0, 4.0], atol=1e-12)


def test_obj_without_mtl_gets_a_valid_default(tmp_path):
    (tmp_path / "plain.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    tris, refl = scene_triangles(mesh_scene(tmp_path, "plain.obj"))
    assert tris.shape == (1, 3, 3)
    assert np.all((refl > 0.0) & (refl <= 1.0)) and np.all(refl == refl[0, 0])  # a grey in (0, 1]


def test_obj_with_latin1_comment(tmp_path):
    (tmp_path / "lat.obj").write_bytes(b"# caf\xe9\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    tris, _ = scene_triangles(mesh_scene(tmp_path, "lat.obj"))
    assert tris.shape == (1, 3, 3)


def _trimesh_box(extents, colour=None):
    import trimesh

    b = trimesh.creation.box(extents=extents)
    if colour is not None:
        b.visual = trimesh.visual.TextureVisuals(
            material=trimesh.visual.material.PBRMaterial(baseColorFactor=list(colour) + [1.0]))
    return b


def _check_box(tris, extents):
    half = np.asarray(extents) / 2
    assert tris.shape == (12, 3, 3)
    pts = tris.reshape(-1, 3)
    np.testing.assert_allclose(pts.min(axis=0), -half, atol=1e-6)
    np.testing.assert_allclose(pts.max(axis=0), half, atol=1e-6)
    a, b, c = extents
    np.testing.assert_allclose(tri_area(tris).sum(), 2 * (a * b + b * c + c * a), rtol=1e-6)


def test_ply(tmp_path):
    _trimesh_box([2.0, 4.0, 6.0]).export(tmp_path / "box.ply")
    tris, refl = scene_triangles(mesh_scene(tmp_path, "box.ply"))
    _check_box(tris, [2.0, 4.0, 6.0])
    assert np.all((refl >= 0.0) & (refl <= 1.0))


def test_glb_with_base_colour(tmp_path):
    _trimesh_box([2.0, 4.0, 6.0], colour=(0.2, 0.4, 0.6)).export(tmp_path / "box.glb")
    tris, refl = scene_triangles(mesh_scene(tmp_path, "box.glb"))
    _check_box(tris, [2.0, 4.0, 6.0])
    np.testing.assert_allclose(refl, [[0.2, 0.4, 0.6]] * 12, atol=0.5 / 255 + 1e-12)


def test_mesh_found_through_env(tmp_path, monkeypatch):
    lib = tmp_path / "lib"
    (lib / "models").mkdir(parents=True)
    _trimesh_box([1.0, 1.0, 1.0]).export(lib / "models" / "cube.ply")
    monkeypatch.setenv("RAYTRACE_ASSETS", str(lib))
    (tmp_path / "scenes").mkdir()
    tris, _ = scene_triangles(mesh_scene(tmp_path / "scenes", "models/cube.ply"))
    _check_box(tris, [1.0, 1.0, 1.0])


# --- primitives --------------------------------------------------------------------------------------------

def test_box_primitive():
    lo, hi = np.array([-1.0, 2.0, -3.0]), np.array([4.0, 3.0, 0.5])
    tris = box_triangles(lo, hi)
    assert tris.shape == (12, 3, 3)
    pts = tris.reshape(-1, 3)
    np.testing.assert_array_equal(pts.min(axis=0), lo)
    np.testing.assert_array_equal(pts.max(axis=0), hi)
    # every corner of every triangle is a corner of the box, every triangle lies in a face
    assert np.all((pts == lo) | (pts == hi))
    for t in tris:
        assert np.any(np.all(t == t[0], axis=0)), "triangle not on an axis-aligned face"
    a, b, c = hi - lo
    np.testing.assert_allclose(tri_area(tris).sum(), 2 * (a * b + b * c + c * a), rtol=1e-14)
    # closed surface: every edge is shared by exactly two triangles
    edges = {}
    for t in tris:
        for i in range(3):
            e = tuple(sorted((tuple(t[i]), tuple(t[(i + 1) % 3]))))
            edges[e] = edges.get(e, 0) + 1
    assert set(edges.values()) == {2}


def test_box_through_scene():
    s = parse(CAMERA + '[[shape]]\nprimitive = "box"\nmin = [-5.0, -5.0, -5.0]\nmax = [5.0, 5.0, 5.0]\n')
    tris, refl = scene_triangles(s)
    assert tris.shape == (12, 3, 3) and refl.shape == (12, 3)
    np.testing.assert_array_equal(tris.reshape(-1, 3).min(axis=0), [-5.0] * 3)
    np.testing.assert_array_equal(tris.reshape(-1, 3).max(axis=0), [5.0] * 3)
    assert np.all((refl > 0.0) & (refl <= 1.0))


def test_quad_primitive():
    c = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 3.0, 0.0], [0.0, 3.0, 0.0]])
    tris = quad_triangles(c)
    assert tris.shape == (2, 3, 3)
    np.testing.assert_allclose(tri_area(tris).sum(), 6.0, rtol=1e-15)
    assert {tuple(p) for p in tris.reshape(-1, 3)} == {tuple(p) for p in c}


@pytest.mark.parametrize("segments", [8, 32])
def test_sphere_primitive(segments):
    center, r = np.array([1.0, -2.0, 0.5]), 1.5
    tris = sphere_triangles(center, r, segments)
    pts = tris.reshape(-1, 3)
    np.testing.assert_allclose(np.linalg.norm(pts - center, axis=1), r, rtol=1e-12)
    np.testing.assert_allclose(pts.min(axis=0), center - r, atol=1e-12 + r * (1 - math.cos(math.pi / segments)))
    np.testing.assert_allclose(pts.max(axis=0), center + r, atol=1e-12 + r * (1 - math.cos(math.pi / segments)))
    area = tri_area(tris)
    assert np.all(area > 0)
    # an inscribed polyhedron: area a little below 4 pi r^2, converging as segments grow
    ratio = area.sum() / (4 * math.pi * r * r)
    assert 1 - 12.0 / segments ** 2 < ratio < 1.0
    # the mean of a closed surface's area-weighted centroids is its centre (symmetry)
    np.testing.assert_allclose((tris.mean(axis=1) * area[:, None]).sum(axis=0) / area.sum(), center, atol=1e-9)


def test_sphere_through_scene_is_closed():
    s = parse(CAMERA + '[[shape]]\nprimitive = "sphere"\ncenter = [0.0, 0.0, 0.0]\nradius = 2.0\nsegments = 16\n')
    tris, _ = scene_triangles(s)
    # enclosed volume by the divergence theorem, independent of orientation sign
    vol = abs(np.einsum("ij,ij->i", tris[:, 0], np.cross(tris[:, 1], tris[:, 2])).sum() / 6.0)
    assert 0.9 * (4 / 3) * math.pi * 8 < vol < (4 / 3) * math.pi * 8


def test_cylinder_primitive():
    base, top, r, n = np.array([0.0, 0.0, 0.0]), np.array([0.0, 5.0, 0.0]), 0.35, 24
    tris = cylinder_triangles(base, top, r, n)
    assert tris.shape == (4 * n, 3, 3)
    pts = tris.reshape(-1, 3)
    radial = np.linalg.norm(pts[:, [0, 2]], axis=1)
    on_axis = radial < 1e-12
    np.testing.assert_allclose(radial[~on_axis], r, rtol=1e-12)  # rim points on the radius
    assert set(np.round(pts[on_axis, 1], 12)) == {0.0, 5.0}  # only the cap centres on the axis
    np.testing.assert_allclose(pts[:, 1].min(), 0.0, atol=1e-15)
    np.testing.assert_allclose(pts[:, 1].max(), 5.0, atol=1e-15)
    polygon = 0.5 * n * r * r * math.sin(2 * math.pi / n)  # area of the n-gon cap
    side = n * 2 * r * math.sin(math.pi / n) * 5.0
    np.testing.assert_allclose(tri_area(tris).sum(), side + 2 * polygon, rtol=1e-12)


def test_cylinder_along_a_slanted_axis():
    base, top, r = np.array([1.0, 1.0, 1.0]), np.array([2.0, 3.0, -1.0]), 0.5
    tris = cylinder_triangles(base, top, r, 16)
    axis = (top - base) / np.linalg.norm(top - base)
    pts = tris.reshape(-1, 3) - base
    along = pts @ axis
    dist = np.linalg.norm(pts - along[:, None] * axis, axis=1)
    assert np.all((np.abs(dist - r) < 1e-12) | (dist < 1e-12))
    np.testing.assert_allclose([along.min(), along.max()], [0.0, 3.0], atol=1e-12)


def test_cylinder_of_zero_length_is_a_user_error():
    s = parse(CAMERA + '[[shape]]\nprimitive = "cylinder"\nbase = [0.0, 1.0, 0.0]\ntop = [0.0, 1.0, 0.0]\n'
              'radius = 1.0\n')
    with pytest.raises(UserError, match=r"shape\[0\]\.top"):
        scene_triangles(s)


def test_rotation_matrix_right_handed():
    x, y, z = np.eye(3)
    np.testing.assert_allclose(rotation_matrix([90.0, 0.0, 0.0]) @ y, z, atol=1e-15)  # x: y → z
    np.testing.assert_allclose(rotation_matrix([0.0, 90.0, 0.0]) @ z, x, atol=1e-15)  # y: z → x
    np.testing.assert_allclose(rotation_matrix([0.0, 0.0, 90.0]) @ x, y, atol=1e-15)  # z: x → y
    # x first, then y: x-rotation takes y to z, then the y-rotation takes z to x
    np.testing.assert_allclose(rotation_matrix([90.0, 90.0, 0.0]) @ y, x, atol=1e-15)
    m = rotation_matrix([12.0, -40.0, 77.0])
    np.testing.assert_allclose(m @ m.T, np.eye(3), atol=1e-15)
    assert abs(np.linalg.det(m) - 1.0) < 1e-14


def test_transform_scale_then_rotate_then_translate():
    unit = quad_triangles([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    t = Transform(scale=np.array([2.0, 3.0, 1.0]), rotate=np.array([0.0, 0.0, 90.0]),
                  translate=np.array([10.0, 0.0, -1.0]))
    out = apply_transform(unit, t)
    # (1, 0, 0) → scale (2, 0, 0) → rotate z 90 (0, 2, 0) → translate (10, 2, -1)
    # (0, 1, 0) → scale (0, 3, 0) → rotate z 90 (-3, 0, 0) → translate (7, 0, -1)
    pts = {tuple(np.round(p, 12)) for p in out.reshape(-1, 3)}
    assert pts == {(10.0, 0.0, -1.0), (10.0, 2.0, -1.0), (7.0, 0.0, -1.0), (7.0, 2.0, -1.0)}
    np.testing.assert_allclose(tri_area(out).sum(), 6.0, rtol=1e-12)


def test_transform_in_scene_rotates_box():
    s = parse(CAMERA + '[[shape]]\nprimitive = "box"\nmin = [0.0, 0.0, 0.0]\nmax = [4.0, 1.0, 2.0]\n'
              'transform = { scale = 0.5, rotate = [0.0, 90.0, 0.0], translate = [1.0, 2.0, 3.0] }\n')
    tris, _ = scene_triangles(s)
    pts = tris.reshape(-1, 3)
    # scaled: [0,2]x[0,0.5]x[0,1]; Ry(90): (x, y, z) → (z, y, -x): [0,1]x[0,0.5]x[-2,0]; translated
    np.testing.assert_allclose(pts.min(axis=0), [1.0, 2.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(pts.max(axis=0), [2.0, 2.5, 3.0], atol=1e-12)


def test_scene_triangles_concatenates_shapes_in_order():
    s = parse(CAMERA + '[[shape]]\nprimitive = "quad"\ncorners = [[0.0,0,0],[1.0,0,0],[1.0,1,0],[0.0,1,0]]\n'
              'reflectance = 0.1\n'
              '[[shape]]\nprimitive = "box"\nmin = [0.0, 0.0, 0.0]\nmax = [1.0, 1.0, 1.0]\nreflectance = 0.9\n')
    tris, refl = scene_triangles(s)
    assert tris.shape == (14, 3, 3)
    np.testing.assert_array_equal(refl[:2], 0.1)
    np.testing.assert_array_equal(refl[2:], 0.9)


# --- the paper's meshes (optional) ----------------------------------------------------------------------

def _shared_scenes():
    here = Path(__file__).resolve().parents[1]
    cands = [Path(p) for p in os.environ.get("RAYTRACE_ASSETS", "").split(os.pathsep) if p]
    cands.append(here.parent / "shared" / "scenes")
    for c in cands:
        if (c / "sibenik" / "sibenik.obj").is_file() and (c / "sibenik" / "sibenik.mtl").is_file():
            return c
    return None


def test_sibenik_through_raytrace_assets(tmp_path, monkeypatch):
    root = _shared_scenes()
    if root is None:
        pytest.skip("sibenik/sibenik.obj not found in RAYTRACE_ASSETS or ../shared/scenes")
    monkeypatch.setenv("RAYTRACE_ASSETS", str(root))
    tris, refl = scene_triangles(mesh_scene(tmp_path, "sibenik/sibenik.obj"))
    # SOURCES.md: 73,564 triangles in sibenik.obj (a handful may be degenerate and dropped)
    assert 73_000 <= len(tris) <= 73_564
    assert np.all(np.isfinite(tris)) and np.all((refl >= 0.0) & (refl <= 1.0))
    kd = np.array([[float(v) for v in line.split()[1:4]]
                   for line in (root / "sibenik" / "sibenik.mtl").read_text(errors="replace").splitlines()
                   if line.strip().startswith("Kd ")])
    uniq = np.unique(refl, axis=0)
    assert len(uniq) >= 3  # several materials, not one default colour
    dist = np.abs(uniq[:, None, :] - kd[None, :, :]).max(axis=2).min(axis=1)
    assert np.all(dist <= 0.5 / 255 + 1e-9), "every reflectance is some Kd from sibenik.mtl"
