"""Area lights, emissive shapes, the environment and shading normals through the Mitsuba 3, pbrt-v4 and
glTF importers and exporters (raytrace/io/emitters.py; the keys of docs/scene_format.md).

Expected dicts are worked out by hand from each file and the formats' sources: mitsuba3
src/shapes/rectangle.cpp, disk.cpp (the shape's +z, to_world^-T, flip_normals), src/emitters/area.cpp
(one-sided, towards the shading normal), envmap.cpp; pbrt-v4 lights.cpp DiffuseAreaLight::Create (L x
scale x power / ((twosided ? 2 : 1) pi A), A per shape) and Light::Create "infinite", shapes.h (normals
flipped by ReverseOrientation, a triangle's towards N); glTF 2.0 (NORMAL, a mirroring node's winding)
and Blender's exporter (emissiveFactor x emissiveStrength = Emission Strength). Round trips:
import -> export -> import gives the same emitters. `-m peers`: Mitsuba 3 itself agrees on the envmap's
orientation and the rectangles' and disks' emitting sides.
"""
from __future__ import annotations

import base64
import json
import math
from pathlib import Path

import numpy as np
import pytest

from raytrace.errors import UserError
from raytrace.io import gltf, mitsuba, pbrt
from raytrace.output.film import write_exr
from raytrace.scene.meshes import rotation_matrix

from .conftest import to_toml


def winding(shape) -> np.ndarray:
    """Unit winding normals (v1 - v0) x (v2 - v0) of a triangles shape, one per face."""
    t = np.asarray(shape["vertices"], float)[np.asarray(shape["faces"])]
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def quad_normal(corners) -> np.ndarray:
    c = np.asarray(corners, float)
    n = np.cross(c[1] - c[0], c[3] - c[0])
    return n / np.linalg.norm(n)


# ------------------------------------------------------------------------------------------------ Mitsuba

SENSOR = ('<sensor type="perspective"><float name="fov" value="40"/><transform name="to_world"><lookat '
          'origin="0, 1, 6" target="0, 1, 0" up="0, 1, 0"/></transform><film type="hdrfilm"><integer name="width" '
          'value="32"/><integer name="height" value="24"/></film></sensor>')
EMITTERS_XML = """
<shape type="rectangle">
    <transform name="to_world"><scale x="0.5" y="0.25"/><rotate x="1" angle="90"/><translate y="2"/></transform>
    <emitter type="area"><rgb name="radiance" value="4, 5, 6"/></emitter>
</shape>
<shape type="rectangle">
    <boolean name="flip_normals" value="true"/>
    <transform name="to_world"><scale x="-1"/><translate z="-3"/></transform>
    <emitter type="area"><rgb name="radiance" value="1"/></emitter>
</shape>
<shape type="disk">
    <transform name="to_world"><scale value="0.3"/><rotate x="1" angle="-90"/><translate x="1" y="3"/></transform>
    <emitter type="area"><rgb name="radiance" value="20"/></emitter>
</shape>
<shape type="sphere">
    <point name="center" x="0" y="1" z="-1"/><float name="radius" value="0.25"/>
    <emitter type="area"><rgb name="radiance" value="7, 8, 9"/></emitter>
</shape>
<shape type="obj">
    <string name="filename" value="tri.obj"/>
    <emitter type="area"><rgb name="radiance" value="3, 2, 1"/></emitter>
</shape>
<emitter type="constant"><rgb name="radiance" value="0.1, 0.2, 0.3"/></emitter>
<emitter type="envmap">
    <string name="filename" value="sky.exr"/><float name="scale" value="2"/>
    <transform name="to_world"><rotate y="1" angle="90"/></transform>
</emitter>
"""
# a triangle wound towards -y whose vertex normal says +y: Mitsuba emits towards the shading normal
TRI_OBJ = "v 0 0 0\nv 1 0 0\nv 0 0 1\nvn 0 1 0\nf 1//1 2//1 3//1\n"


def sky(folder: Path) -> Path:
    rng = np.random.default_rng(7)
    write_exr(folder / "sky.exr", rng.uniform(0.1, 1.0, (8, 16, 3)))
    return folder / "sky.exr"


def mitsuba_file(tmp_path, body=EMITTERS_XML) -> Path:
    (tmp_path / "tri.obj").write_text(TRI_OBJ)
    sky(tmp_path)
    path = tmp_path / "scene.xml"
    path.write_text(f'<scene version="3.0.0">{SENSOR}{body}</scene>')
    return path


def test_mitsuba_emitters_read_as_worked_out_by_hand(tmp_path):
    raw = mitsuba.read_scene(mitsuba_file(tmp_path))
    quad, flipped, disk, sphere, constant, envmap = raw["light"]
    # [-1, 1]^2 scaled (0.5, 0.25), turned 90 degrees about x (y -> z, z -> -y), up 2: its +z emits down
    assert quad == {"type": "quad", "corners": [[-0.5, 2.0, -0.25], [0.5, 2.0, -0.25], [0.5, 2.0, 0.25],
                                                [-0.5, 2.0, 0.25]], "radiance": [4.0, 5.0, 6.0]}
    np.testing.assert_allclose(quad_normal(quad["corners"]), [0.0, -1.0, 0.0], atol=1e-15)
    # mirrored in x: to_world^-T (0, 0, 1) is still +z, flip_normals turns it to -z; corners as mapped
    assert flipped["corners"] == [[1.0, -1.0, -3.0], [-1.0, -1.0, -3.0], [-1.0, 1.0, -3.0], [1.0, 1.0, -3.0]]
    np.testing.assert_allclose(quad_normal(flipped["corners"]), [0.0, 0.0, -1.0], atol=1e-15)
    assert flipped["radiance"] == 1.0
    # the unit disk scaled 0.3, turned -90 degrees about x (+z -> +y), at (1, 3, 0)
    assert disk["type"] == "disk" and disk["radius"] == pytest.approx(0.3, rel=1e-15) and disk["radiance"] == 20.0
    np.testing.assert_allclose(disk["center"], [1.0, 3.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(disk["normal"], [0.0, 1.0, 0.0], atol=1e-15)
    assert sphere == {"type": "sphere", "center": [0.0, 1.0, -1.0], "radius": 0.25, "radiance": [7.0, 8.0, 9.0]}
    assert constant == {"type": "environment", "radiance": [0.1, 0.2, 0.3]}
    # envmap.cpp: u = atan2(x, -z) / 2 pi in to_world's frame; ours has u = 1/2 along -z: R_y(90) R_y(180)
    assert envmap["map"] == str(tmp_path / "sky.exr") and envmap["scale"] == 2.0 and envmap["filter"] == "mitsuba"
    assert "mirror" not in envmap
    np.testing.assert_allclose(rotation_matrix(envmap["rotate"]), [[0, 0, -1], [0, 1, 0], [1, 0, 0]], atol=1e-12)
    (tri,) = raw["shape"]
    assert tri["emission"] == [3.0, 2.0, 1.0] and "two_sided" not in tri  # one-sided, as Mitsuba's
    np.testing.assert_allclose(winding(tri), [[0.0, 1.0, 0.0]], atol=1e-15)  # turned to the normal's side
    assert tri["normals"] == [[0.0, 1.0, 0.0]] * 3


def test_mitsuba_mesh_normals_from_the_file_or_recomputed_or_flat(tmp_path):
    """mesh.cpp: the file's normals; without them Mitsuba recomputes angle-weighted vertex normals (for a
    tent of two triangles at 90 degrees, the ridge's is the mean of the two faces'); face_normals: none."""
    (tmp_path / "tent.obj").write_text("v -1 0 0\nv 0 1 0\nv 0 1 1\nv 1 0 0\nf 1 2 3\nf 2 4 3\n")
    (tmp_path / "tri.obj").write_text(TRI_OBJ)
    body = ('<shape type="obj"><string name="filename" value="tent.obj"/></shape>'
            '<shape type="obj"><string name="filename" value="tent.obj"/><boolean name="face_normals" '
            'value="true"/></shape><shape type="obj"><string name="filename" value="tri.obj"/>'
            '<transform name="to_world"><scale x="2" y="1" z="1"/><rotate z="1" angle="90"/></transform></shape>')
    path = tmp_path / "scene.xml"
    path.write_text(f'<scene version="3.0.0">{SENSOR}{body}'
                    '<emitter type="point"><point name="position" value="0, 3, 0"/></emitter></scene>')
    smooth, flat, turned = mitsuba.read_scene(path)["shape"]
    n = np.asarray(smooth["normals"])
    left, right = np.array([-1.0, 1.0, 0.0]) / math.sqrt(2), np.array([1.0, 1.0, 0.0]) / math.sqrt(2)
    for v, normal in zip(smooth["vertices"], n):
        expect = {-1.0: -left, 1.0: -right}.get(v[0], -np.array([0.0, 1.0, 0.0]))  # winding: outward is -...
        np.testing.assert_allclose(np.abs(normal), np.abs(expect), atol=1e-12)
    assert np.allclose(n @ winding(smooth).sum(axis=0), np.abs(n @ winding(smooth).sum(axis=0)))  # winding side
    assert "normals" not in flat
    # a normal by the inverse transpose: (0, 1, 0) under diag(2, 1, 1) then 90 degrees about z is (-1, 0, 0)
    np.testing.assert_allclose(turned["normals"], [[-1.0, 0.0, 0.0]] * 3, atol=1e-15)


def test_mitsuba_refusals_name_the_key(tmp_path):
    cases = [('<shape type="disk"><transform name="to_world"><scale x="2"/></transform><emitter type="area"/></shape>',
              "an emitting disk's to_world stretches it into an ellipse"),
             ('<emitter type="envmap"><string name="filename" value="sky.png"/></emitter>', "only OpenEXR maps"),
             ('<emitter type="envmap"><string name="filename" value="sky.exr"/><transform name="to_world"><scale '
              'value="2"/></transform></emitter>', "an envmap's to_world must be a rotation"),
             ('<shape type="rectangle"><emitter type="area"/><emitter type="area"/></shape>', "more than one emitter")]
    (tmp_path / "sky.png").write_bytes(b"")
    for body, needle in cases:
        with pytest.raises(UserError, match=needle) as err:
            mitsuba.read_scene(mitsuba_file(tmp_path, body))
        assert "\n" not in str(err.value) and "scene.xml:" in str(err.value)


# --------------------------------------------------------------------------------------------------- pbrt

PBRT_HEAD = ('{mirror}LookAt 0 1 6  0 1 0  0 1 0\nCamera "perspective" "float fov" [ 40 ]\n'
             'Film "rgb" "integer xresolution" [ 32 ] "integer yresolution" [ 24 ]\nWorldBegin\n')
PBRT_WORLD = """
LightSource "infinite" "rgb L" [ 0.1 0.2 0.3 ] "float scale" [ 2 ]
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [ 1 2 3 ] "float scale" [ 2 ] "bool twosided" true
  Shape "bilinearmesh" "point3 P" [ -1 2 -1  1 2 -1  -1 2 1  1 2 1 ]
AttributeEnd
AttributeBegin
  Translate 0 3 0
  Rotate 90 1 0 0
  AreaLightSource "diffuse" "float power" [ 10 ]
  Shape "disk" "float radius" [ 0.5 ]
AttributeEnd
AttributeBegin
  Translate 2 1 0
  AreaLightSource "diffuse" "float power" [ 100 ] "bool twosided" true
  Shape "sphere" "float radius" [ 0.5 ]
AttributeEnd
AttributeBegin
  Translate 0 0 -2
  ReverseOrientation
  AreaLightSource "diffuse" "rgb L" [ 1 1 1 ] "float power" [ 6 ]
  Shape "trianglemesh" "point3 P" [ 0 0 0  2 0 0  0 2 0  -1 0 0 ] "integer indices" [ 0 1 2  0 2 3 ]
AttributeEnd
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [ 5 5 5 ]
  Shape "trianglemesh" "point3 P" [ 0 -1 0  0 -1 1  1 -1 0 ] "integer indices" [ 0 1 2 ] "normal N" [ 0 1 0  0 1 0  0 1 0 ]
AttributeEnd
"""


def pbrt_file(tmp_path, world=PBRT_WORLD, mirror="Scale -1 1 1\n") -> Path:
    path = tmp_path / "scene.pbrt"
    path.write_text(PBRT_HEAD.format(mirror=mirror) + world)
    return path


def test_pbrt_emitters_read_as_worked_out_by_hand(tmp_path):
    raw = pbrt.read_scene(pbrt_file(tmp_path))
    env, quad, disk, sphere = raw["light"]
    assert env == {"type": "environment", "radiance": pytest.approx([0.2, 0.4, 0.6], rel=1e-15)}
    # the patch p00 p10 p01 p11: normal dpdu x dpdv = (2, 0, 0) x (0, 0, 2), down; L x scale, two-sided
    assert quad == {"type": "quad", "corners": [[-1.0, 2.0, -1.0], [1.0, 2.0, -1.0], [1.0, 2.0, 1.0], [-1.0, 2.0, 1.0]],
                    "radiance": [2.0, 4.0, 6.0], "two_sided": True}
    np.testing.assert_allclose(quad_normal(quad["corners"]), [0.0, -1.0, 0.0], atol=1e-15)
    # power 10 over pi x (pi 0.5^2): 40 / pi^2; +z turned 90 degrees about x is -y
    assert disk["type"] == "disk" and disk["radius"] == 0.5 and "two_sided" not in disk
    np.testing.assert_allclose(disk["radiance"], [40.0 / math.pi ** 2] * 3, rtol=1e-15)
    np.testing.assert_allclose(disk["center"], [0.0, 3.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(disk["normal"], [0.0, -1.0, 0.0], atol=1e-15)
    # power 100 over 2 pi x 4 pi 0.25 (two-sided): 50 / pi^2
    assert sphere["type"] == "sphere" and sphere["center"] == [2.0, 1.0, 0.0] and sphere["radius"] == 0.5
    np.testing.assert_allclose(sphere["radiance"], [50.0 / math.pi ** 2] * 3, rtol=1e-15)
    big, small, turned = raw["shape"]
    # power 6 per triangle: areas 2 and 1 give 6 / 2 pi and 6 / pi; ReverseOrientation: they emit to -z
    np.testing.assert_allclose(big["emission"], [3.0 / math.pi] * 3, rtol=1e-15)
    np.testing.assert_allclose(small["emission"], [6.0 / math.pi] * 3, rtol=1e-15)
    for part in (big, small):
        assert len(part["faces"]) == 1
        np.testing.assert_allclose(winding(part), [[0.0, 0.0, -1.0]], atol=1e-15)
    # wound towards -y, N towards +y: pbrt's normal faces N, so the winding is turned to +y
    assert turned["emission"] == [5.0, 5.0, 5.0]
    np.testing.assert_allclose(winding(turned), [[0.0, 1.0, 0.0]], atol=1e-15)


def test_pbrt_mirrored_world_keeps_the_emitting_sides(tmp_path):
    """A plain LookAt is read with world x negated (pbrt.py's docstring): corners, centres, normals and
    windings follow, so each emitter still faces its mirrored side."""
    plain, mirrored = (pbrt.read_scene(pbrt_file(tmp_path, mirror=m)) for m in ("Scale -1 1 1\n", ""))
    x = np.array([-1.0, 1.0, 1.0])
    for a, b in zip(plain["light"][1:], mirrored["light"][1:]):
        for key in ("center", "normal"):
            if key in a:
                np.testing.assert_allclose(np.asarray(a[key]) * x, b[key], atol=1e-15)
        if "corners" in a:
            np.testing.assert_allclose(np.asarray(a["corners"]) * x, np.asarray(b["corners"])[[0, 3, 2, 1]], atol=1e-15)
            np.testing.assert_allclose(quad_normal(a["corners"]) * x, quad_normal(b["corners"]), atol=1e-15)
    for a, b in zip(plain["shape"], mirrored["shape"]):
        np.testing.assert_allclose(winding(a) * x, winding(b), atol=1e-15)
        if "normals" in a:
            np.testing.assert_allclose(np.asarray(a["normals"]) * x, b["normals"], atol=1e-15)


def test_pbrt_infinite_illuminance_and_refusals(tmp_path):
    raw = pbrt.read_scene(pbrt_file(tmp_path, 'LightSource "infinite" "float illuminance" [ 2 ]\n'))
    np.testing.assert_allclose(raw["light"][0]["radiance"], [2.0 / math.pi] * 3, rtol=1e-15)  # E_v / pi
    for world, needle in [
            ('LightSource "infinite" "string filename" "sky.exr" "point3 portal" [ 0 0 0  1 0 0  1 1 0  0 1 0 ]\n',
             '"point3 portal" \\(a portal light\\) is not read'),
            ('AreaLightSource "diffuse"\nShape "sphere" "float radius" 1\n'
             'AttributeBegin\nScale 1 2 1\nShape "sphere"\nAttributeEnd\n', "an area light on a sphere scaled unevenly"),
            ('AreaLightSource "diffuse"\nScale 1 2 1\nShape "disk"\n', "a disk stretched into an ellipse"),
            ('AreaLightSource "blackbody"\n', 'AreaLightSource "blackbody" is not read')]:
        with pytest.raises(UserError, match=needle):
            pbrt.read_scene(pbrt_file(tmp_path, world))


def test_pbrt_plymesh_normals_and_emitting_side(tmp_path):
    """A PLY's nx ny nz are pbrt's N: read by the inverse transpose, and an area light on it emits
    towards them (the winding turned where it disagrees)."""
    v = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # wound towards -y
    n = np.array([[0.0, 1.0, 0.0], [0.6, 0.8, 0.0], [0.0, 0.8, 0.6]])
    (tmp_path / "m.ply").write_bytes(pbrt._ply_bytes(v, np.array([[0, 1, 2]]), n))
    world = 'AreaLightSource "diffuse"\nScale 2 1 1\nShape "plymesh" "string filename" "m.ply"\n'
    (shape,) = pbrt.read_scene(pbrt_file(tmp_path, world))["shape"]
    np.testing.assert_allclose(shape["normals"], n / [2.0, 1.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(winding(shape), [[0.0, 1.0, 0.0]], atol=1e-15)


def test_mitsuba_emitting_cube_faces_out_under_a_mirror(tmp_path):
    body = ('<shape type="cube"><transform name="to_world"><scale x="-1" y="2" z="1"/><rotate y="1" angle="30"/>'
            '</transform><emitter type="area"/></shape>')
    (cube,) = mitsuba.read_scene(mitsuba_file(tmp_path, body))["shape"]
    t = np.asarray(cube["vertices"])[np.asarray(cube["faces"])]
    assert len(t) == 12 and cube["emission"] == 1.0
    assert np.all(np.einsum("ij,ij->i", winding(cube), t.mean(axis=1)) > 0.0)  # outward about the centre 0


def test_pbrt_area_light_scope_and_interface(tmp_path):
    """The area light holds for the shapes after it in its attribute scope; an "interface" shape drops it
    (scene.cpp), said in a note."""
    world = ('AttributeBegin\nAreaLightSource "diffuse"\nShape "sphere" "float radius" 0.5\nAttributeEnd\n'
             'Shape "trianglemesh" "point3 P" [ 0 0 0 1 0 0 0 1 0 ] "integer indices" [ 0 1 2 ]\n'
             'AttributeBegin\nAreaLightSource "diffuse"\nMaterial "interface"\nShape "sphere"\nAttributeEnd\n')
    with pytest.warns(pbrt.PbrtNote, match='an area light on a shape with the "interface" material'):
        raw = pbrt.read_scene(pbrt_file(tmp_path, world))
    assert [light["type"] for light in raw["light"]] == ["sphere"]
    assert ["emission" in s for s in raw["shape"]] == [False]


# --------------------------------------------------------------------------------------------------- glTF

def gltf_file(tmp_path, material, matrix=None) -> Path:
    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    nrm = np.array([[0, 0, 1], [0.6, 0, 0.8], [0, 0.6, 0.8]], np.float32)
    blob = pos.tobytes() + nrm.tobytes()
    node = {"mesh": 0, **({"matrix": matrix} if matrix else {})}
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [node],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}, "material": 0}]}],
           "materials": [material], "extensionsUsed": ["KHR_materials_emissive_strength"],
           "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64,"
                        + base64.b64encode(blob).decode()}],
           "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36,
                                                                               "byteLength": 36}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0],
                          "max": [1, 1, 0]}, {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3"}]}
    path = tmp_path / "t.gltf"
    path.write_text(json.dumps(doc))
    return path


def test_gltf_emission_normals_and_a_mirroring_node(tmp_path):
    """emissiveFactor x emissiveStrength (Blender's convention), one-sided unless doubleSided;
    NORMAL by the node's inverse transpose; a mirroring node turns the winding (glTF 2.0, 3.7.4)."""
    material = {"emissiveFactor": [1.0, 0.5, 0.25], "extensions": {"KHR_materials_emissive_strength": {
        "emissiveStrength": 8.0}}, "pbrMetallicRoughness": {"metallicFactor": 0.0}}
    mirror = [-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
    with pytest.warns(gltf.GltfNote, match="emitting from its front face"):
        plain = gltf.read_scene(gltf_file(tmp_path, material))["shape"][0]
    assert plain["emission"] == [8.0, 4.0, 2.0]
    assert plain["two_sided"] is False
    np.testing.assert_allclose(winding(plain), [[0.0, 0.0, 1.0]], atol=1e-15)
    np.testing.assert_allclose(plain["normals"], [[0, 0, 1], [0.6, 0, 0.8], [0, 0.6, 0.8]], atol=1e-7)
    with pytest.warns(gltf.GltfNote):
        turned = gltf.read_scene(gltf_file(tmp_path, {**material, "doubleSided": True}, mirror))["shape"][0]
    assert turned["two_sided"] is True
    np.testing.assert_allclose(winding(turned), [[0.0, 0.0, 1.0]], atol=1e-15)  # the front face: still +z
    np.testing.assert_allclose(turned["normals"], [[0, 0, 1], [-0.6, 0, 0.8], [0, 0.6, 0.8]], atol=1e-7)


def test_blender_emitter_and_lamp_light_as_in_cycles():
    """tests/data/gltf/emitter.gltf, made and exported by Blender 3.4 (make_emitter.py): a square of
    Emission Strength 50, colour (1, 0.8, 0.6), area 0.04, facing down at height 1, and a point lamp of
    4 x 50 x 0.04 = 8 W there. Cycles, each alone (`make_emitter.py -- OUT --render`, 1024 spp), lights
    the floor point below them 3.0835 times as much from the square as from the lamp (the 2 x 2 pixels
    about it). Read here: the square's radiance S x colour, the lamp P / 4 pi W/sr; the square's
    irradiance at the point below (its exact integral, scipy) over the lamp's I / h^2 must be Cycles'
    ratio (a radiance of S / pi would give 0.98)."""
    from scipy.integrate import dblquad

    raw = gltf.read_scene(Path(__file__).resolve().parent / "data" / "gltf" / "emitter.gltf")
    (square,) = [s for s in raw["shape"] if "emission" in s]
    np.testing.assert_allclose(square["emission"], [50.0, 40.0, 30.0], rtol=1e-6)  # float32 colour
    assert square["two_sided"] is True  # Blender's default material: doubleSided
    (lamp,) = raw["light"]
    np.testing.assert_allclose(lamp["intensity"], np.array([1.0, 0.8, 0.6]) * 8.0 / (4.0 * math.pi), rtol=1e-6)
    v = np.asarray(square["vertices"])
    h = float(v[:, 1].mean())
    assert np.allclose(v[:, 1], 1.0, atol=1e-6) and np.allclose(lamp["position"], [0.0, 1.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(winding(square), [[0.0, -1.0, 0.0]] * 2, atol=1e-6)  # facing the floor
    (x0, x1), (z0, z1) = (v[:, 0].min(), v[:, 0].max()), (v[:, 2].min(), v[:, 2].max())
    square_e = square["emission"][0] * dblquad(lambda z, x: h * h / (h * h + x * x + z * z) ** 2, x0, x1, z0, z1)[0]
    assert square_e / (lamp["intensity"][0] / h ** 2) == pytest.approx(3.0835, rel=0.01)


# ---------------------------------------------------------------------------------------------- round trips

def camera():
    return {"position": [0.0, 1.0, 6.0], "look_at": [0.0, 1.0, 0.0], "fov": 40.0, "width": 32, "height": 24, "spp": 1}


def emitting_scene(tmp_path, environment=True) -> dict:
    lights = [{"type": "point", "position": [0.0, 2.5, 1.0], "intensity": 3.0},
              {"type": "quad", "corners": [[-0.5, 2.99, -0.5], [0.5, 2.99, -0.5], [0.5, 2.99, 0.5], [-0.5, 2.99, 0.5]],
               "radiance": [10.0, 9.0, 8.0]},
              {"type": "disk", "center": [1.0, 2.9, 0.5], "normal": [0.0, -1.0, 0.0], "radius": 0.3, "radiance": 20.0},
              {"type": "sphere", "center": [-1.0, 1.0, 0.0], "radius": 0.1, "radiance": [50.0, 40.0, 30.0]}]
    if environment:
        lights.append({"type": "environment", "radiance": [0.2, 0.3, 0.5]})
    shapes = [{"primitive": "box", "min": [-3.0, 0.0, -3.0], "max": [3.0, 3.0, 3.0], "reflectance": 0.5},
              {"primitive": "triangles", "vertices": [[0, 0.5, 0], [1, 0.5, 0], [0, 1.5, 0.2], [1, 1.5, 0.4]],
               "faces": [[0, 1, 2], [1, 3, 2]], "normals": [[0, 0, 1], [0.1, 0, 1], [0, 0.1, 1], [0.1, 0.1, 1]],
               "emission": [1.0, 2.0, 3.0], "reflectance": 0.25}]
    return {"camera": camera(), "shape": shapes, "light": lights}


def emitters_of(raw) -> tuple[list, list]:
    """(area and environment lights with rounded numbers, sorted; emitting triangles: each one's corners
    from its smallest, in winding order, with its emission and sidedness, sorted)."""
    def rounded(x):
        return np.round(np.asarray(x, float) * np.ones(3), 5).tolist() if np.ndim(x) < 2 else np.round(x, 5).tolist()

    lights = sorted((repr({k: (rounded(v) if k in ("corners", "center", "normal", "radiance") else v)
                           for k, v in light.items() if k not in ("map", "rotate")})
                     for light in raw.get("light", []) if light.get("type") != "point"))
    tris = []
    for shape in raw.get("shape", []):
        if "emission" in shape:
            for t in np.asarray(shape["vertices"], float)[np.asarray(shape["faces"])]:
                t = np.roll(t, -min(range(3), key=lambda k: tuple(t[k])), axis=0)
                tris.append((np.round(t, 5).tolist(), rounded(shape["emission"]), shape.get("two_sided", False)))
    return lights, sorted(tris)


def corner_normals(raw) -> list:
    """The (position, unit normal) pairs of the emitting shapes' vertices (a corner written once per
    triangle, as pbrt's export does, counts once)."""
    return sorted({(tuple(np.round(v, 5)), tuple(np.round(np.asarray(n) / np.linalg.norm(n), 5)))
                  for s in raw["shape"] if "normals" in s and "emission" in s
                  for v, n in zip(s["vertices"], s["normals"])})


def test_mitsuba_round_trip(tmp_path):
    raw = emitting_scene(tmp_path)
    raw["light"].append({"type": "environment", "map": str(sky(tmp_path)), "scale": 2.0, "rotate": [0.0, 30.0, 0.0],
                         "filter": "mitsuba", "mirror": True})
    out = tmp_path / "out" / "scene.xml"
    out.parent.mkdir()
    mitsuba.export(raw, out, "test", False)
    back = mitsuba.read_scene(out)
    assert emitters_of(back) == emitters_of(raw)
    env = [light for light in back["light"] if "map" in light][0]
    assert env["map"] == str(tmp_path / "sky.exr") and env["scale"] == 2.0
    assert env["filter"] == "mitsuba" and env["mirror"] is True
    np.testing.assert_allclose(rotation_matrix(env["rotate"]), rotation_matrix([0.0, 30.0, 0.0]), atol=1e-12)
    assert corner_normals(back) == corner_normals(raw)  # the PLY's normals, float32: 5 decimals


def mitsuba_envmap_eval(image, to_world, dirs):
    """A twin of mitsuba3 src/emitters/envmap.cpp `eval` in RGB: v = to_world^-1 w, u = atan2(v_x, -v_z) / 2 pi
    wrapped into [0, 1), t = acos(v_y) / pi; bilinear over the bitmap at x = u W - 1/2 (periodic: a column
    each side copied from the opposite edge), y = t (H - 1) (the first and last rows on the poles)."""
    H, W = image.shape[:2]
    v = dirs @ np.linalg.inv(to_world).T
    u = np.arctan2(v[:, 0], -v[:, 2]) / (2 * math.pi)
    u -= np.floor(u)
    x, y = u * W - 0.5, np.arccos(np.clip(v[:, 1], -1, 1)) / math.pi * (H - 1)
    x0, y0 = np.floor(x).astype(int), np.minimum(np.floor(y).astype(int), H - 2)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    a, b = x0 % W, (x0 + 1) % W
    return ((1 - fy) * ((1 - fx) * image[y0, a] + fx * image[y0, b]) +
            fy * ((1 - fx) * image[y0 + 1, a] + fx * image[y0 + 1, b]))


@pytest.mark.parametrize("mirror", ["", '<scale x="-1"/>'])
def test_mitsuba_envmap_renders_as_mitsuba_looks_it_up(tmp_path, mirror):
    """An envmap under three rotations (and a mirror): the imported light's radiance along 5000 random
    directions equals the twin of Mitsuba's lookup, to 1e-12."""
    from raytrace.lights import environment
    from raytrace.scene.format import scene_from_text

    image = np.random.default_rng(1).uniform(0.1, 1.0, (8, 16, 3)).astype(np.float32).astype(float)
    write_exr(tmp_path / "sky.exr", image)
    body = ('<emitter type="envmap"><string name="filename" value="sky.exr"/><float name="scale" value="2.5"/>'
            f'<transform name="to_world">{mirror}<rotate y="1" angle="30"/><rotate x="1" angle="20"/>'
            '<rotate z="1" angle="-50"/></transform></emitter>')
    path = tmp_path / "scene.xml"
    path.write_text(f'<scene version="3.0.0">{SENSOR}{body}</scene>')
    env = mitsuba.read_scene(path)["light"][0]
    assert env["filter"] == "mitsuba" and env.get("mirror", False) == bool(mirror)
    light = scene_from_text(to_toml({"camera": camera(), "light": [env], "medium": {"sigma_a": 0.0, "sigma_s": 0.0}}),
                            str(tmp_path / "s.toml"), tmp_path / "s.toml").lights[0]
    M = np.diag([-1.0 if mirror else 1.0, 1.0, 1.0])
    for axis, angle in (("y", 30), ("x", 20), ("z", -50)):  # each <rotate> left-multiplies
        M = rotation_matrix({"x": [angle, 0, 0], "y": [0, angle, 0], "z": [0, 0, angle]}[axis]) @ M
    dirs = np.random.default_rng(2).normal(size=(5000, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    np.testing.assert_allclose(environment.radiance(light, dirs), 2.5 * mitsuba_envmap_eval(image, M, dirs),
                               rtol=1e-12, atol=1e-14)


def test_mitsuba_export_of_other_maps(tmp_path):
    """A map looked up "nearest" or "bilinear" is refused in one line naming its filter (Mitsuba interpolates
    every map its own way), written with --approximate and a warning; an octahedral map is refused."""
    sky(tmp_path)
    for keys, needle in [({}, 'light[0].filter: a map looked up "nearest"'),
                         ({"filter": "bilinear"}, 'light[0].filter: a map looked up "bilinear"')]:
        raw = {"camera": camera(), "light": [{"type": "environment", "map": str(tmp_path / "sky.exr"), **keys}]}
        with pytest.raises(UserError, match=needle.replace("[", r"\[").replace("]", r"\]")):
            mitsuba.export(raw, tmp_path / "x.xml", "test", False)
        assert not (tmp_path / "x.xml").exists()
        with pytest.warns(UserWarning, match="--approximate"):
            mitsuba.export(raw, tmp_path / "x.xml", "test", True)
        assert '<emitter type="envmap">' in (tmp_path / "x.xml").read_text()
        (tmp_path / "x.xml").unlink()
    write_exr(tmp_path / "octa.exr", np.ones((4, 4, 3), np.float32))
    raw = {"camera": camera(), "light": [{"type": "environment", "map": str(tmp_path / "octa.exr"),
                                          "mapping": "octahedral"}]}
    with pytest.raises(UserError, match=r"light\[0\].mapping: Mitsuba 3's envmap is equirectangular"):
        mitsuba.export(raw, tmp_path / "x.xml", "test", True)


def test_mitsuba_export_finds_the_map_beside_the_scene(tmp_path, monkeypatch):
    """An environment map named relative to the scene file is written with its path as the scene
    reader finds it, whatever the working folder (it was resolved against the working folder)."""
    folder = tmp_path / "scene"
    folder.mkdir()
    write_exr(folder / "sky.exr", np.full((4, 8, 3), 0.5, np.float32))
    raw = {"camera": {"position": [0.0, 1.0, 4.0], "look_at": [0.0, 0.0, 0.0], "width": 8, "height": 6},
           "shape": [{"primitive": "quad", "corners": [[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]]}],
           "light": [{"type": "environment", "map": "sky.exr", "filter": "mitsuba"}]}
    (folder / "s.toml").write_text(to_toml(raw))
    monkeypatch.chdir(tmp_path)
    mitsuba.export(raw, tmp_path / "out.xml", str(folder / "s.toml"), False)
    assert f'name="filename" value="{(folder / "sky.exr").resolve()}"' in (tmp_path / "out.xml").read_text()


def test_pbrt_round_trip(tmp_path):
    raw = emitting_scene(tmp_path)
    raw["shape"][1]["two_sided"] = True
    out = tmp_path / "scene.pbrt"
    pbrt.export(raw, out, "test", False)
    back = pbrt.read_scene(out)
    assert emitters_of(back) == emitters_of(raw)
    assert corner_normals(back) == corner_normals(raw)
    raw["light"].append({"type": "environment", "map": "sky.exr"})
    with pytest.raises(UserError, match=r"light\[5\].map: pbrt-v4's environment maps are equal-area octahedral"):
        pbrt.export(raw, tmp_path / "x.pbrt", "test", False)
    assert not (tmp_path / "x.pbrt").exists()


def test_gltf_round_trip(tmp_path):
    """Emission and quad lights (as emitting triangles) round-trip; disks and spheres become meshes only
    with --approximate, the environment is refused (glTF has none)."""
    raw = emitting_scene(tmp_path, environment=False)
    raw["light"] = raw["light"][:2]
    out = tmp_path / "scene.glb"
    gltf.export(raw, out, "test", False)
    with pytest.warns(gltf.GltfNote):
        back = gltf.read_scene(out)
    lights, tris = emitters_of(raw)
    quad = raw["light"][1]
    c = np.asarray(quad["corners"], float)
    as_tris = emitters_of({"shape": [{"vertices": c, "faces": [[0, 1, 2], [0, 2, 3]], "emission": quad["radiance"]}]})
    assert emitters_of(back) == ([], sorted(tris + as_tris[1]))
    assert corner_normals(back) == corner_normals(raw)
    full = emitting_scene(tmp_path)
    with pytest.raises(UserError, match=r"light\[2\]: a disk light .*--approximate"):
        gltf.export(full, tmp_path / "x.glb", "test", False)
    assert not (tmp_path / "x.glb").exists()
    with pytest.warns(gltf.GltfNote, match="environment light; written as nothing"):
        gltf.export(full, tmp_path / "x.glb", "test", True)
    with pytest.warns(gltf.GltfNote):
        meshes = [s for s in gltf.read_scene(tmp_path / "x.glb")["shape"] if "emission" in s]
    np.testing.assert_allclose([s["emission"] for s in meshes], [[1.0, 2.0, 3.0], [10.0, 9.0, 8.0], [20.0] * 3,
                                                                 [50.0, 40.0, 30.0]], rtol=1e-12)


# ----------------------------------------------------------------------------------------- Mitsuba 3 itself

@pytest.fixture(scope="module")
def mi():
    pytest.importorskip("mitsuba")
    import mitsuba

    mitsuba.set_variant("scalar_rgb")
    return mitsuba


@pytest.mark.peers
def test_envmap_orientation_matches_mitsuba(mi, tmp_path):
    """Mitsuba's envmap under a to_world of three rotations, evaluated along 500 random directions, equals
    the radiance of our import (filter "mitsuba": bilinear, columns at the texel
    centres, the first and last rows on the poles) to float32's precision."""
    from raytrace.lights import environment
    from raytrace.scene.format import scene_from_text

    image = np.random.default_rng(1).uniform(0.1, 1.0, (8, 16, 3))
    write_exr(tmp_path / "sky.exr", image)
    body = ('<emitter type="envmap"><string name="filename" value="sky.exr"/><float name="scale" value="2.5"/>'
            '<transform name="to_world"><rotate y="1" angle="30"/><rotate x="1" angle="20"/><rotate z="1" '
            'angle="-50"/></transform></emitter>')
    path = tmp_path / "scene.xml"
    path.write_text(f'<scene version="3.0.0">{SENSOR}{body}</scene>')
    env = mitsuba.read_scene(path)["light"][0]
    light = scene_from_text(to_toml({"camera": camera(), "light": [env], "medium": {"sigma_a": 0.0, "sigma_s": 0.0}}),
                            str(tmp_path / "s.toml"), tmp_path / "s.toml").lights[0]
    emitter = mi.load_file(str(path)).emitters()[0]
    dirs = np.random.default_rng(2).normal(size=(500, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    ours = environment.radiance(light, dirs)
    for d, expected in zip(dirs, ours):
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*(-d))
        np.testing.assert_allclose(np.array(emitter.eval(si)), expected, rtol=2e-5)


@pytest.mark.peers
def test_emitting_sides_match_mitsuba(mi, tmp_path):
    """The normal Mitsuba samples on each emitting rectangle and disk (flip_normals, mirroring) is the
    quad's (c1 - c0) x (c3 - c0) and the disk's `normal` as imported."""
    raw = mitsuba.read_scene(mitsuba_file(tmp_path, EMITTERS_XML.split("<shape type=\"sphere\">")[0]))
    shapes = mi.load_file(str(tmp_path / "scene.xml")).shapes()  # (not in the file's order: matched by centre)
    centres = [np.mean(light["corners"], axis=0) if light["type"] == "quad" else light["center"]
               for light in raw["light"]]
    assert len(shapes) == len(raw["light"]) == 3
    for shape in shapes:
        box = shape.bbox()
        k = int(np.argmin([np.linalg.norm((np.array(box.min) + np.array(box.max)) / 2.0 - c) for c in centres]))
        light = raw["light"][k]
        ps = shape.sample_position(0.0, mi.Point2f(0.3, 0.6))
        expected = quad_normal(light["corners"]) if light["type"] == "quad" else light["normal"]
        np.testing.assert_allclose(np.array(ps.n), expected, atol=1e-6)
