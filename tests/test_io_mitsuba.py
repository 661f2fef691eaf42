"""Mitsuba 3 XML in and out (raytrace/io/mitsuba.py, docs/formats/mitsuba.md).

Default suite: the hand-written fog room (tests/data/mitsuba/room.xml) imports to the dict worked out
by hand from Mitsuba's documented conventions; TOML -> XML -> import gives the same scene (up to the
PLY files' float32) and the same image; bad input is refused in one line, with nothing written.
`-m peers` (needs `pip install mitsuba`): Mitsuba 3 itself renders the hand-written room and an
exported bundled scene, which agree with ours within Mitsuba's noise, and loads every exported file.
"""
from __future__ import annotations

import math
import re
import sys
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

import raytrace
from raytrace.cli import main
from raytrace.errors import UserError
from raytrace.io import mitsuba
from raytrace.scene.format import scene_from_dict
from raytrace.scene.meshes import scene_triangles

from .conftest import ROOT, to_toml

DATA = Path(__file__).parent / "data" / "mitsuba"


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


# ------------------------------------------------------------------------------------------- import

def test_room_imports_to_the_dict_worked_out_by_hand():
    raw = mitsuba.read_scene(DATA / "room.xml")
    cam = raw["camera"]
    origin, target = np.array([0.4, 0.3, 3.2]), np.array([0.1, -0.4, -1.5])
    assert cam["position"] == pytest.approx(origin.tolist(), abs=1e-15)
    assert unit(np.subtract(cam["look_at"], cam["position"])) == pytest.approx(unit(target - origin), abs=1e-12)
    # fov 75 along x (Mitsuba's default axis) on a 48 x 32 film: tan(fov_y / 2) = tan(37.5 deg) / 1.5
    assert cam["fov"] == pytest.approx(2 * math.degrees(math.atan(math.tan(math.radians(37.5)) / 1.5)), rel=1e-12)
    assert (cam["width"], cam["height"], cam["spp"]) == (48, 32, 64)  # spp from <default name="spp">
    up = np.asarray(cam["up"])  # in the plane of the view direction and (0, 1, 0), orthogonal to the view
    assert abs(up @ unit(target - origin)) < 1e-12 and abs(np.cross(unit(target - origin), [0, 1, 0]) @ up) < 1e-12
    assert up[1] > 0
    # sigma_t 0.4 x scale 0.5, albedo (0.9, 0.7, 0.5), g from <default name="g">
    med = raw["medium"]
    assert med["sigma_s"] == pytest.approx([0.18, 0.14, 0.10], abs=1e-15)
    assert med["sigma_a"] == pytest.approx([0.02, 0.06, 0.10], abs=1e-15)
    assert med["phase"] == {"type": "hg", "g": 0.4}
    assert raw["light"] == [{"type": "point", "position": [0.5, 1.4, -1.0], "intensity": [12.0, 10.0, 8.0]}]
    room, ball, plate = raw["shape"]
    assert room == {"primitive": "box", "min": [-3.0, -2.0, -4.0], "max": [3.0, 2.0, 4.0],
                    "reflectance": [0.6, 0.55, 0.5]}
    assert {k: ball[k] for k in ("primitive", "center", "radius", "reflectance")} == {
        "primitive": "sphere", "center": [-1.3, -1.4, -1.8], "radius": 0.6, "reflectance": [0.9, 0.7, 0.4]}
    assert 64 <= ball["segments"] <= 256
    # the rectangle's corners (+-1, +-1, 0) scaled by (0.6, 0.5), rotated -70 deg about x, translated
    c, s = math.cos(math.radians(-70)), math.sin(math.radians(-70))
    corners = [[x * 0.6 + 0.4, y * 0.5 * c + 0.7, y * 0.5 * s - 1.1] for x, y in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    assert plate["primitive"] == "quad" and plate["reflectance"] == 0.4
    assert np.allclose(plate["corners"], corners, rtol=0, atol=1e-15)
    assert raw["render"] == {"volumetric_shadows": True}  # Mitsuba's volpath shadows the medium
    scene_from_dict(raw, "room.xml")  # a valid scene


def test_spot_reads_as_mitsuba_curve_through_include():
    raw = mitsuba.read_scene(DATA / "room_spot.xml")
    assert len(raw["shape"]) == 3 and raw["light"][0]["type"] == "point"  # room.xml, included
    spot = raw["light"][1]
    assert spot["position"] == [-1.8, 1.6, 0.5]
    assert spot["direction"] == pytest.approx(unit([1.2, -3.6, -2.5]).tolist(), abs=1e-12)
    assert (spot["cone_angle"], spot["falloff_start"], spot["falloff"]) == (25.0, 12.0, "mitsuba")
    assert spot["intensity"] == [20.0, 20.0, 30.0]


def test_spot_room_is_a_valid_scene():
    scene_from_dict(mitsuba.read_scene(DATA / "room_spot.xml"), "room_spot.xml")


def write(tmp_path, body, name="scene.xml"):
    p = tmp_path / name
    p.write_text(f'<scene version="3.0.0">\n{body}\n</scene>\n')
    return p


SENSOR = """<sensor type="perspective"><float name="fov" value="60"/><string name="fov_axis" value="{axis}"/>
<transform name="to_world"><translate x="1" y="2" z="3"/></transform>
<film type="hdrfilm"><integer name="width" value="40"/><integer name="height" value="20"/></film></sensor>"""


@pytest.mark.parametrize("axis,tan_y", [("x", math.tan(math.pi / 6) / 2), ("y", math.tan(math.pi / 6)),
                                        ("diagonal", math.tan(math.pi / 6) / math.sqrt(5)),
                                        ("smaller", math.tan(math.pi / 6)), ("larger", math.tan(math.pi / 6) / 2)])
def test_fov_axis(tmp_path, axis, tan_y):
    cam = mitsuba.read_scene(write(tmp_path, SENSOR.format(axis=axis)))["camera"]
    assert math.tan(math.radians(cam["fov"]) / 2) == pytest.approx(tan_y, rel=1e-12)
    # the identity to_world looks down +z with +y up (Mitsuba's camera space), here moved to (1, 2, 3)
    assert cam["position"] == [1, 2, 3] and cam["look_at"] == [1, 2, 4] and cam["up"] == [0, 1, 0]
    assert cam["spp"] == 4  # Mitsuba's independent sampler's default


def test_meshes_transforms_and_interiors(tmp_path):
    (tmp_path / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    raw = mitsuba.read_scene(write(tmp_path, SENSOR.format(axis="x") + """
<medium type="homogeneous" id="inside"><rgb name="sigma_t" value="1, 2, 3"/><float name="albedo" value="0.5"/></medium>
<shape type="obj"><string name="filename" value="tri.obj"/>
  <transform name="to_world"><scale value="2"/><rotate z="1" angle="90"/><translate x="5"/></transform>
  <bsdf type="dielectric"><string name="int_ior" value="water"/><float name="ext_ior" value="1.0"/></bsdf>
  <ref name="interior" id="inside"/></shape>
<shape type="cube"><bsdf type="null"/></shape>
<shape type="disk"><transform name="to_world"><matrix value="2 0 0 0  0 1 0 0  0 0 1 0  0 0 0 1"/></transform></shape>
<shape type="cylinder"><float name="radius" value="0.5"/><point name="p1" value="0, 0, 3"/></shape>
<shape type="sphere"><float name="radius" value="0.5"/><bsdf type="null"/><ref name="interior" id="inside"/></shape>"""))
    tet, disk, tube, ball = raw["shape"]  # the null cube without an interior is invisible: left out
    assert ball["segments"] == 64 and ball["interior"]["sigma_s"] == [0.5, 1.0, 1.5] and "ior" not in ball["interior"]
    # scale 2, then 90 degrees about z (x -> y, y -> -x), then x + 5
    assert np.allclose(tet["vertices"], [[5, 0, 0], [5, 2, 0], [3, 0, 0], [5, 0, 2]], atol=1e-15)
    assert tet["faces"] == [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]
    assert tet["interior"] == {"sigma_a": [0.5, 1.0, 1.5], "sigma_s": [0.5, 1.0, 1.5], "phase": "isotropic",
                               "ior": 1.333}
    assert "reflectance" not in tet
    v = np.asarray(disk["vertices"])  # the unit disk stretched to an ellipse of half-axes 2 and 1
    assert np.allclose(v[:, 2], 0) and np.max(v[:, 0]) == pytest.approx(2) and np.max(v[:, 1]) == pytest.approx(1)
    assert np.max(np.hypot(v[:, 0] / 2, v[:, 1])) == pytest.approx(1, abs=1e-12)
    assert disk["reflectance"] == 0.5  # Mitsuba's default bsdf: diffuse 0.5
    v = np.asarray(tube["vertices"])  # an open tube: every vertex on the radius, none on the axis
    assert np.allclose(np.hypot(v[:, 0], v[:, 1]), 0.5) and set(np.round(v[:, 2], 12)) == {0.0, 3.0}


def test_focus_distance_and_thinlens_of_aperture_zero_read_as_pinhole(tmp_path):
    """Mitsuba reads focus_distance on every projective camera (src/render/sensor.cpp ProjectiveCamera);
    a thinlens of aperture_radius 0 is a pinhole (thinlens.cpp: epsilon); a real aperture is refused."""
    plain = mitsuba.read_scene(write(tmp_path, SENSOR.format(axis="x"), "a.xml"))["camera"]
    focus = SENSOR.format(axis="x").replace("<transform", '<float name="focus_distance" value="1000"/><transform')
    assert mitsuba.read_scene(write(tmp_path, focus, "b.xml"))["camera"] == plain
    thin = focus.replace('type="perspective">', 'type="thinlens"><float name="aperture_radius" value="0"/>')
    assert mitsuba.read_scene(write(tmp_path, thin, "c.xml"))["camera"] == plain
    with pytest.raises(UserError, match=r"aperture_radius > 0 \(depth of field\)"):
        mitsuba.read_scene(write(tmp_path, thin.replace('name="aperture_radius" value="0"',
                                                        'name="aperture_radius" value="0.1"'), "d.xml"))


TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


def test_include_and_meshes_found_as_mitsuba_finds_them(tmp_path):
    """mitsuba-data's participating_media layout: main.xml includes include/base.xml, which includes
    "include/preamble.xml" (beside main.xml, not beside base.xml) and a mesh "meshes/m.obj" beside
    main.xml (parser.cpp TagType::Include: the including file's folder, then the main file's)."""
    for d in ("include", "meshes"):
        (tmp_path / d).mkdir()
    (tmp_path / "meshes" / "m.obj").write_text(TRI)
    write(tmp_path, '<default name="res" value="20"/>', "include/preamble.xml")
    write(tmp_path, '<include filename="include/preamble.xml"/>' + SENSOR.format(axis="x").replace('"40"', '"$res"')
          + '<shape type="obj"><string name="filename" value="meshes/m.obj"/></shape>', "include/base.xml")
    raw = mitsuba.read_scene(write(tmp_path, '<include filename="include/base.xml"/>', "main.xml"))
    assert raw["camera"]["width"] == 20 and raw["shape"][0]["vertices"] == [[0, 0, 0], [1, 0, 0], [0, 1, 0]]


def test_path_element_adds_a_folder_searched_first(tmp_path):
    """<path value=.../> (parser.cpp TagType::Resource): a folder relative to the file, searched before
    the main file's folder; a folder that does not exist is refused naming it."""
    for d in ("a", "b"):
        (tmp_path / d).mkdir()
    (tmp_path / "a" / "m.obj").write_text(TRI)
    (tmp_path / "b" / "m.obj").write_text(TRI.replace("v 1 0 0", "v 2 0 0"))
    (tmp_path / "m.obj").write_text(TRI.replace("v 1 0 0", "v 3 0 0"))
    shape = '<shape type="obj"><string name="filename" value="m.obj"/></shape>'
    first = lambda raw: raw["shape"][0]["vertices"][1][0]  # noqa: E731
    assert first(mitsuba.read_scene(write(tmp_path, SENSOR.format(axis="x") + shape, "s0.xml"))) == 3
    assert first(mitsuba.read_scene(write(tmp_path, '<path value="a"/>' + SENSOR.format(axis="x") + shape,
                                          "s1.xml"))) == 1
    assert first(mitsuba.read_scene(write(tmp_path, '<path value="a"/><path value="b"/>' + SENSOR.format(axis="x")
                                          + shape, "s2.xml"))) == 2  # the later <path> is searched first
    with pytest.raises(UserError, match=r"s3.xml:2: <path>: folder 'nowhere' not found"):
        mitsuba.read_scene(write(tmp_path, '<path value="nowhere"/>' + SENSOR.format(axis="x"), "s3.xml"))


# ------------------------------------------------------------------------------------------- round trip

def round_trip_scene(w=24, h=16, spot=None):
    scene = {
        "camera": {"position": [0.3, 0.4, 2.8], "look_at": [-0.2, 0.1, -1.0], "fov": 65.0, "width": w, "height": h,
                   "spp": 1},
        "shape": [
            {"primitive": "box", "min": [-3.0, -2.0, -4.0], "max": [3.0, 2.0, 4.0], "reflectance": [0.6, 0.5, 0.4]},
            {"primitive": "quad", "reflectance": 0.3,  # a parallelogram: a Mitsuba rectangle
             "corners": [[-0.8, 0.6, -2.2], [1.6, 0.6, -2.2], [1.6, 0.0, -0.4], [-0.8, 0.0, -0.4]]},
            {"primitive": "quad", "reflectance": 0.7,  # not one: a PLY mesh
             "corners": [[-2.0, -1.9, -3.0], [-1.0, -1.9, -3.0], [-1.2, -1.9, -2.0], [-2.5, -1.9, -2.2]]},
            {"primitive": "sphere", "center": [1.0, -1.4, -2.0], "radius": 0.5, "segments": 24,
             "reflectance": [0.2, 0.4, 0.6]},
            {"primitive": "cylinder", "base": [-1.5, -2.0, -2.5], "top": [-1.5, 0.5, -2.5], "radius": 0.3},
            {"primitive": "box", "min": [0.0, 0.0, 0.0], "max": [0.5, 0.3, 0.4], "reflectance": 0.9,
             "transform": {"scale": [1.0, 2.0, 1.0], "rotate": [10.0, 30.0, 0.0], "translate": [-1.0, -1.2, -1.0]}},
        ],
        "light": [{"position": [0.5, 1.0, -1.0], "intensity": [10.0, 8.0, 6.0]}],
        "medium": {"sigma_a": [0.05, 0.02, 0.01], "sigma_s": [0.15, 0.1, 0.05], "phase": {"type": "hg", "g": 0.3}},
    }
    if spot:
        scene["light"].append({"type": "spot", "position": [-1.0, 1.5, 0.0], "look_at": [-0.5, -2.0, -2.0],
                               "intensity": 30.0, "cone_angle": 25.0, "falloff_start": 15.0, "falloff": spot})
    return scene


def exported(tmp_path, raw, approximate=False):
    out = tmp_path / "out" / "scene.xml"
    out.parent.mkdir(exist_ok=True)
    files = mitsuba.export(raw, out, "test scene", approximate)
    return out, files


def test_round_trip_same_scene_and_image(tmp_path):
    raw = round_trip_scene()
    out, files = exported(tmp_path, raw)
    assert [f.name for f in files] == ["scene.xml", "scene-2.ply", "scene-3.ply", "scene-4.ply", "scene-5.ply"]
    text = out.read_text()
    for needle in ('<integrator type="volpath">', '<integer name="max_depth" value="2" />', '<rfilter type="box" />',
                   '<bsdf type="twosided">', '<ref id="fog" name="medium" />', '<string name="fov_axis" value="y" />'):
        assert needle in text
    back = mitsuba.read_scene(out)
    a, b = scene_from_dict(raw, "toml"), scene_from_dict(back, str(out), out)
    assert np.array_equal(a.camera.position, b.camera.position)
    fa, fb = unit(a.camera.look_at - a.camera.position), unit(b.camera.look_at - b.camera.position)
    assert np.allclose(fa, fb, atol=1e-12)
    assert np.allclose(unit(np.cross(fa, a.camera.up)), unit(np.cross(fb, b.camera.up)), atol=1e-12)
    assert (a.camera.fov, a.camera.width, a.camera.height, a.camera.spp) == pytest.approx(
        (b.camera.fov, b.camera.width, b.camera.height, b.camera.spp), rel=1e-14)
    assert np.allclose(a.medium.sigma_a, b.medium.sigma_a, rtol=1e-14) and np.allclose(a.medium.sigma_s,
                                                                                       b.medium.sigma_s, rtol=1e-14)
    assert (a.medium.phase, a.medium.g) == (b.medium.phase, b.medium.g)
    assert np.array_equal(a.lights[0].position, b.lights[0].position)
    assert np.array_equal(a.lights[0].intensity, b.lights[0].intensity)
    ta, ra = scene_triangles(a)
    tb, rb = scene_triangles(b)
    assert ta.shape == tb.shape and np.array_equal(ra, rb)
    # the same triangles, in order, up to float32 (the PLY files; |coordinates| <= 4)
    assert np.abs(ta - tb).max() <= 4 * 2.0 ** -24 * 4
    assert back["render"] == {"volumetric_shadows": True}  # as Mitsuba renders it
    img_a, img_b = (raytrace.render(s, method="analytic", spp=1, volumetric_shadows=True).array for s in (a, b))
    assert img_a.max() > 0 and np.allclose(img_a, img_b, rtol=1e-4, atol=1e-6 * img_a.max())


def test_interior_round_trip(tmp_path):
    raw = round_trip_scene()
    raw["shape"] = raw["shape"][:1] + [{"primitive": "sphere", "center": [0.0, -1.0, -1.5], "radius": 0.6,
                                        "segments": 16, "interior": {"sigma_a": 0.3, "sigma_s": [0.5, 0.4, 0.3],
                                                                     "phase": "rayleigh"}}]
    out, _ = exported(tmp_path, raw)
    text = out.read_text()
    assert '<bsdf type="null" />' in text and '<medium type="homogeneous" name="interior">' in text
    assert '<ref id="fog" name="exterior" />' in text  # leaving the sphere, a ray is back in the fog
    back = scene_from_dict(mitsuba.read_scene(out), str(out), out)
    inner = back.shapes[1].interior
    assert np.allclose(inner.sigma_a, 0.3, rtol=1e-14) and np.allclose(inner.sigma_s, [0.5, 0.4, 0.3], rtol=1e-14)
    assert inner.ior == 1.0 and inner.phase == scene_from_dict(raw, "t").shapes[1].interior.phase


def test_mitsuba_spot_exports_exactly(tmp_path):
    """Mitsuba's own curve round-trips through its spot's cutoff_angle and beam_width."""
    el = ET.Element("scene")
    writer = mitsuba._Writer(None, tmp_path / "s.xml", "t", False)
    light = scene_from_dict({"camera": round_trip_scene()["camera"], "light": [
        {"type": "spot", "position": [-1.0, 1.5, 0.0], "look_at": [-0.5, -2.0, -2.0], "intensity": 30.0,
         "cone_angle": 25.0, "falloff_start": 15.0}]}, "t").lights[0]
    writer.light(el, 0, light, {"falloff": "mitsuba"})
    spot = el.find("emitter")
    values = {f.get("name"): float(f.get("value")) for f in spot.findall("float")}
    assert values == pytest.approx({"cutoff_angle": 25.0, "beam_width": 15.0}, rel=1e-13)
    look = spot.find("transform/lookat")
    o, t = (np.array([float(x) for x in look.get(k).split(",")]) for k in ("origin", "target"))
    assert o.tolist() == [-1.0, 1.5, 0.0] and np.allclose(unit(t - o), unit([0.5, -3.5, -2.0]), atol=1e-15)


def test_spot_round_trip(tmp_path):
    raw = round_trip_scene(spot="mitsuba")
    out, _ = exported(tmp_path, raw)
    assert mitsuba.read_scene(out)["light"][1]["falloff"] == "mitsuba"


# ------------------------------------------------------------------------------------------- bad input

BOMB = """<?xml version="1.0"?>
<!DOCTYPE scene [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">
<!ENTITY c "&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;"><!ENTITY d "&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;">]>
<scene version="3.0.0"><string name="x" value="&d;"/></scene>
"""


@pytest.mark.parametrize("body,needle", [
    ('<shape type="sphere">\n<float name="radius" value="1"/>\n</shap>', ":4: malformed XML"),
    ('<shape type="sphere"><float name="radius" value="nan"/></shape>', "'nan' is not finite"),
    ('<emitter type="point"><point name="position" value="1, inf, 0"/></emitter>', "'inf' is not finite"),
    ('<emitter type="envmap"><string name="filename" value="sky.exr"/></emitter>', "envmap file 'sky.exr' not found"),
    ('<emitter type="sunsky"/>', "sunsky emitters are not read"),
    ('<shape type="cylinder"><emitter type="area"/></shape>', "an emitting cylinder is not read"),
    ('<shape type="sphere"><emitter type="spot"/></shape>', "a spot emitter inside a shape is not read"),
    ('<shape type="sphere"><boolean name="flip_normals" value="true"/><emitter type="area"/></shape>',
     "a sphere emitting inward is not read"),
    ('<shape type="serialized"/>', "serialized shapes are not read"),
    ('<shape type="cube"><bsdf type="roughconductor"/></shape>', "roughconductor bsdfs are not read"),
    ('<shape type="cube"><bsdf type="diffuse"><texture type="bitmap" name="reflectance"/></bsdf></shape>',
     "textured reflectance"),
    ('<shape type="obj"><string name="filename" value="missing.obj"/></shape>', "missing.obj' not found"),
    ('<shape type="cube"><float name="radius" value="$r"/></shape>', "parameter $r"),
    ('<shape type="cube"><float name="radiuss" value="1"/></shape>', "parameter 'radiuss'"),
    ('<shape type="sphere"><transform name="to_world"><scale x="2"/></transform></shape>', "non-uniform scale"),
    ('<medium type="heterogeneous" id="m"/><shape type="cube"><bsdf type="null"/><ref name="interior" id="m"/>'
     '</shape>', "only homogeneous media"),
    ('<shape type="cube"><ref id="nothing"/></shape>', "no object has id 'nothing'"),
])
def test_bad_input_one_line(tmp_path, body, needle):
    sensor = SENSOR.format(axis="x") if "malformed" not in needle else ""
    with pytest.raises(UserError) as err:
        mitsuba.read_scene(write(tmp_path, sensor + body))
    msg = str(err.value)
    assert needle in msg and "\n" not in msg and str(tmp_path / "scene.xml") in msg


def test_entity_bomb_refused(tmp_path):
    p = tmp_path / "bomb.xml"
    p.write_text(BOMB)
    with pytest.raises(UserError, match=r"bomb.xml:2: XML entity declarations are refused"):
        mitsuba.read_scene(p)


def test_include_loop_refused(tmp_path):
    write(tmp_path, '<include filename="b.xml"/>', "a.xml")
    write(tmp_path, '<include filename="a.xml"/>', "b.xml")
    with pytest.raises(UserError, match=r"<include> loop \(a.xml -> b.xml -> a.xml\)"):
        mitsuba.read_scene(tmp_path / "a.xml")


def test_cli_render_bad_xml_exits_2(tmp_path, capsys):
    p = write(tmp_path, SENSOR.format(axis="x") + '<emitter type="envmap"/>')
    assert main(["render", str(p), "--out", str(tmp_path / "x.exr")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "an envmap without a filename" in err
    assert not (tmp_path / "x.exr").exists()


@pytest.mark.parametrize("change,needle", [
    ({"camera": {"type": "environment"}}, "no equirectangular sensor"),
    ({"medium": {"type": "height_fog", "sigma_s": 0.1, "scale_height": 2.0}}, "medium.type: height fog"),
    ({"shape": [{"primitive": "box", "min": [-1, -1, -1], "max": [1, 1, 1], "interior": {"sigma_s": 0.5, "ior": 1.33}}]},
     "shape[0].interior.ior: a refractive interior"),
    ({"background": {"radiance": 0.1}}, "background.radiance"),
    ({"render": {"volumetric_shadows": False}}, "render.volumetric_shadows"),
])
def test_export_refuses_what_mitsuba_cannot_express(tmp_path, change, needle):
    raw = round_trip_scene()
    for k, v in change.items():
        raw[k] = {**raw[k], **v} if k == "camera" else v
    with pytest.raises(UserError, match=needle.replace("[", r"\[").replace("]", r"\]").replace(".", r"\.")):
        exported(tmp_path, raw)
    assert not any((tmp_path / "out").iterdir())  # nothing written


def test_export_approximate_warns_and_writes(tmp_path):
    raw = round_trip_scene()
    raw["medium"] = {"type": "height_fog", "sigma_s": 0.1, "scale_height": 2.0, "h0": -1.0}
    with pytest.warns(UserWarning, match=r"medium.type: height fog; written as homogeneous fog of its density at the "
                                         r"camera \(0\.4966 x"):
        out, _ = exported(tmp_path, raw, approximate=True)
    back = mitsuba.read_scene(out)["medium"]  # exp(-(0.4 + 1) / 2) at the camera's height
    assert back["sigma_s"] == pytest.approx(0.1 * math.exp(-0.7), rel=1e-14)


def test_cli_export_smoothstep_spot(tmp_path, capsys):
    """The default (smoothstep) spot: refused with exit 2 and nothing written; with --approximate, a
    warning naming the light and Mitsuba's spot with the same angles."""
    scene = tmp_path / "s.toml"
    raw = round_trip_scene()
    raw["light"].append({"type": "spot", "position": [-1.0, 1.5, 0.0], "look_at": [-0.5, -2.0, -2.0],
                         "intensity": 30.0, "cone_angle": 25.0, "falloff_start": 15.0})
    scene.write_text(to_toml(raw))
    out = tmp_path / "o" / "s.xml"
    out.parent.mkdir()
    args = ["export", str(scene), "--format", "mitsuba", "--out", str(out)]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "light[1].falloff" in err and len(err.strip().splitlines()) == 1
    assert not any(out.parent.iterdir())
    with pytest.warns(UserWarning, match=r"light\[1\]\.falloff: the \"smoothstep\" spot curve; written as Mitsuba's spot"):
        assert main(args + ["--approximate"]) == 0
    assert '<emitter type="spot">' in out.read_text()


# ------------------------------------------------------------------------------------------- Mitsuba 3 itself

@pytest.fixture(scope="module")
def mi():
    pytest.importorskip("mitsuba")
    sys.path.insert(0, str(ROOT))
    from benchmarks.vs_mitsuba import choose_variant

    import mitsuba

    mitsuba.set_variant(choose_variant("auto")[0])
    return mitsuba


def mitsuba_runs(mi, xml, spp, runs):
    scene = mi.load_file(str(xml))
    return np.array([np.array(mi.render(scene, spp=spp, seed=k), dtype=np.float64)[..., :3] for k in range(runs)])


def agreement(runs, ours):
    """(mean ratio Mitsuba / ours over the lit pixels' totals, its standard error from the runs, the
    per-pixel ratio's median, per-channel z-scores of the lit pixels against Mitsuba's standard error)."""
    mean, sem = runs.mean(0), runs.std(0, ddof=1) / np.sqrt(len(runs))
    lit = ours.sum(2) > 1e-3 * ours.sum(2).max()
    per_run = runs.sum(3)[:, lit].sum(1) / ours.sum(2)[lit].sum()
    z = ((mean - ours) / np.maximum(sem, 1e-300))[lit]
    return per_run.mean(), per_run.std(ddof=1) / np.sqrt(len(runs)), np.median(mean.sum(2)[lit] / ours.sum(2)[lit]), z


def check_agreement(runs, ours):
    ratio, se, median, z = agreement(runs, ours)
    n = len(runs)
    # an unbiased match: z is Student's t with n - 1 degrees of freedom (mean square (n-1)/(n-3));
    # edge pixels (our 16 x 16 stratified samples against Mitsuba's random ones) leave a few outliers
    assert abs(ratio - 1.0) < 4 * se + 1e-3, (ratio, se)
    assert abs(median - 1.0) < 5e-3, median
    assert np.mean(z ** 2) < 1.5 * (n - 1) / (n - 3), np.mean(z ** 2)
    assert np.mean(np.abs(z) > 5) < 2e-3, np.sort(np.abs(z))[-10:]


@pytest.mark.peers
def test_hand_written_room_agrees_with_mitsuba(mi):
    ours = raytrace.render(str(DATA / "room.xml"), method="quadrature", spp=256).array
    check_agreement(mitsuba_runs(mi, DATA / "room.xml", 512, 16), ours)


@pytest.mark.peers
def test_hand_written_room_with_spot_agrees_with_mitsuba(mi):
    ours = raytrace.render(str(DATA / "room_spot.xml"), method="quadrature", spp=256).array
    check_agreement(mitsuba_runs(mi, DATA / "room_spot.xml", 512, 16), ours)


@pytest.mark.peers
def test_exported_bundled_scene_agrees_with_mitsuba(mi, tmp_path):
    over = ["camera.width=48", "camera.height=32", "camera.spp=256"]
    raw, source, _ = raytrace.api.scene_dict("shafts", over)
    out = tmp_path / "shafts.xml"
    mitsuba.export(raw, out, source, False)
    ours = raytrace.render("shafts", method="quadrature", volumetric_shadows=True, overrides=over).array
    check_agreement(mitsuba_runs(mi, out, 512, 16), ours)


@pytest.mark.peers
@pytest.mark.parametrize("name", ["round trip", "interior", "shafts", "stage", "box_room", "particles_shaft"])
def test_mitsuba_loads_every_export(mi, tmp_path, name):
    approximate = name in ("stage", "particles_shaft")  # smoothstep spots; a particle layer
    if name == "round trip":
        raw, source = round_trip_scene(), "round trip"
    elif name == "interior":
        raw, source = round_trip_scene(), "interior"
        raw["shape"].append({"primitive": "box", "min": [-0.5, -1.9, -1.0], "max": [0.5, -1.0, 0.0],
                             "interior": {"sigma_a": 0.2, "sigma_s": 0.6, "phase": {"type": "hg", "g": -0.3}}})
    else:
        over = ['camera.type="perspective"', "camera.fov=60.0"] if name == "box_room" else []
        raw, source, _ = raytrace.api.scene_dict(name, over)
    out = tmp_path / "scene.xml"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore" if approximate else "error")
        files = mitsuba.export(raw, out, source, approximate)
    scene = mi.load_file(str(out))
    ours = scene_from_dict(raw, source)
    # every triangle (Mitsuba merges meshes that share a bsdf), every light
    assert sum(shape.face_count() for shape in scene.shapes()) == len(scene_triangles(ours)[0])
    assert len(scene.emitters()) == len(ours.lights) and len(files) >= 1


@pytest.mark.peers
@pytest.mark.parametrize("fov", ['<float name="fov" value="50"/>',
                                 '<float name="fov" value="50"/><string name="fov_axis" value="diagonal"/>',
                                 '<float name="fov" value="50"/><string name="fov_axis" value="smaller"/>',
                                 '<string name="focal_length" value="28mm"/>'])
def test_camera_rays_match_mitsuba_sensor(mi, tmp_path, fov):
    """Mitsuba's sensor (parsed by Mitsuba) and our imported camera shoot the same rays through the
    pixel centres: fov axes, a lookat without up (Mitsuba's own basis), rotations after it."""
    from raytrace.camera import generate_rays

    p = write(tmp_path, f"""<sensor type="perspective">{fov}
<transform name="to_world"><lookat origin="1, 2, 3" target="1.2, -1, 2.5"/><rotate x="0.6" y="0.8" angle="7"/></transform>
<film type="hdrfilm"><integer name="width" value="9"/><integer name="height" value="5"/></film>
<sampler type="independent"><integer name="sample_count" value="1"/></sampler></sensor>""")
    cam = scene_from_dict(mitsuba.read_scene(p), str(p)).camera
    o, d = generate_rays(cam)
    sensor = mi.load_file(str(p)).sensors()[0]
    for k in range(cam.width * cam.height):
        j, i = divmod(k, cam.width)
        ray, _ = sensor.sample_ray(0.0, 0.5, [(i + 0.5) / cam.width, (j + 0.5) / cam.height], [0.5, 0.5])
        assert np.allclose(np.ravel(ray.d), d[k], atol=1e-6)
        assert np.linalg.norm(np.cross(np.ravel(ray.o) - o[k], d[k])) < 1e-5  # Mitsuba's starts at its near_clip


@pytest.mark.peers
def test_shape_geometry_matches_mitsuba(mi, tmp_path):
    """Each imported shape's bounding box equals the one Mitsuba builds from the same XML (its
    parser, transforms and shape plugins): rotations about a non-unit axis, matrices, lookat."""
    (tmp_path / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    shapes = {
        "rect": '<shape type="rectangle" id="{}"><transform name="to_world"><scale x="0.5" y="2"/>'
                '<rotate x="1" y="1" angle="30"/><translate value="1 2 3"/></transform>{}</shape>',
        "cube": '<shape type="cube" id="{}"><transform name="to_world"><rotate y="1" angle="25"/>'
                '<matrix value="1 0.2 0 0  0 1 0 1  0 0 2 0  0 0 0 1"/></transform>{}</shape>',
        "ball": '<shape type="sphere" id="{}"><point name="center" value="1, 0, -1"/><float name="radius" value="0.3"/>'
                '<transform name="to_world"><scale value="2"/><rotate z="1" angle="40"/></transform>{}</shape>',
        "disk": '<shape type="disk" id="{}"><transform name="to_world"><lookat origin="0, 1, 0" target="1, 2, 1"/>'
                '</transform>{}</shape>',
        "tube": '<shape type="cylinder" id="{}"><point name="p1" value="0, 1, 2"/><float name="radius" value="0.4"/>'
                '<transform name="to_world"><translate x="-2"/></transform>{}</shape>',
        "mesh": '<shape type="obj" id="{}"><string name="filename" value="tri.obj"/><transform name="to_world">'
                '<rotate x="2" angle="60"/><scale value="1.5"/></transform>{}</shape>',
    }
    body = "".join(s.format(k, f'<bsdf type="diffuse"><float name="reflectance" value="{0.1 * i}"/></bsdf>')
                   for i, (k, s) in enumerate(shapes.items()))
    p = write(tmp_path, SENSOR.format(axis="x").replace("</sensor>", '<float name="far_clip" value="1e5"/></sensor>'
                                                       ) + body)
    raw = mitsuba.read_scene(p)
    theirs = {s.id(): s.bbox() for s in mi.load_file(str(p)).shapes()}
    for (name, _), shape in zip(shapes.items(), raw["shape"]):
        one = scene_from_dict({"camera": raw["camera"], "shape": [shape]}, str(p), p)
        tris = scene_triangles(one)[0].reshape(-1, 3)
        box = theirs[name]
        # tessellated curves lie within their sagitta inside Mitsuba's exact extent
        tol = 2e-3 if name in ("ball", "disk", "tube") else 1e-5
        assert np.allclose(tris.min(0), np.ravel(box.min), atol=tol), name
        assert np.allclose(tris.max(0), np.ravel(box.max), atol=tol), name


def test_a_refused_file_lists_all_its_problems_in_one_run(tmp_path):
    """Every unsupported element and parameter at once, after a line that counts them (a Cornell box:
    a spot emitter in a shape, a conductor bsdf, an envmap whose file is missing, two parameters not read)."""
    body = (SENSOR.format(axis="x").replace("<transform", '<float name="lens" value="1"/><transform')
            + '<shape type="cube"><emitter type="spot"/><bsdf type="conductor"/></shape>'
            '<emitter type="envmap"><string name="filename" value="sky.exr"/></emitter>'
            '<shape type="sphere"><float name="radiuss" value="1"/><float name="radiusss" value="1"/></shape>'
            '<emitter type="point"><point name="position" value="0, 1, 0"/></emitter>')
    with pytest.raises(UserError) as err:
        mitsuba.read_scene(write(tmp_path, body))
    lines = str(err.value).splitlines()
    assert lines[0] == f"{tmp_path / 'scene.xml'}: 6 problems, one a line with its fix"
    for line, part in zip(lines[1:], ["parameter 'lens'", "a spot emitter inside a shape is not read",
                                      "conductor bsdfs are not read", "envmap file 'sky.exr' not found",
                                      "parameter 'radiuss'", "parameter 'radiusss'"]):
        assert re.match(re.escape(str(tmp_path / 'scene.xml')) + r":\d+: <", line) and part in line and "; " in line, (line, part)
    assert len(lines) == 7


def test_export_refusal_mentions_approximate(tmp_path):
    raw = round_trip_scene()
    raw["render"] = {"volumetric_shadows": False}
    with pytest.raises(UserError, match=r"or pass --approximate to write shadowed"):
        exported(tmp_path, raw)


@pytest.mark.parametrize("kind", ["plastic", "roughplastic"])
def test_coated_bsdfs_are_read_as_their_diffuse_base(tmp_path, kind):
    """Mitsuba's plastic and roughplastic (a diffuse base under a dielectric coat) become diffuse
    surfaces of their diffuse_reflectance (default 0.5), inside twosided too, with a note naming the line
    (the same note once); their coat's parameters are accepted and not rendered."""
    body = (SENSOR.format(axis="x")
            + f'<shape type="cube"><bsdf type="{kind}"><rgb name="diffuse_reflectance" value="0.2, 0.3, 0.4"/>'
            '<float name="int_ior" value="1.9"/><rgb name="specular_reflectance" value="0.5"/></bsdf></shape>'
            f'<shape type="sphere"><bsdf type="twosided"><bsdf type="{kind}"/></bsdf></shape>'
            '<emitter type="point"><point name="position" value="0, 1, 0"/></emitter>')
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        raw = mitsuba.read_scene(write(tmp_path, body))
    notes = [str(w.message) for w in said if issubclass(w.category, mitsuba.MitsubaNote)]
    assert len(notes) == 1 and re.search(rf"scene.xml:\d+: <bsdf type=\"{kind}\">: {kind} read as diffuse of its "
                                         "diffuse_reflectance; ", notes[0]), notes
    assert [s["reflectance"] for s in raw["shape"]] == [[0.2, 0.3, 0.4], 0.5]
