"""pbrt-v4 scenes in and out (raytrace/io/pbrt.py, docs/formats/pbrt.md).

The expected numbers are derived by hand from pbrt-v4's sources (github.com/mmp/pbrt-v4 at commit
5f7a6068; files under src/pbrt/), not from the importer; the pbrt camera below is a twin written from
cameras.h and util/transform.cpp.
"""
from __future__ import annotations

import math
import os
import re
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest

import raytrace
from raytrace.camera import basis, generate_rays
from raytrace.cli import main
from raytrace.errors import UserError
from raytrace.io import pbrt
from raytrace.lights import DIRECTIONAL, SPOT
from raytrace.scene.assets import bundled_scenes
from raytrace.scene.format import read_toml, scene_from_dict
from raytrace.scene.meshes import scene_triangles

DATA = Path(__file__).parent / "data" / "pbrt"


def read(name):
    return pbrt.read_scene(DATA / name)


def triangles(shape) -> set:
    """An inline mesh's triangles as a set of corner sets (rounded to 1e-12)."""
    v = np.asarray(shape["vertices"])
    return {frozenset(tuple(np.round(p, 12) + 0.0) for p in v[f]) for f in np.asarray(shape["faces"])}


def square(*corners):
    """The two triangles (p0 p1 p2), (p0 p2 p3) of a quad, as `triangles` gives them."""
    c = [tuple(map(float, p)) for p in corners]
    return {frozenset([c[0], c[1], c[2]]), frozenset([c[0], c[2], c[3]])}


# ------------------------------------------------------------------------------------------- a twin of pbrt's camera


def pbrt_look_at(eye, look, up):
    """util/transform.cpp lines 81-113: worldFromCamera has columns right = normalize(up x dir),
    newUp = dir x right, dir = normalize(look - eye), eye."""
    eye, look, up = (np.asarray(a, float) for a in (eye, look, up))
    d = (look - eye) / np.linalg.norm(look - eye)
    right = np.cross(up / np.linalg.norm(up), d)
    right /= np.linalg.norm(right)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, np.cross(d, right), d, eye
    return m


def pbrt_directions(world_from_camera, fov, W, H, xs, ys, window=None):
    """World directions of pbrt-v4's perspective camera rays through raster points (xs, ys): cameras.cpp
    lines 495-509 (the screen window: the shorter axis spans [-1, 1]), cameras.h lines 263-272
    (rasterFromScreen = Scale(W, -H, 1) Scale(1 / (max.x - min.x), 1 / (max.y - min.y), 1)
    Translate(-min.x, -max.y, 0)), transform.cpp lines 119-130 (Perspective: Scale(1 / tan(fov / 2))
    after the projective divide); PerspectiveCamera::GenerateRay: dir = normalize(cameraFromRaster(p))."""
    frame = W / H
    (x0, x1), (y0, y1) = ((-frame, frame), (-1.0, 1.0)) if frame > 1 else ((-1.0, 1.0), (-1.0 / frame, 1.0 / frame))
    if window is not None:  # "float screenwindow" [x0 x1 y0 y1] replaces the default (cameras.cpp lines 510-523)
        (x0, x1), (y0, y1) = window[:2], window[2:]
    sx, sy = x0 + np.asarray(xs) / W * (x1 - x0), y1 - np.asarray(ys) / H * (y1 - y0)  # raster -> screen
    t = math.tan(math.radians(fov) / 2.0)
    d = np.stack([sx * t, sy * t, np.ones_like(sx)], axis=-1)  # screen -> camera at z = 1
    d = d @ world_from_camera[:3, :3].T
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


@pytest.mark.parametrize("name, world_from_camera, fov, mirror", [
    # fog_room.pbrt: Scale -1 1 1, LookAt: CTM = S L, so worldFromCamera = L^-1 S^-1
    ("fog_room.pbrt", pbrt_look_at([0, 2, 6], [0, 1.5, 0], [0, 1, 0]) @ np.diag([-1.0, 1, 1, 1]), 45.0, False),
    # sun_room.pbrt: a plain LookAt, a portrait film: pbrt's image is mirrored and fov spans its width
    ("sun_room.pbrt", pbrt_look_at([0, 2, 6], [0, 1.5, 0], [0, 1, 0]), 40.0, True),
    ("asymmetric.pbrt", pbrt_look_at([0, 0, 0], [0, 0, 1], [0, 1, 0]), 40.0, True),
])
def test_camera_rays_match_pbrts(name, world_from_camera, fov, mirror):
    """Every pixel centre's ray of the imported camera is pbrt's ray through the same raster point
    (x negated where the file's camera is mirrored): orientation, handedness and fov axis at once."""
    scene = scene_from_dict(read(name), name)
    cam = scene.camera
    cam.spp = 1  # the pixel centres
    _, d = generate_rays(cam)
    j, i = np.meshgrid(np.arange(cam.height) + 0.5, np.arange(cam.width) + 0.5, indexing="ij")
    want = pbrt_directions(world_from_camera, fov, cam.width, cam.height, i.ravel(), j.ravel())
    if mirror:
        want[:, 0] *= -1.0
    np.testing.assert_allclose(d, want, atol=1e-12)


def pbrt_equirect_directions(world_from_camera, W, H, xs, ys):
    """cameras.cpp SphericalCamera::GenerateRay, equirectangular: theta = pi y / H, phi = 2 pi x / W,
    dir = (sin theta cos phi, sin theta sin phi, cos theta) with y and z swapped."""
    theta, phi = math.pi * np.asarray(ys) / H, 2.0 * math.pi * np.asarray(xs) / W
    d = np.stack([np.sin(theta) * np.cos(phi), np.cos(theta), np.sin(theta) * np.sin(phi)], axis=-1)
    return d @ world_from_camera[:3, :3].T


@pytest.mark.parametrize("name, size", [("stage", None), ("stage", (9, 16)), ("box_room", None)])
def test_exported_camera_is_ours_in_pbrt(name, size, tmp_path):
    """The camera lines we write, read by the pbrt twins above (perspective: Scale -1 1 1 then LookAt,
    so worldFromCamera = LookAt^-1 Scale(-1, 1, 1); spherical: a plain LookAt), give our camera's ray
    at every pixel centre."""
    out = tmp_path / "x.pbrt"
    raw = read_toml(bundled_scenes()[name])
    if size:  # a portrait film: pbrt's fov spans the width
        raw["camera"].update(width=size[0], height=size[1])
    pbrt.export(raw, out, name, False)
    lines = out.read_text().splitlines()
    look = next(np.array(ln.split()[1:], float) for ln in lines if ln.startswith("LookAt"))
    wfc = pbrt_look_at(look[:3], look[3:6], look[6:])
    cam = scene_from_dict(raw, name).camera
    cam.spp = 1
    _, d = generate_rays(cam)
    j, i = np.meshgrid(np.arange(cam.height) + 0.5, np.arange(cam.width) + 0.5, indexing="ij")
    if cam.type == "perspective":
        assert "Scale -1 1 1" in lines
        fov = float(next(ln for ln in lines if ln.startswith("Camera")).split("[")[1].split("]")[0])
        want = pbrt_directions(wfc @ np.diag([-1.0, 1, 1, 1]), fov, cam.width, cam.height, i.ravel(), j.ravel())
    else:
        want = pbrt_equirect_directions(wfc, cam.width, cam.height, i.ravel(), j.ravel())
    np.testing.assert_allclose(d, want, atol=1e-12)


def test_image_orientation_asymmetric_scene():
    """asymmetric.pbrt: pbrt shows the sphere at world x = +1.5 right of centre (its docstring derives it
    from LookAt and rasterFromNDC), at raster x = 16 (1 + 0.3 / (2 tan 20 deg)) = 22.6, and the lit floor
    below. Rendered from the imported scene, so are ours."""
    img = raytrace.render(pbrt.read_scene(DATA / "asymmetric.pbrt"), method="analytic").array.sum(axis=2)
    row = img[8]
    assert row[21:25].min() > 0.05  # the sphere, around column 22.6
    assert row[7:11].max() == 0.0  # its mirror image is black: nothing there
    assert img[:4].max() == 0.0 and img[12:].min() > 0.0  # black above the sphere, the floor below


# --------------------------------------------------------------------------------------------- hand-written files


def test_fog_room_imports_pbrts_units():
    """fog_room.pbrt against numbers derived by hand from pbrt-v4's sources:

    - lights: pbrt's output RGB of a light "rgb I" [r g b] with `scale` s is s (r, g, b). lights.cpp
      lines 196-200 divide the scale by SpectrumToPhotometric(I), which for an RGB spectrum is the
      luminance of its illuminant alone (util/spectrum.cpp lines 37-47: the colour space's D65,
      normalised to Y = CIE_Y_integral by util/spectrum.cpp line 156); the XYZ sensor's Y is the
      plain integral against y-bar (film.h lines 95-100, imaging ratio 1 at film.cpp lines 220-233), so
      "rgb I" [1 1 1] renders as Y = 1, RGB (1, 1, 1).
    - point light (lights.cpp lines 202-206): power 100, scale 2: 2 * 100 / (4 pi) (1, 0.5, 0.25) =
      (15.915494309189533, 7.957747154594767, 3.978873577297383) W/sr.
    - spot light (lights.cpp lines 1441-1460): coneangle 30, conedeltaangle 10 -> cos_end = cos 30 deg =
      0.8660254037844387, cos_start = cos 20 deg = 0.9396926207859084, k_e = 2 pi ((1 - cos_start) +
      (cos_start - cos_end) / 2) = 0.6103548267347101; power 50, scale 3: I = 150 / k_e =
      245.75868565252995 W/sr; its smoothstep between 20 and 30 deg (lines 1360-1363) is our default.
      Placed by the CTM (Translate 0 3.5 0): from (2, 3.5, 0), axis towards (1, 0, 0).
    - medium (media.cpp lines 175-197): scale 2 multiplies sigma_a and sigma_s; g is HG's.
    - camera: fov 45 on a 32 x 24 film spans the height (cameras.cpp lines 499-503), our vertical fov.
    - plate: (x, y, 0) -> Translate(1, 1.2, 0) Rotate(90, x) Scale(1.5) -> (1 + 1.5 x, 1.2, 1.5 y)
      (Rotate: util/transform.h lines 220-241).
    """
    d = read("fog_room.pbrt")
    cam = d["camera"]
    assert cam["position"] == [0.0, 2.0, 6.0] and (cam["width"], cam["height"], cam["spp"], cam["fov"]) == (32, 24, 4, 45.0)
    f = np.subtract(cam["look_at"], cam["position"])
    np.testing.assert_allclose(f / np.linalg.norm(f), np.array([0, -0.5, -6]) / math.sqrt(36.25), atol=1e-15)
    np.testing.assert_allclose(cam["up"], np.array([0, 12, -1]) / math.sqrt(145), atol=1e-15)
    assert d["medium"] == {"sigma_a": [0.02, 0.04, 0.06], "sigma_s": [0.2, 0.2, 0.2], "phase": {"type": "hg", "g": 0.3}}
    point, spot = d["light"]
    assert point["type"] == "point" and point["position"] == [-1.0, 3.0, 1.0]
    np.testing.assert_allclose(point["intensity"], [15.915494309189533, 7.957747154594767, 3.978873577297383],
                               rtol=1e-15)
    assert spot["type"] == "spot" and spot["position"] == [2.0, 3.5, 0.0]
    assert (spot["cone_angle"], spot["falloff_start"]) == (30.0, 20.0)
    np.testing.assert_allclose(spot["intensity"], [245.75868565252995] * 3, rtol=1e-14)
    np.testing.assert_allclose(spot["direction"], np.array([-1, -3.5, 0]) / math.sqrt(13.25), atol=1e-15)
    floor, wall, plate, sphere = d["shape"]
    assert triangles(floor) == square([-4, 0, -4], [4, 0, -4], [4, 0, 4], [-4, 0, 4])
    assert triangles(wall) == square([-4, 0, -4], [4, 0, -4], [4, 4, -4], [-4, 4, -4])
    assert floor["reflectance"] == wall["reflectance"] == [0.6, 0.55, 0.5] and plate["reflectance"] == [0.8] * 3
    assert triangles(plate) == square([0.25, 1.2, -0.75], [1.75, 1.2, -0.75], [1.75, 1.2, 0.75], [0.25, 1.2, 0.75])
    assert sphere == {"primitive": "sphere", "center": [-1.5, 1.0, 0.0], "radius": 0.75, "segments": 64,
                      "exact": True, "interior": {"sigma_a": [0.5] * 3, "sigma_s": [1.0, 2.0, 3.0], "phase": "isotropic", "ior": 1.0}}
    scene_from_dict(d, "fog_room.pbrt")  # a valid scene


def test_sun_room_imports_mirrored():
    """sun_room.pbrt: a plain LookAt, so x is negated everywhere (see test_camera_rays_match_pbrts);
    a 24 x 32 film: fov 40 spans the width, vertical fov = 2 atan(tan 20 deg * 32 / 24) =
    51.77400875924256 deg; distant light (lights.cpp lines 250-273): irradiance scale * illuminance *
    L = 1.5 * 4 * (0.8, 0.9, 1), travelling from -> to = -(1, 4, 2) / sqrt 21 (mirrored: (1, -4, -2) /
    sqrt 21); the dielectric's eta is the interior's ior; Scale 0.5 makes the radius 0.75; pbrt's
    default spp is 16 (samplers.cpp line 70)."""
    d = read("sun_room.pbrt")
    assert "medium" not in d and d["camera"]["spp"] == 16
    assert d["camera"]["fov"] == pytest.approx(51.77400875924256, rel=1e-14)
    (sun,) = d["light"]
    np.testing.assert_allclose(sun["irradiance"], [4.8, 5.4, 6.0], rtol=1e-15)
    np.testing.assert_allclose(sun["direction"], np.array([1, -4, -2]) / math.sqrt(21), atol=1e-15)
    plate, sphere = d["shape"][2:]
    assert triangles(plate) == square([-0.25, 1.2, -0.75], [-1.75, 1.2, -0.75], [-1.75, 1.2, 0.75],
                                      [-0.25, 1.2, 0.75])
    assert sphere["center"] == [1.5, 1.0, 0.0] and sphere["radius"] == 0.75
    assert sphere["interior"] == {"sigma_a": [0.5] * 3, "sigma_s": [1.0, 2.0, 3.0], "phase": {"type": "hg", "g": -0.2},
                                  "ior": 1.33}
    scene_from_dict(d, "sun_room.pbrt")


def test_transforms_and_shapes(tmp_path):
    """Transform lists the matrix column by column and replaces the CTM; ConcatTransform multiplies
    (scene.cpp lines 577-587); CoordinateSystem / CoordSysTransform save and restore it; a sphere
    under a non-uniform scale becomes triangles on the ellipsoid; a non-planar bilinear patch is
    tessellated on the patch; Import keeps the importer's graphics state."""
    (tmp_path / "part.pbrt").write_text('Translate 100 0 0\nShape "trianglemesh" "point3 P" [ 0 0 0 1 0 0 0 1 0 ]\n')
    p = tmp_path / "t.pbrt"
    p.write_text("""Scale -1 1 1
LookAt 0 0 -10  0 0 0  0 1 0
Camera "perspective"
WorldBegin
CoordinateSystem "start"
Transform [ 1 0 0 0  0 1 0 0  0 0 1 0  5 6 7 1 ]
Shape "trianglemesh" "point3 P" [ 0 0 0 1 0 0 0 1 0 ]
ConcatTransform [ 2 0 0 0  0 2 0 0  0 0 2 0  0 0 0 1 ]
Shape "trianglemesh" "point3 P" [ 0 0 0 1 0 0 0 1 0 ]
CoordSysTransform "start"
Scale 1 2 3
Shape "sphere" "float radius" 2
Identity
Shape "bilinearmesh" "point3 P" [ 0 0 0  1 0 0  0 1 0  1 1 1 ]
Import "part.pbrt"
Shape "trianglemesh" "point3 P" [ 0 0 0 1 0 0 0 1 0 ]
""")
    d = pbrt.read_scene(p)
    t1, t2, ellipsoid, patch, imported, last = d["shape"]
    assert triangles(t1) == {frozenset([(5.0, 6.0, 7.0), (6.0, 6.0, 7.0), (5.0, 7.0, 7.0)])}
    assert triangles(t2) == {frozenset([(5.0, 6.0, 7.0), (7.0, 6.0, 7.0), (5.0, 8.0, 7.0)])}
    v = np.asarray(ellipsoid["vertices"])
    np.testing.assert_allclose((v / [2.0, 4.0, 6.0]) ** 2 @ np.ones(3), 1.0, rtol=1e-12)  # on x²/4 + y²/16 + z²/36 = 1
    assert np.ptp(v, axis=0) == pytest.approx([4.0, 8.0, 12.0], rel=2e-3)
    v = np.asarray(patch["vertices"])
    np.testing.assert_allclose(v[:, 2], v[:, 0] * v[:, 1], atol=1e-15)  # on the patch z = u v
    assert len(patch["faces"]) == 2 * 16 * 16
    assert triangles(imported) == {frozenset([(100.0, 0.0, 0.0), (101.0, 0.0, 0.0), (100.0, 1.0, 0.0)])}
    assert triangles(last) == {frozenset([(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)])}


def test_render_fog_room_through_the_cli(tmp_path):
    """`render.py render FILE.pbrt` renders an imported scene; --set applies to it."""
    out = tmp_path / "fog.exr"
    assert main(["render", str(DATA / "fog_room.pbrt"), "--out", str(out), "--width", "6", "--height", "4",
                 "--spp", "1", "--method", "quadrature", "--set", "shape.3.segments=16"]) == 0
    assert out.is_file()


# ------------------------------------------------------------------------------------------------------- bad input

BASE = 'LookAt 0 0 0 0 0 1 0 1 0\nCamera "perspective"\nWorldBegin\n'


@pytest.mark.parametrize("text, fragments", [
    (BASE + 'Shape "sphere" "float radius" [ 1\n\n"bad', [":6:", "unterminated string"]),
    (BASE + "\nFrobnicate 1 2 3\n", [":5:", "unknown directive Frobnicate"]),
    (BASE + 'Shape "sphere" "float radius" 1e999\n', [":4:", "1e999 is not a finite number"]),
    (BASE + 'Translate nan 0 0\n', [":4:", "nan is not a finite number"]),
    (BASE + 'LightSource "point" "rgb I" [ 1 inf 1 ]\n', [":4:", "inf is not a finite number"]),
    (BASE + 'Shape "plymesh" "string filename" "missing.ply"\n', [":4:", "missing.ply", "not found"]),
    (BASE + 'Shape "disk" "float innerradius" 0.5\n', [":4:", "only a whole disk"]),
    (BASE + 'Shape "cylinder"\n', [":4:", 'Shape "cylinder" is not read']),
    (BASE + 'Material "conductor"\n', [":4:", 'Material "conductor" is not read']),
    (BASE + 'LightSource "infinite" "string filename" "sky.exr"\n', [":4:", '"string filename"',
                                                                     "equal-area octahedral"]),
    (BASE + 'LightSource "infinite" "point3 portal" [ 0 0 0 1 0 0 1 1 0 0 1 0 ]\n', [":4:", "portal"]),
    (BASE + 'LightSource "goniometric"\n', [":4:", 'LightSource "goniometric" is not read']),
    (BASE + 'AreaLightSource "diffuse" "bool twosided" 3\n', [":4:", '"bool twosided" needs true or false']),
    (BASE + 'ReverseOrientation\nAreaLightSource "diffuse"\nShape "sphere"\n', [":6:", "emits inward"]),
    (BASE + 'LightSource "point" "blackbody I" 3000\n', [":4:", '"blackbody I" is a non-RGB spectrum']),
    (BASE + 'Texture "t" "spectrum" "imagemap"\n', [":4:", "Texture (textures) is not read"]),
    (BASE + 'Material "diffuse" "texture reflectance" "t"\n', [":4:", '"texture reflectance" is type texture']),
    (BASE + 'Material "diffuse" "rgb reflectance" [ 1.5 0 0 ]\n', [":4:", "outside [0, 1]"]),
    (BASE + 'Shape "sphere" "float zmax" 0.5\n', [":4:", '"zmax" (a partial sphere)']),
    (BASE + 'Shape "sphere" "float radiuss" 2\n', [":4:", 'parameter "float radiuss" is not read']),
    (BASE + 'Shape "trianglemesh" "point3 P" [ 0 0 0 1 0 0 0 1 0 ] "integer indices" [ 0 1 3 ]\n',
     [":4:", "3 indices per element"]),
    (BASE + "AttributeEnd\n", [":4:", "AttributeEnd without a matching AttributeBegin"]),
    (BASE + "AttributeBegin\n", [":4:", "AttributeBegin without AttributeEnd"]),
    (BASE + 'MediumInterface "fog" ""\nShape "sphere"\n', [":5:", 'medium "fog" is not defined']),
    ('Camera "orthographic"\n', [":1:", 'Camera "orthographic" is not read']),
    ('Shape "sphere"\n', [":1:", "Shape before WorldBegin"]),
    (BASE + 'Film "rgb"\n', [":4:", "Film after WorldBegin"]),
    ("LookAt 0 0 0 0 0 0 0 1 0\n", [":1:", "LookAt: the eye equals the look point"]),
    ("WorldBegin\n", [":1:", "WorldBegin before any Camera"]),
    ('Camera "perspective" "float fov" [ 1 2\n', ["unexpected end of file"]),
    ('Camera "perspective" "fov" 1\n', [":1:", '"fov" is not a parameter declaration']),
])
def test_bad_input_one_line(tmp_path, capsys, text, fragments):
    """Each mistake: exit 2 and one line naming the file, the line, the directive and the fix."""
    p = tmp_path / "bad.pbrt"
    p.write_text(text)
    assert main(["describe", str(p)]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "Traceback" not in err and "; " in err
    for f in fragments:
        assert f in err, err
    assert str(p) in err


def test_include_loop(tmp_path):
    (tmp_path / "a.pbrt").write_text(BASE + 'Include "b.pbrt"\n')
    (tmp_path / "b.pbrt").write_text('\nInclude "a.pbrt"\n')
    with pytest.raises(UserError, match=r"b\.pbrt:2: Include loop \(a\.pbrt -> b\.pbrt -> a\.pbrt\)"):
        pbrt.read_scene(tmp_path / "a.pbrt")


# ---------------------------------------------------------------------------------------------------- round trips


def same_scene(a, b):
    """Two validated scenes describe the same thing: camera rays, lights, medium, every triangle with its
    reflectance and interior."""
    ca, cb = a.camera, b.camera
    assert (ca.type, ca.width, ca.height, ca.spp) == (cb.type, cb.width, cb.height, cb.spp)
    if ca.type == "perspective":
        assert ca.fov == pytest.approx(cb.fov, rel=1e-13)
    np.testing.assert_allclose(ca.position, cb.position, rtol=1e-15, atol=1e-15)
    np.testing.assert_allclose(np.array(basis(ca)), np.array(basis(cb)), atol=1e-14)
    assert len(a.lights) == len(b.lights)
    for la, lb in zip(a.lights, b.lights):
        assert la.kind == lb.kind
        np.testing.assert_allclose(la.intensity, lb.intensity, rtol=1e-15)
        if la.kind != DIRECTIONAL:
            np.testing.assert_array_equal(la.position, lb.position)
        if la.kind in (SPOT, DIRECTIONAL):
            np.testing.assert_allclose(la.axis, lb.axis, atol=1e-15)
            np.testing.assert_allclose([la.cos_end, la.cos_start], [lb.cos_end, lb.cos_start], atol=1e-15)
    ma, mb = a.medium, b.medium
    np.testing.assert_array_equal(ma.sigma_a, mb.sigma_a)
    np.testing.assert_array_equal(ma.sigma_s, mb.sigma_s)
    assert (ma.phase, ma.g) == (mb.phase, mb.g)
    rows = []
    for scene in (a, b):  # (interior index, corners, reflectance) per triangle, sorted: a mesh of several
        t, r, i = scene_triangles(scene, shape_ids=True)  # reflectances goes out as one shape per reflectance
        inner = [k for k, sh in enumerate(scene.shapes) if sh.interior is not None]
        which = np.array([inner.index(k) if k in inner else -1 for k in i], dtype=float)
        r = np.where(which[:, None] >= 0, -1.0, r)  # an interior's boundary has no surface
        key = np.concatenate([which[:, None], t.reshape(-1, 9), r], axis=1)
        rows.append(key[np.lexsort(key.T[::-1])])
    np.testing.assert_array_equal(*rows)
    ins = [[s.interior for s in scene.shapes if s.interior is not None] for scene in (a, b)]
    assert len(ins[0]) == len(ins[1])
    for ia, ib in zip(*ins):
        np.testing.assert_array_equal(ia.sigma_a, ib.sigma_a)
        np.testing.assert_array_equal(ia.sigma_s, ib.sigma_s)
        assert (ia.phase, ia.g, ia.ior) == (ib.phase, ib.g, ib.ior)


def round_trip(raw, source, tmp_path):
    out = tmp_path / "scene.pbrt"
    written = pbrt.export(raw, out, source, False)
    assert out in written
    back = pbrt.read_scene(out)
    path = Path(source) if Path(source).is_file() else None
    return scene_from_dict(raw, source, path), scene_from_dict(back, str(out), out), written


EXPRESSIBLE = ["box_room", "shafts", "stage", "wax"]


def same_image(a, b, width, height):
    """Both scenes render alike at a small size (shadowed analytic; quadrature inside shapes, where
    volumetric shadows are not implemented). The inputs agree to 1e-15 (a spot's axis and the camera's
    basis are renormalised), but the analytic method adapts its series to a requested 1e-3: a rounding
    difference may change a term count, so pixels agree to far below that precision, not bit for bit."""
    inside = any(s.interior is not None for s in a.shapes)
    kw = dict(method="quadrature" if inside else "analytic", width=width, height=height, spp=1,
              volumetric_shadows=not inside)
    ia, ib = raytrace.render(a, **kw).array, raytrace.render(b, **kw).array
    assert ia.max() > 0
    np.testing.assert_allclose(ib, ia, rtol=1e-6, atol=1e-9 * ia.max())


@pytest.mark.parametrize("name", EXPRESSIBLE)
def test_round_trip_bundled(name, tmp_path):
    """TOML -> pbrt -> import: the same scene (numbers printed with repr, so exactly up to the camera's
    basis, recomputed from pbrt's matrix) and the same image."""
    path = bundled_scenes()[name]
    a, b, _ = round_trip(read_toml(path), str(path), tmp_path)
    same_scene(a, b)
    same_image(a, b, 12, 8)


def test_round_trip_mesh_as_ply_portrait_and_sun(tmp_path):
    """A mesh file goes out as PLY beside the scene (doubles: exact); a portrait camera's fov, a sun
    with an index-matched interior in vacuum and a spot given by its direction come back."""
    shutil.copy(DATA / "plate.ply", tmp_path / "plate.ply")
    raw = {"camera": {"position": [0.5, 2.0, 5.0], "look_at": [0.0, 0.5, 0.0], "fov": 50.0, "width": 9, "height": 16},
           "shape": [{"mesh": "plate.ply", "reflectance": [0.7, 0.2, 0.1],
                      "transform": {"rotate": [90.0, 0.0, 0.0], "scale": 4.0}},
                     {"primitive": "sphere", "center": [0.0, 1.0, 0.0], "radius": 0.5, "segments": 12,
                      "interior": {"sigma_s": [0.5, 1.0, 2.0], "phase": {"type": "hg", "g": 0.4}}}],
           "light": [{"type": "directional", "direction": [0.3, -1.0, 0.2], "irradiance": [1.0, 2.0, 3.0]},
                     {"type": "spot", "position": [1.0, 3.0, 0.0], "direction": [0.0, -1.0, 0.1], "intensity": 5.0,
                      "cone_angle": 25.0}]}
    source = str(tmp_path / "scene.toml")
    (tmp_path / "scene.toml").write_text("")
    a, b, written = round_trip(raw, source, tmp_path)
    assert tmp_path / "scene_shape0.ply" in written
    same_scene(a, b)
    same_image(a, b, 9, 16)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["bridge", "sibenik"])
def test_round_trip_meshes_from_assets(name, tmp_path):
    """Scenes of real meshes (RAYTRACE_ASSETS): each mesh goes out as PLY files beside the scene, one per
    reflectance (sibenik's MTL colours), and comes back the same scene."""
    if not os.environ.get("RAYTRACE_ASSETS"):
        pytest.skip("needs RAYTRACE_ASSETS (../shared/scenes)")
    path = bundled_scenes()[name]
    a, b, written = round_trip(read_toml(path), str(path), tmp_path)
    assert sum(p.suffix == ".ply" for p in written) >= 2
    same_scene(a, b)


def test_export_writes_single_scattering_settings(tmp_path):
    """volpath with maxdepth 1 is single scattering: integrators.cpp line 1020 ends a path at a
    scattering event once depth (incremented there and at surfaces, line 1146) reaches maxdepth, after
    direct lighting at the first event; maxdepth 2 would add a second scattering. A box filter of
    radius 0.5 is the pixel's area; the camera is unmirrored by Scale -1 1 1."""
    out = tmp_path / "stage.pbrt"
    pbrt.export(read_toml(bundled_scenes()["stage"]), out, "stage", False)
    text = out.read_text()
    for line in ('Integrator "volpath" "integer maxdepth" [ 1 ]', 'PixelFilter "box" "float xradius" [ 0.5 ]',
                 'MediumInterface "fog" "fog"', "Scale -1 1 1\nLookAt"):
        assert line in text


@pytest.mark.parametrize("name, key", [("valley_fog", "medium.type"), ("sunrise", "medium.type"),
                                       ("ocean", "shape[0].interior.ior"), ("particles_shaft", "medium.particles")])
def test_export_refuses_what_pbrt_cannot_express(name, key, tmp_path, capsys):
    out = tmp_path / "x.pbrt"
    assert main(["export", name, "--format", "pbrt", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and key in err and "; " in err
    assert not any(tmp_path.iterdir())  # nothing written


@pytest.mark.parametrize("change, key", [
    (lambda r: r["light"][0].update(type="spot", look_at=[0.0, 0.0, 0.0], falloff="mitsuba"), "light[0].falloff"),
    (lambda r: r["medium"].update(phase="rayleigh"), "medium.phase"),
    (lambda r: r["medium"].update(phase={"type": "hg", "g": 0.995}), "medium.phase.g"),
    (lambda r: r.update(background={"radiance": 0.1}), "background.radiance"),
])
def test_approximate_writes_the_closest_form_with_a_warning(change, key, tmp_path, capsys):
    raw = read_toml(bundled_scenes()["shafts"])
    change(raw)
    with pytest.raises(UserError, match=re.escape(key) + ".*--approximate"):
        pbrt.export(raw, tmp_path / "x.pbrt", "shafts", False)
    assert not any(tmp_path.iterdir())
    pbrt.export(raw, tmp_path / "x.pbrt", "shafts", True)
    assert f"warning: shafts: {key}" in capsys.readouterr().err
    scene_from_dict(pbrt.read_scene(tmp_path / "x.pbrt"), "x.pbrt")



def test_tokens_and_options(tmp_path):
    """pbrt-v4's lexical rules (parser.cpp Tokenizer::Next, parseParameters): comments to the end of
    the line (not inside strings), escapes in strings, numbers with signs, leading dots and exponents,
    directives run together on one line, a bare value or a bracketed list; Option is read past, a
    stratified sampler takes xsamples x ysamples, MediumInterface with one name sets both sides."""
    toks = pbrt.tokenize('# a "comment"\n"a\\\\b\\"c" [+.5 5e-1]#x\nLookAt', "s")
    assert [(t.kind, t.value, t.line) for t in toks] == [
        ("str", 'a\\b"c', 2), ("[", "[", 2), ("word", "+.5", 2), ("word", "5e-1", 2), ("]", "]", 2),
        ("word", "LookAt", 3)]
    p = tmp_path / "t.pbrt"
    p.write_text('Option "bool disablepixeljitter" true\nSampler "stratified" "integer xsamples" 3 '
                 '"integer ysamples" [2]\nMakeNamedMedium "a b" "string type" "homogeneous" "rgb sigma_a" [0 0 0] '
                 '"rgb sigma_s" [+.5 5e-1 0.5E0]\nMediumInterface "a b"\nScale -1 1 1 LookAt 0 0 5 0 0 0 0 1 0 '
                 'Camera "perspective" "float fov" [30]#c\nWorldBegin\n')
    d = pbrt.read_scene(p)
    assert d["camera"]["spp"] == 6 and (d["camera"]["width"], d["camera"]["height"]) == (1280, 720)
    assert d["medium"] == {"sigma_a": [0.0] * 3, "sigma_s": [0.5] * 3, "phase": "isotropic"}


# Houdini's pbrt-v4 exporter (shadeops/houdini-pbrt-v4 tests/scenes/TestLights/test_pointlight.pbrt): a camera
# rotation written with 4 decimals and a screen window that sets the horizontal field of view
HOUDINI_CAMERA = ("Transform [ 0.6691 -0.4263 -0.6087 0 0 0.8192 -0.5736 0 -0.7431 -0.3838 -0.5481 0 0.5921 -0.07283 "
                  '13.84 1 ]\nCamera "perspective" "float fov" [ 45 ] "float screenwindow" [ -1 1 -0.75 0.75 ]\n')


def houdini(tmp_path, camera=HOUDINI_CAMERA, film='"integer xresolution" [ 32 ] "integer yresolution" [ 24 ]',
            world='LightSource "point" "rgb I" [ 0.5 0.75 1 ] "float scale" [ 5 ]\n'):
    p = tmp_path / "houdini.pbrt"
    p.write_text(f'Film "rgb" {film}\n{camera}WorldBegin\n{world}')
    return p


def test_screenwindow_sets_the_field_of_view(tmp_path):
    """Every pixel's ray is pbrt's through the window [-1 1 -0.75 0.75]: fov 45 spans the width (the
    default window would give the height fov 45, a third wider); the 4-decimal rotation (its axes'
    lengths differ by 1.2e-4) is read with a note, to the precision it was written."""
    with pytest.warns(pbrt.PbrtNote, match=r"orthonormal to 0\.00012 \(a rotation written with few decimals\)"):
        scene = scene_from_dict(pbrt.read_scene(houdini(tmp_path)), "houdini")
    cam = scene.camera
    cam.spp = 1
    _, d = generate_rays(cam)
    j, i = np.meshgrid(np.arange(cam.height) + 0.5, np.arange(cam.width) + 0.5, indexing="ij")
    m = np.array([float(t) for t in HOUDINI_CAMERA.split("[")[1].split("]")[0].split()]).reshape(4, 4).T
    want = pbrt_directions(np.linalg.inv(m), 45.0, 32, 24, i.ravel(), j.ravel(), window=(-1, 1, -0.75, 0.75))
    # Houdini writes a camera transform of det -1 (its handedness flip), so pbrt's image is not mirrored
    assert np.linalg.det(m[:3, :3]) < 0
    np.testing.assert_allclose(d, want, atol=2e-4)  # the file's axes are orthonormal to 4e-5
    assert cam.fov == pytest.approx(math.degrees(2 * math.atan(0.75 * math.tan(math.radians(22.5)))), rel=1e-12)


@pytest.mark.parametrize("window, needle", [
    ("-1 1 -0.5 1", "is off-centre (a lens shift)"),
    ("-1 1 -1 1", "the window's aspect 1 differs from the film's 32/24 = 1.33333"),
])
def test_screenwindow_that_is_not_read_is_refused_with_the_reason(tmp_path, window, needle):
    camera = HOUDINI_CAMERA.replace("-1 1 -0.75 0.75", window)
    with pytest.raises(UserError, match=re.escape(needle)):
        pbrt.read_scene(houdini(tmp_path, camera))


def test_camera_transform_orthonormal_to_1e3_or_refused(tmp_path):
    skewed = "Transform [ 1 0 0 0 0.01 1 0 0 0 0 1 0 0 0 5 1 ]\nCamera \"perspective\"\n"
    with pytest.raises(UserError, match=r"scales unevenly or shears the image \(axes off orthonormal by 0\.01\)"):
        pbrt.read_scene(houdini(tmp_path, skewed))
    stretched = "Scale 1 1.01 1\nCamera \"perspective\"\n"
    with pytest.raises(UserError, match="scales unevenly or shears"):
        pbrt.read_scene(houdini(tmp_path, stretched))


def test_film_iso_and_exposure_scale_the_lights(tmp_path):
    """film.cpp PixelSensor::Create: imagingRatio = exposureTime * ISO / 100, exposureTime = shutterclose -
    shutteropen (scene.cpp); the image is linear in the lights, so their power carries the factor."""
    plain = pbrt.read_scene(houdini(tmp_path))["light"][0]["intensity"]
    camera = HOUDINI_CAMERA.replace("[ -1 1 -0.75 0.75 ]", '[ -1 1 -0.75 0.75 ] "float shutteropen" 0.25 '
                                    '"float shutterclose" 0.75')
    with pytest.warns(pbrt.PbrtNote, match=r"0\.5 x 400 / 100 = 2 .*lights' power is scaled"):
        raw = pbrt.read_scene(houdini(tmp_path, camera, film='"integer xresolution" 32 "integer yresolution" 24 '
                                      '"float iso" 400 "float whitebalance" 0 "string sensor" "cie1931"'))
    assert raw["light"][0]["intensity"] == [2.0 * v for v in plain] == [5.0, 7.5, 10.0]


def test_film_defaults_are_silent_and_other_sensors_refused(tmp_path):
    square = HOUDINI_CAMERA.replace("0.6691 -0.4263 -0.6087 0 0 0.8192 -0.5736 0 -0.7431 -0.3838 -0.5481",
                                    "1 0 0 0 0 1 0 0 0 0 1")
    film = '"integer xresolution" 32 "integer yresolution" 24 '
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pbrt.read_scene(houdini(tmp_path, square, film + '"float iso" 100 "float whitebalance" 0 "string sensor" "cie1931"'))
    for extra, needle in [('"string sensor" "canon_eos_100d"', "a camera's spectral response"),
                          ('"float whitebalance" 5000', "a von Kries adaptation from a 5000 K daylight white")]:
        with pytest.raises(UserError, match=needle):
            pbrt.read_scene(houdini(tmp_path, square, film + extra))


def test_a_refused_file_lists_all_its_problems_in_one_run(tmp_path, capsys):
    """pbrt-v4-scenes' explosion.pbrt took four edits, one refusal each, before its real limit: now one
    run lists every unsupported feature, one line each after a line that counts them."""
    p = tmp_path / "many.pbrt"
    p.write_text('LookAt 0 0 5 0 0 0 0 1 0\nCamera "perspective" "float lensradius" 0.1\n'
                 'Film "rgb" "string sensor" "canon_eos_100d" "float iso" 100\nWorldBegin\n'
                 'AreaLightSource "diffuse" "string filename" "e.png"\nShape "sphere"\n'
                 'MakeNamedMedium "smoke" "string type" "nanovdb" "string filename" "smoke.nvdb"\n'
                 'Texture "t" "spectrum" "imagemap" "string filename" "a.png"\n'
                 'Material "conductor"\nShape "sphere" "float radius" 2 "float gamma" 0 "float beta" 1\n'
                 'MediumInterface "smoke" ""\nMaterial "interface"\nShape "sphere"\n')
    assert main(["describe", str(p)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err[0] == f"error: {p}: 8 problems, one a line with its fix"
    wanted = [':2: Camera "perspective": "lensradius" > 0', ':3: Film "rgb": sensor "canon_eos_100d"',
              ':5: AreaLightSource "diffuse": "string filename" (an image on the emitter) is not read', ':7: MakeNamedMedium "smoke": medium type "nanovdb"',
              ":8: Texture (textures) is not read", ':9: Material "conductor" is not read',
              ':10: Shape "sphere": parameter "float gamma" is not read', ':10: Shape "sphere": parameter "float beta"']
    assert len(err) == 1 + len(wanted)
    for line, part in zip(err[1:], wanted):
        assert line.startswith(f"  {p}:") and part in line and "; " in line, (line, part)


def test_at_most_20_problems_are_listed(tmp_path):
    p = tmp_path / "many.pbrt"
    p.write_text('LookAt 0 0 5 0 0 0 0 1 0\nCamera "perspective"\nWorldBegin\n' + 'Shape "cone"\n' * 25)
    with pytest.raises(UserError) as err:
        pbrt.read_scene(p)
    lines = str(err.value).splitlines()
    assert lines[0] == f"{p}: 25 problems, one a line with its fix (the first 20 shown)" and len(lines) == 21


def test_a_fatal_problem_comes_first(tmp_path):
    """Reading stops at malformed input; what was found before it is listed after it."""
    p = tmp_path / "bad.pbrt"
    p.write_text(BASE + 'Shape "cylinder"\nInclude "missing.pbrt"\nShape "cone"\n')
    with pytest.raises(UserError) as err:
        pbrt.read_scene(p)
    lines = str(err.value).splitlines()
    assert "2 problems" in lines[0] and "reading stopped at the first" in lines[0]
    assert 'included file' in lines[1] and 'Shape "cylinder" is not read' in lines[2] and len(lines) == 3


def test_shape_alpha(tmp_path):
    """scene.cpp getAlphaTexture: "float alpha" 1 is opaque (read), 0 lets every ray through (the shape
    is left out, with a note), in between a stochastic alpha test (refused)."""
    base = 'Shape "sphere" "float alpha" {}\nShape "sphere" "float radius" 2\n'
    assert len(pbrt.read_scene(houdini(tmp_path, world=base.format(1)))["shape"]) == 2
    with pytest.warns(pbrt.PbrtNote, match=r'"float alpha" 0: invisible to every ray in pbrt; left out'):
        shapes = pbrt.read_scene(houdini(tmp_path, world=base.format(0)))["shape"]
    assert [s["radius"] for s in shapes] == [2.0]
    with pytest.raises(UserError, match=r'"float alpha" 0.5 \(a partly transparent surface\) is not read'):
        pbrt.read_scene(houdini(tmp_path, world=base.format(0.5)))
