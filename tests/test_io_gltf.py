"""glTF 2.0 import and export (raytrace/io/gltf.py, docs/formats/gltf.md).

The room in tests/data/gltf was made and exported by Blender 3.4's own glTF exporter (make_room.py);
room.toml is the same scene written by hand. Expected values are computed here from the glTF and
KHR specifications, not from the importer."""
from __future__ import annotations

import base64
import copy
import json
import math
import re
import shutil
import struct
import subprocess
import warnings
from pathlib import Path

import numpy as np
import pytest
import trimesh

import raytrace
from raytrace.cli import main
from raytrace.errors import UserError
from raytrace.io import gltf
from raytrace.scene.format import read_toml, scene_from_dict
from raytrace.scene.meshes import scene_triangles

DATA = Path(__file__).resolve().parent / "data" / "gltf"
FLOAT32 = 2e-7  # relative: what a float32 in the file holds of a float64
FOG = {"sigma_a": 0.02, "sigma_s": 0.05}  # a glTF has no fog: the renders add the same to both sides


@pytest.fixture(autouse=True)
def _quiet_notes():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", gltf.GltfNote)
        yield


def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def shapes_of(raw):
    """Validated shapes only (the spot's falloff key is not parsed yet): (triangles per shape, Scene)."""
    scene = scene_from_dict({"camera": raw["camera"], "shape": copy.deepcopy(raw["shape"])}, "test")
    tris, refl, ids = scene_triangles(scene, shape_ids=True)
    return [tris[ids == i] for i in range(len(scene.shapes))], [refl[ids == i] for i in range(len(scene.shapes))], scene


def same_surface(a, b, tol):
    """Two triangle soups cover the same surface, however each is triangulated: equal areas, and every
    triangle's centroid and corners of one lie on the other (trimesh's closest point)."""
    def area(t):
        return 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum()

    assert area(a) == pytest.approx(area(b), rel=tol)
    for x, y in ((a, b), (b, a)):
        pts = np.concatenate([x.mean(axis=1), x.reshape(-1, 3)])
        near = trimesh.triangles.closest_point(np.repeat(y, len(pts), axis=0), np.tile(pts, (len(y), 1)))
        dist = np.linalg.norm(near - np.tile(pts, (len(y), 1)), axis=1).reshape(len(y), len(pts)).min(axis=0)
        assert dist.max() <= tol * np.abs(y).max()


def camera_frame(cam):
    forward = unit(np.subtract(cam["look_at"], cam["position"]))
    right = unit(np.cross(forward, cam.get("up", [0.0, 1.0, 0.0])))
    return forward, right, np.cross(right, forward)


def assert_same_scene(got, want, tol=FLOAT32):
    """Scene dicts equal up to `tol`: camera frame and image, lights, surfaces, materials and interiors."""
    for g, w in zip(camera_frame(got["camera"]), camera_frame(want["camera"])):
        np.testing.assert_allclose(g, w, atol=tol)
    np.testing.assert_allclose(got["camera"]["position"], want["camera"]["position"], atol=tol)
    assert got["camera"]["fov"] == pytest.approx(want["camera"]["fov"], rel=tol)
    for k in ("width", "height"):
        assert got["camera"][k] == want["camera"][k]
    assert len(got["light"]) == len(want["light"])
    for g, w in zip(got["light"], want["light"]):
        assert g["type"] == w["type"] and g.get("falloff") == w.get("falloff")
        np.testing.assert_allclose(np.broadcast_to(g.get("intensity", g.get("irradiance")), 3),
                                   np.broadcast_to(w.get("intensity", w.get("irradiance")), 3), rtol=tol)
        if g["type"] != "directional":
            np.testing.assert_allclose(g["position"], w["position"], atol=tol)
        if g["type"] != "point":
            axis = [unit(x["direction"] if "direction" in x else np.subtract(x["look_at"], x["position"])) for x in (g, w)]
            np.testing.assert_allclose(*axis, atol=tol)
        if g["type"] == "spot":
            assert (g["cone_angle"], g["falloff_start"]) == pytest.approx((w["cone_angle"], w["falloff_start"]), rel=tol)
    gt, gr, gs = shapes_of(got)
    wt, wr, ws = shapes_of(want)
    assert len(gt) == len(wt)
    for i in range(len(gt)):
        same_surface(gt[i], wt[i], tol)
        np.testing.assert_allclose(gr[i].mean(axis=0), wr[i].mean(axis=0), rtol=tol)
        a, b = gs.shapes[i].interior, ws.shapes[i].interior
        assert (a is None) == (b is None)
        if a is not None:
            np.testing.assert_allclose(a.sigma_a, b.sigma_a, rtol=1e-12, atol=1e-15)
            np.testing.assert_allclose(a.sigma_s, b.sigma_s, rtol=1e-12, atol=1e-15)
            assert (a.phase, a.ior) == (b.phase, b.ior) and a.g == pytest.approx(b.g, abs=1e-15)
    for k in ("medium", "background"):
        assert got.get(k) == want.get(k)


def render(raw, **kw):
    return raytrace.render(raw, method="quadrature", width=48, height=32, spp=1, **kw).array


# -- the Blender room ----------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["room.glb", "room.gltf"])
def test_blender_room_imports_as_the_hand_written_scene(name):
    assert_same_scene(gltf.read_scene(DATA / name), read_toml(DATA / "room.toml"))


def _room_pair(with_spot):
    got, want = gltf.read_scene(DATA / "room.glb"), read_toml(DATA / "room.toml")
    for raw in (got, want):
        raw["medium"] = dict(FOG)
        if not with_spot:
            del raw["light"][1]
    # the same rays and the same cone: Blender stores their angles in float32 (compared above)
    want["camera"] = got["camera"]
    if with_spot:
        want["light"][1].pop("look_at")
        want["light"][1].update({k: got["light"][1][k] for k in ("direction", "cone_angle", "falloff_start")})
    return got, want


def test_blender_room_renders_as_the_hand_written_scene():
    """Point light, fog, the absorbing block on the floor: the same image to rounding (3e-15 measured)."""
    got, want = _room_pair(with_spot=False)
    a, b = render(got), render(want)
    assert a.max() > 0.05 and np.all(np.isfinite(a))
    np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-14)


def test_blender_room_with_its_spot_renders_as_the_hand_written_scene():
    got, want = _room_pair(with_spot=True)
    np.testing.assert_allclose(render(got), render(want), rtol=1e-10, atol=1e-14)


@pytest.mark.peers
@pytest.mark.skipif(shutil.which("blender") is None, reason="needs Blender (Debian: apt-get install blender python3-numpy)")
@pytest.mark.parametrize("name", ["room.glb", "room.gltf"])
def test_blender_exports_the_room_afresh(tmp_path, name):
    """Blender's exporter run now (make_room.py) gives the hand-written scene, like the committed files."""
    subprocess.run(["blender", "-b", "--factory-startup", "--python", str(DATA / "make_room.py"), "--", str(tmp_path)],
                   check=True, capture_output=True, timeout=600)
    assert_same_scene(gltf.read_scene(tmp_path / name), read_toml(DATA / "room.toml"))


def test_blender_units_are_candela_over_683():
    """Blender writes W / (4 pi) x 683 cd for a point light of W watts; we read W/sr = cd / 683."""
    doc = json.loads((DATA / "room.gltf").read_text())
    cd = doc["extensions"]["KHR_lights_punctual"]["lights"][0]["intensity"]
    assert cd == pytest.approx(100.0 / (4.0 * math.pi) * 683.0, rel=1e-15)
    light = gltf.read_scene(DATA / "room.gltf")["light"][0]
    np.testing.assert_allclose(light["intensity"], np.array([1.0, 0.75, 0.5]) * cd / 683.0, rtol=1e-15)


# -- round trips ---------------------------------------------------------------------------------------

def trip_scene(spot=False):
    """Every shape kind, a scattering HG interior behind glass, an absorbing one, a point light (and a spot)."""
    raw = {
        "camera": {"position": [0.25, 1.5, 3.5], "look_at": [0.0, 0.5, 0.0], "up": [0.0, 1.0, 0.25], "fov": 45.0,
                   "width": 40, "height": 24, "spp": 1},
        "shape": [
            {"primitive": "box", "min": [-3.0, 0.0, -3.0], "max": [3.0, 3.0, 4.0], "reflectance": [0.5, 0.625, 0.75]},
            {"primitive": "quad", "corners": [[-1.0, 1.5, -1.0], [1.0, 1.5, -1.0], [1.0, 1.5, -0.5], [-1.0, 1.5, -0.5]],
             "reflectance": 0.25},
            {"primitive": "box", "min": [0.5, 0.0, 0.0], "max": [1.5, 1.0, 1.0],
             "interior": {"sigma_a": [0.5, 1.0, 2.0], "sigma_s": [0.75, 0.5, 0.25], "phase": {"type": "hg", "g": 0.5},
                          "ior": 1.0}},
            {"primitive": "sphere", "center": [-1.0, 0.5, 0.5], "radius": 0.5, "segments": 12,
             "interior": {"sigma_a": 0.25, "ior": 1.33}},
            {"primitive": "triangles", "vertices": [[0.0, 2.0, -2.0], [1.0, 2.0, -2.0], [0.0, 2.5, -2.0]],
             "faces": [[0, 1, 2]], "transform": {"scale": 2.0, "rotate": [0.0, 30.0, 0.0], "translate": [0.5, 0.0, 0.0]}},
        ],
        "light": [{"type": "point", "position": [1.0, 2.5, 2.0], "intensity": [8.0, 6.0, 4.0]}],
        "medium": {"sigma_a": 0.01, "sigma_s": [0.05, 0.04, 0.03], "phase": {"type": "hg", "g": 0.3}},
        "background": {"radiance": [0.0, 0.0, 0.125]},
    }
    if spot:
        raw["light"].append({"type": "spot", "position": [-1.0, 2.75, 1.0], "look_at": [-0.5, 0.0, 0.0],
                             "intensity": 20.0, "cone_angle": 35.0, "falloff_start": 20.0, "falloff": "gltf"})
    return raw


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_round_trip_gives_the_same_scene(tmp_path, suffix):
    raw = trip_scene(spot=True)
    files = gltf.export(raw, tmp_path / f"s{suffix}", "trip.toml", approximate=False)
    assert [f.name for f in files] == ([f"s{suffix}"] if suffix == ".glb" else ["s.bin", "s.gltf"])
    assert sum(f.stat().st_size for f in files) < 20_000
    back = gltf.read_scene(tmp_path / f"s{suffix}")
    assert_same_scene(back, raw)
    # triangles in the same order, each corner the float32 of the original
    want, _, _ = shapes_of(raw)
    got, _, _ = shapes_of(back)
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w.astype(np.float32).astype(np.float64))


def test_round_trip_renders_the_same_image(tmp_path):
    raw = trip_scene()
    out = tmp_path / "s.glb"
    assert main(["export", _write(tmp_path, raw), "--format", "gltf", "--out", str(out)]) == 0
    back = gltf.read_scene(out)
    # the sphere's and the turned triangle's corners are rounded to float32: compare on the same ones
    for i in (3, 4):
        raw["shape"][i] = copy.deepcopy(back["shape"][i])
    a, b = render(raw), render(back)
    assert a.max() > 0.01
    np.testing.assert_allclose(b, a, rtol=1e-9, atol=1e-14)
    # and through the file path, as `render.py render s.glb` reads it
    np.testing.assert_allclose(raytrace.render(str(out), method="quadrature", width=48, height=32).array, b, rtol=1e-12)


def test_round_trip_with_a_gltf_spot_renders_the_same_image(tmp_path):
    raw = trip_scene(spot=True)
    gltf.export(raw, tmp_path / "s.glb", "trip.toml", approximate=False)
    back = gltf.read_scene(tmp_path / "s.glb")
    for i in (3, 4):
        raw["shape"][i] = copy.deepcopy(back["shape"][i])
    np.testing.assert_allclose(render(back), render(raw), rtol=1e-9, atol=1e-14)


def _write(tmp_path, raw):
    from .conftest import to_toml

    path = tmp_path / "scene.toml"
    path.write_text(to_toml(raw))
    return str(path)


def test_export_writes_khr_units_and_volumes(tmp_path):
    """The file itself, against the KHR definitions: cd = 683 W/sr, sigma_t = -ln(c) / d, the draft's albedo."""
    raw = trip_scene(spot=True)
    gltf.export(raw, tmp_path / "s.gltf", "trip.toml", approximate=False)
    doc = json.loads((tmp_path / "s.gltf").read_text())
    point, spot = doc["extensions"]["KHR_lights_punctual"]["lights"]
    np.testing.assert_allclose(np.multiply(point["color"], point["intensity"]), np.array([8.0, 6.0, 4.0]) * 683.0)
    assert spot["spot"]["outerConeAngle"] == pytest.approx(math.radians(35.0))
    assert spot["spot"]["innerConeAngle"] == pytest.approx(math.radians(20.0))
    ext = doc["materials"][2]["extensions"]
    vol, scatter = ext["KHR_materials_volume"], ext["KHR_materials_volume_scatter"]
    sigma_t = -np.log(vol["attenuationColor"]) / vol["attenuationDistance"]
    np.testing.assert_allclose(sigma_t, [1.25, 1.5, 2.25], rtol=1e-14)
    m = np.array(scatter["multiscatterColor"])
    rho = 1 - (4.09712 + 4.20863 * m - np.sqrt(9.59217 + 41.6808 * m + 17.7126 * m ** 2)) ** 2  # the draft's formula
    np.testing.assert_allclose(rho, np.array([0.75, 0.5, 0.25]) / [1.25, 1.5, 2.25], rtol=1e-12)
    assert scatter["scatterAnisotropy"] == 0.5 and ext["KHR_materials_ior"]["ior"] == 1.0
    assert vol["thicknessFactor"] > 0 and ext["KHR_materials_transmission"]["transmissionFactor"] == 1.0
    assert doc["materials"][3]["extensions"]["KHR_materials_ior"]["ior"] == 1.33
    assert "KHR_materials_volume_scatter" not in doc["materials"][3]["extensions"]


def test_the_multiscatter_inversion_against_scipy():
    from scipy.optimize import brentq

    def draft(m):
        return 1 - (4.09712 + 4.20863 * m - math.sqrt(9.59217 + 41.6808 * m + 17.7126 * m * m)) ** 2

    for rho in (1e-4, 0.1, 0.5, 0.9, 0.999):
        m = brentq(lambda x: draft(x) - rho, 0.0, 1.0, xtol=1e-15)
        assert gltf.multi_scatter_albedo(rho) == pytest.approx(m, abs=1e-12)
        assert gltf.single_scatter_albedo(m) == pytest.approx(rho, rel=1e-10)
    assert gltf.single_scatter_albedo(0.0) == 0.0  # the draft's default: no scattering


# -- what glTF cannot express ------------------------------------------------------------------------------

@pytest.mark.parametrize("change, key", [
    ({"medium": {"type": "height_fog", "sigma_s": 0.05, "scale_height": 2.0}}, "medium.type"),
    ({"camera": {"type": "environment", "position": [0.0, 1.0, 0.0], "look_at": [0.0, 1.0, -1.0]}}, "camera.type"),
    ({"light": [{"type": "spot", "position": [0.0, 2.0, 0.0], "direction": [0.0, -1.0, 0.0], "intensity": 1.0,
                 "cone_angle": 30.0}]}, "light[0].falloff"),
    ({"light": [{"type": "spot", "position": [0.0, 2.0, 0.0], "direction": [0.0, -1.0, 0.0], "intensity": 1.0,
                 "cone_angle": 30.0, "falloff": "mitsuba"}]}, "light[0].falloff"),
    ({"light": [{"type": "spot", "position": [0.0, 2.0, 0.0], "direction": [0.0, -1.0, 0.0], "intensity": 1.0,
                 "cone_angle": 120.0, "falloff_start": 10.0, "falloff": "gltf"}]}, "light[0].cone_angle"),
    ({"shape": [{"primitive": "box", "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 1.0],
                 "interior": {"sigma_s": 0.5, "phase": "rayleigh"}}]}, "shape[0].interior.phase"),
])
def test_what_gltf_cannot_express_is_refused_naming_the_key(tmp_path, change, key):
    raw = trip_scene() | change
    with pytest.raises(UserError) as err:
        gltf.export(raw, tmp_path / "s.glb", "trip.toml", approximate=False)
    assert str(err.value).startswith(f"trip.toml: {key}: ") and "\n" not in str(err.value)
    assert not list(tmp_path.iterdir())


def test_approximate_writes_the_closest_form_with_a_warning(tmp_path):
    raw = trip_scene() | {"light": [{"type": "spot", "position": [0.0, 2.0, 0.0], "direction": [0.0, -1.0, 0.0],
                                     "intensity": 1.0, "cone_angle": 30.0, "falloff_start": 30.0}]}
    with pytest.warns(gltf.GltfNote, match=r"light\[0\]\.falloff: \"smoothstep\" spot falloff.*--approximate"):
        gltf.export(raw, tmp_path / "s.glb", "trip.toml", approximate=True)
    spot = gltf.read_scene(tmp_path / "s.glb")["light"][0]
    assert spot["falloff"] == "gltf" and spot["cone_angle"] == pytest.approx(30.0)
    assert 0 < spot["cone_angle"] - spot["falloff_start"] < 1e-4


def test_export_cli_refuses_in_one_line_and_writes_nothing(tmp_path, capsys):
    raw = trip_scene() | {"medium": {"type": "height_fog", "sigma_s": 0.05, "scale_height": 2.0}}
    out = tmp_path / "s.gltf"
    assert main(["export", _write(tmp_path, raw), "--format", "gltf", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "medium.type" in err and "height fog" in err
    assert not out.exists() and not out.with_suffix(".bin").exists()


# -- hand-written files: transforms, materials, lights, cameras --------------------------------------------

TRIANGLE = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], dtype=np.float32)


def write_gltf(tmp_path, doc, blob=TRIANGLE.tobytes(), name="t.gltf", embed=True):
    """A .gltf around one buffer (a data URI, or a .bin beside it) holding `blob`."""
    base = {"asset": {"version": "2.0"}, "accessors": [
        {"bufferView": 0, "componentType": 5126, "count": len(blob) // 12, "type": "VEC3"}],
        "bufferViews": [{"buffer": 0, "byteLength": len(blob)}],
        "buffers": [{"byteLength": len(blob), "uri": ("data:application/octet-stream;base64,"
                                                      + base64.b64encode(blob).decode()) if embed else "t.bin"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "material": 0}]}],
        "materials": [{"doubleSided": True, "pbrMetallicRoughness": {"metallicFactor": 0.0}}]}
    base.update(doc)
    path = tmp_path / name
    path.write_text(json.dumps(base))
    if not embed:
        (tmp_path / "t.bin").write_bytes(blob)
    return path


def test_node_transforms_trs_matrix_and_hierarchy(tmp_path):
    """Child (T R S) under a parent given as a column-major matrix: x' = M_parent (T + R (S x))."""
    s, half = math.sqrt(0.5), math.sqrt(0.5)
    parent = np.array([[2.0, 0, 0, 10.0], [0, 2.0, 0, 20.0], [0, 0, 2.0, 30.0], [0, 0, 0, 1]])
    doc = {"nodes": [{"matrix": parent.T.ravel().tolist(), "children": [1]},
                     {"mesh": 0, "translation": [1.0, 2.0, 3.0], "rotation": [0.0, s, 0.0, half], "scale": [3.0, 1.0, 1.0]}],
           "scenes": [{"nodes": [0]}]}
    got = gltf.read_scene(write_gltf(tmp_path, doc))["shape"][0]["vertices"]
    # a quarter turn about +y takes (x, y, z) to (z, y, -x)
    child = [[1 + 0, 2 + 0, 3 - 0], [1 + 0, 2 + 0, 3 - 3], [1 + 0, 2 + 1, 3 - 0]]
    np.testing.assert_allclose(got, 2.0 * np.array(child) + [10.0, 20.0, 30.0], atol=1e-14)


def test_lights_units_directions_and_cones(tmp_path):
    s = math.sqrt(0.5)
    lights = [{"type": "point", "color": [1.0, 0.5, 0.25], "intensity": 683.0, "range": 5.0},
              {"type": "spot", "intensity": 1366.0, "spot": {"innerConeAngle": 0.25, "outerConeAngle": 0.5}},
              {"type": "directional", "color": [0.5, 1.0, 1.0], "intensity": 6830.0}]
    doc = {"extensions": {"KHR_lights_punctual": {"lights": lights}},
           "nodes": [{"translation": [1.0, 2.0, 3.0], "extensions": {"KHR_lights_punctual": {"light": 0}}},
                     {"translation": [0.0, 4.0, 0.0], "rotation": [-s, 0.0, 0.0, s],  # -Z turned to -Y
                      "extensions": {"KHR_lights_punctual": {"light": 1}}},
                     {"rotation": [0.0, s, 0.0, s], "extensions": {"KHR_lights_punctual": {"light": 2}}}]}
    with pytest.warns(gltf.GltfNote, match=r"lights\[0\]\.range: not applied"):
        point, spot, sun = gltf.read_scene(write_gltf(tmp_path, doc))["light"]
    assert point == {"type": "point", "position": [1.0, 2.0, 3.0], "intensity": [1.0, 0.5, 0.25]}
    assert spot["intensity"] == [2.0, 2.0, 2.0] and spot["falloff"] == "gltf"
    np.testing.assert_allclose(spot["direction"], [0.0, -1.0, 0.0], atol=1e-15)
    assert spot["cone_angle"] == pytest.approx(math.degrees(0.5)) and spot["falloff_start"] == pytest.approx(math.degrees(0.25))
    assert sun["type"] == "directional" and sun["irradiance"] == [5.0, 10.0, 10.0]
    np.testing.assert_allclose(sun["direction"], [-1.0, 0.0, 0.0], atol=1e-15)  # -Z turned a quarter about +y


def test_cameras_by_name_aspect_and_orthographic(tmp_path):
    cams = [{"name": "ortho", "type": "orthographic", "orthographic": {"xmag": 1, "ymag": 1, "znear": 0.1, "zfar": 9}},
            {"name": "wide", "type": "perspective", "perspective": {"yfov": 0.5, "aspectRatio": 2.0, "znear": 0.1}},
            {"name": "square", "type": "perspective", "perspective": {"yfov": 1.0, "znear": 0.1}}]
    doc = {"cameras": cams, "nodes": [{"camera": 0}, {"camera": 1, "translation": [0, 1, 5]},
                                      {"camera": 2, "name": "node-of-square"}]}
    path = write_gltf(tmp_path, doc)
    with pytest.warns(gltf.GltfNote, match=r"cameras\[0\]: 'orthographic' camera left out"):
        first = gltf.read_scene(path)["camera"]
    assert (first["width"], first["height"], first["fov"]) == (1024, 512, pytest.approx(math.degrees(0.5)))
    assert first["position"] == [0, 1, 5] and first["look_at"] == [0, 1, 4]
    by_node = gltf.read_scene(path, camera="node-of-square")["camera"]
    assert (by_node["width"], by_node["height"]) == (512, 512)
    with pytest.raises(UserError, match=r"no camera named 'nope'; choose one of: node-of-square, ortho, square, wide"):
        gltf.read_scene(path, camera="nope")


def test_material_notes_and_texture_mean(tmp_path):
    from PIL import Image

    Image.fromarray(np.array([[[255, 0, 255], [0, 255, 255]]], dtype=np.uint8)).save(tmp_path / "tex.png")
    doc = {"nodes": [{"mesh": 0}], "images": [{"uri": "tex.png"}], "textures": [{"source": 0}],
           "materials": [{"emissiveFactor": [1.0, 0.0, 0.0], "pbrMetallicRoughness": {
               "baseColorFactor": [0.5, 0.5, 1.0, 1.0], "baseColorTexture": {"index": 0}}}]}
    with pytest.warns(gltf.GltfNote) as notes:
        shape = gltf.read_scene(write_gltf(tmp_path, doc))["shape"][0]
    text = " | ".join(str(n.message) for n in notes)
    for part in ("metallicFactor: metals are rendered as diffuse",
                 "doubleSided: single-sided in glTF; rendered two-sided (both faces reflect), emitting from its front",
                 "baseColorTexture: replaced by its mean"):
        assert part in text, text
    # sRGB 0 and 255 are linear 0 and 1 under any transfer curve: mean (0.5, 0.5, 1)
    np.testing.assert_allclose(shape["reflectance"], [0.25, 0.25, 1.0], rtol=1e-15)
    # emission (read since the lights issue): emissiveFactor (x emissiveStrength, 1), one-sided as the material
    assert shape["emission"] == [1.0, 0.0, 0.0] and shape["two_sided"] is False


def test_volume_with_scatter_draft_and_default_ior(tmp_path):
    cube = trimesh.creation.box().triangles.astype(np.float32).reshape(-1, 3)
    m = [0.2, 0.5, 0.8]
    doc = {"nodes": [{"mesh": 0}], "materials": [{"doubleSided": True, "extensions": {
        "KHR_materials_transmission": {"transmissionFactor": 1.0},
        "KHR_materials_volume": {"thicknessFactor": 1.0, "attenuationColor": [0.5, 0.6, 0.7], "attenuationDistance": 2.0},
        "KHR_materials_volume_scatter": {"multiscatterColor": m, "scatterAnisotropy": -0.25}}}]}
    interior = gltf.read_scene(write_gltf(tmp_path, doc, cube.tobytes()))["shape"][0]["interior"]
    sigma_t = -np.log([0.5, 0.6, 0.7]) / 2.0
    rho = [1 - (4.09712 + 4.20863 * x - math.sqrt(9.59217 + 41.6808 * x + 17.7126 * x * x)) ** 2 for x in m]
    np.testing.assert_allclose(interior["sigma_s"], sigma_t * rho, rtol=1e-14)
    np.testing.assert_allclose(interior["sigma_a"], sigma_t * (1 - np.array(rho)), rtol=1e-14)
    assert interior["phase"] == {"type": "hg", "g": -0.25} and interior["ior"] == 1.5  # KHR_materials_ior's default


# -- bad input: one line, exit 2, nothing written --------------------------------------------------------

def _cli_refuses(path, capsys, tmp_path, *parts):
    out = tmp_path / "x.exr"
    assert main(["render", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and str(path) in err, err
    for p in parts:
        assert p in err, err
    assert not out.exists()


def test_malformed_json_names_the_line(tmp_path, capsys):
    path = tmp_path / "bad.gltf"
    path.write_text('{\n  "asset": {"version": "2.0"},\n  "nodes": [\n    {"name": "a",}\n  ]\n}\n')
    _cli_refuses(path, capsys, tmp_path, "malformed JSON at line 4")


@pytest.mark.parametrize("literal", ["NaN", "Infinity", "-Infinity", "1e999"])
def test_non_finite_json_numbers_are_refused(tmp_path, capsys, literal):
    path = tmp_path / "bad.gltf"
    path.write_text('{"asset": {"version": "2.0"},\n"nodes": [{"translation": [0, ' + literal + ', 0]}]}')
    _cli_refuses(path, capsys, tmp_path, f"{literal} at line 2 is not finite")


def test_non_finite_vertices_are_refused(tmp_path, capsys):
    blob = np.array([[0, 0, 0], [1, np.nan, 0], [0, 1, 0]], dtype=np.float32).tobytes()
    path = write_gltf(tmp_path, {"nodes": [{"mesh": 0}]}, blob)
    _cli_refuses(path, capsys, tmp_path, "accessors[0]: 1 of its 3 elements is not finite")


def test_a_missing_buffer_is_refused(tmp_path, capsys):
    path = write_gltf(tmp_path, {"nodes": [{"mesh": 0}]}, embed=False)
    (tmp_path / "t.bin").unlink()
    _cli_refuses(path, capsys, tmp_path, "buffers[0].uri: 't.bin' is missing", "copy t.bin next to t.gltf")


def test_a_short_buffer_and_an_accessor_past_its_view_are_refused(tmp_path, capsys):
    path = write_gltf(tmp_path, {"nodes": [{"mesh": 0}], "buffers": [
        {"byteLength": 36, "uri": "data:application/octet-stream;base64," + base64.b64encode(b"\0" * 20).decode()}]})
    _cli_refuses(path, capsys, tmp_path, "buffers[0].byteLength: says 36 bytes but the data has 20")
    path = write_gltf(tmp_path, {"nodes": [{"mesh": 0}], "accessors": [
        {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"}]})
    _cli_refuses(path, capsys, tmp_path, "accessors[0]: 4 elements run past the end of bufferViews[0]")


def test_an_accessor_beyond_the_memory_budget_is_refused_before_reading(tmp_path, capsys):
    path = write_gltf(tmp_path, {"nodes": [{"mesh": 0}], "accessors": [
        {"bufferView": 0, "componentType": 5126, "count": 2 ** 40, "type": "VEC3"}]})
    _cli_refuses(path, capsys, tmp_path, "accessors[0].count: 1099511627776 elements would take", "memory budget")
    path = write_gltf(tmp_path, {"nodes": [{"mesh": 0}], "accessors": [
        {"bufferView": 0, "componentType": 5126, "count": 10 ** 400, "type": "VEC3"}]})
    _cli_refuses(path, capsys, tmp_path, "is beyond 64-bit integers")


def test_a_truncated_glb_is_refused(tmp_path, capsys):
    data = (DATA / "room.glb").read_bytes()
    path = tmp_path / "cut.glb"
    path.write_bytes(data[:len(data) // 2])
    _cli_refuses(path, capsys, tmp_path, "truncated")


def test_compressed_meshes_and_node_cycles_are_refused(tmp_path, capsys):
    path = write_gltf(tmp_path, {"nodes": [{"mesh": 0}], "extensionsUsed": ["KHR_draco_mesh_compression"],
                                 "extensionsRequired": ["KHR_draco_mesh_compression"]})
    _cli_refuses(path, capsys, tmp_path, "KHR_draco_mesh_compression: compressed meshes are not decoded")
    path = write_gltf(tmp_path, {"nodes": [{"children": [1]}, {"children": [0]}], "scenes": [{"nodes": [0]}]})
    _cli_refuses(path, capsys, tmp_path, "nodes[0].children: the node is its own ancestor")


def test_the_glb_container_is_read_like_the_gltf(tmp_path):
    """room.glb and room.gltf + room.bin (both from Blender) give identical dicts."""
    a, b = gltf.read_scene(DATA / "room.glb"), gltf.read_scene(DATA / "room.gltf")
    for sa, sb in zip(a.pop("shape"), b.pop("shape")):
        np.testing.assert_array_equal(sa.pop("vertices"), sb.pop("vertices"))
        np.testing.assert_array_equal(sa.pop("faces"), sb.pop("faces"))
        np.testing.assert_array_equal(sa.pop("normals"), sb.pop("normals"))  # Blender writes NORMAL
        assert sa == sb
    assert a == b
    header = struct.unpack_from("<4sII", (DATA / "room.glb").read_bytes())
    assert header[0] == b"glTF" and header[1] == 2


def test_any_value_of_the_wrong_type_is_a_one_line_refusal(tmp_path):
    """Every key of the Blender room set in turn to a value of another type or range: the import and
    the scene's validation end in a UserError (or succeed), never in a traceback; its problems are one
    line each."""
    base = json.loads((DATA / "room.gltf").read_text())
    base["buffers"][0]["uri"] = str(DATA / "room.bin")
    paths = []

    def walk(node, at=()):
        for k, v in (node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()):
            paths.append(at + (k,))
            walk(v, at + (k,))

    walk(base)
    wrong = ["x", -1, 0, 1e30, [], {}, None, True, [1, 2], 2 ** 40, 0.5]
    path = tmp_path / "f.gltf"
    for n, at in enumerate(paths):
        doc = copy.deepcopy(base)
        node = doc
        for k in at[:-1]:
            node = node[k]
        node[at[-1]] = wrong[n % len(wrong)]
        path.write_text(json.dumps(doc))
        try:
            raw = gltf.read_scene(path)
            scene_from_dict(raw, str(path), path)
        except UserError as exc:  # one line, or a file's several problems one a line (exc.lines)
            lines = exc.lines or [str(exc)]
            assert str(exc) == "\n".join(lines) and "malformed glTF (" not in str(exc), (at, exc)


def test_file_without_camera_gets_one_framing_the_scene(tmp_path):
    """A default perspective camera (said in one note) looks at the centre of the shapes' bounding box
    with every corner of the box in view; --set moves it."""
    cube = (trimesh.creation.box(extents=[2.0, 1.0, 4.0]).triangles + [10.0, -3.0, 1.0]).astype(np.float32)
    path = write_gltf(tmp_path, {"nodes": [{"mesh": 0}]}, cube.reshape(-1, 3).tobytes())
    with warnings.catch_warnings(record=True) as notes:
        warnings.simplefilter("always")
        cam = scene_from_dict(gltf.read_scene(path), "t").camera
    said = [str(n.message) for n in notes if "no perspective camera" in str(n.message)]
    assert len(said) == 1 and "--set camera.position=" in said[0]
    np.testing.assert_allclose(cam.look_at, [10.0, -3.0, 1.0], atol=1e-6)
    forward = unit(cam.look_at - cam.position)
    assert forward == pytest.approx([0.0, 0.0, -1.0])  # from +z of the centre
    corners = np.array([[x, y, z] for x in (9, 11) for y in (-3.5, -2.5) for z in (-1, 3)], dtype=np.float64)
    to = corners - cam.position
    half = math.radians(cam.fov) / 2.0  # a square image: the same half-angle across and up
    assert np.all(np.abs(to[:, 0] / -to[:, 2]) <= math.tan(half)) and np.all(np.abs(to[:, 1] / -to[:, 2]) <= math.tan(half))
    moved = raytrace.load(path, overrides=["camera.position=[10, -3, 20]"]).camera
    assert moved.position.tolist() == [10.0, -3.0, 20.0]


def test_notes_of_one_kind_are_one_line(tmp_path):
    """16 single-sided materials: one note naming them and their count, not 16."""
    doc = {"nodes": [{"mesh": i} for i in range(16)], "materials": [{} for _ in range(16)],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "material": i}]} for i in range(16)]}
    with warnings.catch_warnings(record=True) as notes:
        warnings.simplefilter("always")
        gltf.read_scene(write_gltf(tmp_path, doc))
    sided = [str(n.message) for n in notes if "doubleSided" in str(n.message)]
    assert sided == [f"{tmp_path / 't.gltf'}: materials[0, 1, 2, 3, 4, 5, 6, 7, ...].doubleSided (16 materials): "
                     "single-sided in glTF; rendered two-sided (both faces reflect)"]


def test_scene_without_lights_warns_and_says_how_to_add_one(tmp_path, capsys):
    """The warning names a point lamp above and behind the camera (never at it); added with --set as
    it says, the image is no longer black and the warning is not given (it is given after the
    overrides)."""
    cube = trimesh.creation.box().triangles.astype(np.float32)
    path = write_gltf(tmp_path, {"nodes": [{"mesh": 0}]}, cube.reshape(-1, 3).tobytes())
    with warnings.catch_warnings(record=True) as notes:
        warnings.simplefilter("always")
        assert main(["describe", str(path)]) == 0
    line = next(str(n.message) for n in notes if "no lights" in str(n.message))
    assert "the scene has no lights; it renders black" in line
    lamp = re.search(r"--set '(light=\[\{.*\}\])'", line).group(1)
    cam = gltf.read_scene(path)["camera"]
    pos = np.array([float(x) for x in re.search(r"position = \[(.*?)\]", lamp).group(1).split(",")])
    offset = pos - cam["position"]
    assert offset[1] > 0.1 and offset[2] > 0.1  # above (+y) and behind (the camera looks down -z)
    out = tmp_path / "lit.exr"
    with warnings.catch_warnings(record=True) as notes:  # the lamp given, the warning goes
        warnings.simplefilter("always")
        assert main(["render", str(path), "--set", lamp, "--width", "8", "--height", "8", "--spp", "1",
                     "--out", str(out)]) == 0
    assert not [n for n in notes if "no lights" in str(n.message)]
    from raytrace.output.film import read_exr

    assert np.max(read_exr(out)[0]) > 0.0


def test_a_refused_file_lists_all_its_problems_in_one_run(tmp_path):
    """An unknown required extension and two primitives that cannot be read: three lines after the
    count, each naming its key (glTF's wording: keys, not TOML tables)."""
    doc = {"extensionsRequired": ["EXT_unknown"], "nodes": [{"mesh": 0}, {"mesh": 1}],
           "meshes": [{"primitives": [{"attributes": {}}]},
                      {"primitives": [{"attributes": {"POSITION": 0}, "extensions": {"KHR_draco_mesh_compression": {}}}]}]}
    with pytest.raises(UserError) as err:
        gltf.read_scene(write_gltf(tmp_path, doc))
    lines = str(err.value).splitlines()
    assert lines[0] == f"{tmp_path / 't.gltf'}: 3 problems, one a line with its fix"
    for line, part in zip(lines[1:], ["extensionsRequired: EXT_unknown: this extension is not read",
                                      "meshes[0].primitives[0].attributes.POSITION: missing",
                                      "meshes[1].primitives[0]: Draco-compressed meshes are not decoded"]):
        assert part in line and "[camera]" not in line, (line, part)
