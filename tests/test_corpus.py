"""Real scene files of other tools (tests/data/corpus/, sources and licences in tests/data/SOURCES.md):
each imports and renders as its format means it, or is refused naming the features that are not read;
none gives a traceback. Their area lights, emitting shapes and environments import to the dicts worked
out by hand from the files (the renderer takes those light kinds once the lights issue's `area` work is
in: until then such files are refused naming the kind, and their renders are checked after it).

The expected outcomes are read off the files and the formats' sources (Khronos' glTF 2.0 specification,
mitsuba3's parser and plugins, pbrt-v4's cameras.cpp and scene.cpp), not from the importers: a camera's
field of view from its `yfov` or pbrt's screen window, the features named from the elements the file
holds. Meshes over the corpus's size budget are left out of it (see SOURCES.md): their files are refused
naming the missing mesh besides their real limits.
"""
from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from raytrace import io
from raytrace.api import render, scene_dict
from raytrace.cli import main
from raytrace.errors import UserError
from raytrace.output.film import read_exr

CORPUS = Path(__file__).resolve().parent / "data" / "corpus"
HOUDINI_FOV = math.degrees(2.0 * math.atan(0.75 * math.tan(math.radians(22.5))))  # fov 45 across [-1 1 -0.75 0.75]
NO_LIGHTS = "the scene has no lights; it renders black"
MEDIA = "mitsuba-data/tests/scenes/participating_media/"

# file -> (camera's vertical fov in degrees, lit: the image is not black, the notes expected)
RENDERS = {
    "gltf-sample-assets/Cameras.gltf": (math.degrees(0.7), False, [NO_LIGHTS]),
    "gltf-sample-assets/SimpleMeshes.gltf": (45.0, False, ["no perspective camera: a default one", NO_LIGHTS]),
    "houdini-pbrt-v4/TestLights/test_pointlight.pbrt": (HOUDINI_FOV, True, ["orthonormal to 0.00012"]),
    "houdini-pbrt-v4/TestLights/test_spotlight.pbrt": (HOUDINI_FOV, True, ["orthonormal to 0.00012"]),
    "houdini-pbrt-v4/TestLights/test_distantlight.pbrt": (HOUDINI_FOV, True, ["orthonormal to 0.00012"]),
    "houdini-pbrt-v4/TestLights/test_sunlight.pbrt": (HOUDINI_FOV, False, [NO_LIGHTS]),  # "sun, not supported"
}

ENVMAP = "envmap file 'textures/museum.exr' not found"  # (left out of the corpus: not in the repository)
CHECKER = "textured reflectance"
ALPHA0 = '"float alpha" 0 with an area light: pbrt-v4 makes it an invisible light'
HOUDINI_NOTES = ["orthonormal to 0.00012", ALPHA0]
GOLD = "pbrt-v4-scenes/killeroo-gold.pbrt"
SPHERE_LIGHT = "mitsuba-data/docs/scenes/shape_sphere_light_analytic.xml"
# file -> what its refusal names, in order (a fatal problem first, then by file and line; the first line counts them)
REFUSES = {
    "houdini-pbrt-v4/TestCamera/test_camera_ortho.pbrt": ['Camera "orthographic" is not read'],
    "houdini-pbrt-v4/TestCamera/test_camera_persp_crop.pbrt": [
        '"float cropwindow" is not read', "the window's aspect 1.33333 differs from the film's 1280/720"],
    "houdini-pbrt-v4/TestCamera/test_camera_persp_dof.pbrt": ['"lensradius" > 0 (depth of field)'],
    "houdini-pbrt-v4/TestCamera/test_camera_spherical.pbrt": ['only "string mapping" "equirectangular" is read'],
    "houdini-pbrt-v4/TestMediums/test_interior_cloud.pbrt": ['medium type "cloud" is not read'],
    "houdini-pbrt-v4/TestMediums/test_interior_nanovdb.pbrt": ['medium type "nanovdb" is not read'],
    "pbrt-v4-scenes/killeroo-simple.pbrt": ['included file "'],
    GOLD: ['included file "', "Texture (textures) is not read", "Texture (textures) is not read",
           '"texture reflectance" is type texture', 'Material "conductor" is not read'],
    "mitsuba-tutorials/cbox.xml": ["conductor bsdfs are not read"],
    MEDIA + "test_hetero_sigmat_albedo_volpath.xml": [CHECKER, ENVMAP, "only homogeneous media", "sphere_base.obj"],
    MEDIA + "test_hetero_sigmat_volpath.xml": [CHECKER, ENVMAP, "only homogeneous media", "sphere_base.obj"],
    MEDIA + "test_hetero_spectral_sigmat_no_scattering_volpath.xml": [CHECKER, ENVMAP, "only homogeneous media",
                                                                      "sphere_base.obj"],
    MEDIA + "test_hetero_spectral_sigmat_volpathmis.xml": [CHECKER, ENVMAP, "only homogeneous media", "sphere_base.obj"],
    MEDIA + "test_homo_area_light_volpath.xml": [CHECKER, "sphere_tiny.obj", "thindielectric"],
    MEDIA + "test_homo_dielectric_envmap_volpath.xml": [ENVMAP, "sphere_tiny.obj", "sphere_base.obj"],
    MEDIA + "test_homo_emitter_inside_medium_volpath.xml": [CHECKER, ENVMAP, "thindielectric", "thindielectric",
                                                            "torus1.obj", "torus2.obj"],
    MEDIA + "test_homo_null_envmap_volpath.xml": [CHECKER, ENVMAP, "sphere_tiny.obj", "sphere_base.obj"],
    MEDIA + "test_homo_obj_inside_medium_volpath.xml": [CHECKER, ENVMAP, "thindielectric", "thindielectric",
                                                        "torus1.obj", "torus2.obj"],
    MEDIA + "test_homo_roughdielectric_spot_volpath.xml": ["roughdielectric bsdfs"] * 2,
    MEDIA + "test_homo_spectral_sigmat_volpathmis.xml": [CHECKER, ENVMAP, "sphere_tiny.obj", "sphere_base.obj"],
    MEDIA + "test_surf_area_light_volpath.xml": [CHECKER, ENVMAP, "sphere_tiny.obj", "sphere_base.obj"],
}
# read whole, with lights of the kinds the lights issue adds: file -> (camera's vertical fov, the notes expected)
AREA_LIGHTS = {
    "houdini-pbrt-v4/TestLights/test_spherelight.pbrt": (HOUDINI_FOV, HOUDINI_NOTES),
    "houdini-pbrt-v4/TestMediums/test_exterior_cam.pbrt": (HOUDINI_FOV, HOUDINI_NOTES),
    "houdini-pbrt-v4/TestMediums/test_exterior_cam_interior_obj.pbrt": (HOUDINI_FOV, HOUDINI_NOTES),
    "houdini-pbrt-v4/TestMediums/test_interior_homogeneous.pbrt": (HOUDINI_FOV, HOUDINI_NOTES),
    "mitsuba-data/scenes/cbox/cbox-rgb.xml": (39.3077, []),
    "mitsuba-data/scenes/cbox/cbox.xml": (39.3077, []),  # its spectra as Mitsuba's RGB variants read them
    "houdini-pbrt-v4/TestShapes/test_loopsubdiv.pbrt": (HOUDINI_FOV, ["orthonormal to 0.00012"]),
    "houdini-pbrt-v4/TestShapes/test_loopsubdiv_levels.pbrt": (HOUDINI_FOV, ["orthonormal to 0.00012"]),
    SPHERE_LIGHT: (26.0, ["roughplastic read as diffuse of its diffuse_reflectance"]),
}


def scene_files():
    return sorted(str(p.relative_to(CORPUS)) for p in CORPUS.rglob("*") if io.importer(p) and p.is_file()
                  and p.parent.name not in ("include", "fragments"))


def test_every_file_has_an_expected_outcome_and_fits_the_budget():
    assert sorted(RENDERS) + sorted(REFUSES) and set(scene_files()) == set(RENDERS) | set(REFUSES) | set(AREA_LIGHTS)
    assert all(p.stat().st_size < 2 ** 20 for p in CORPUS.rglob("*") if p.is_file())


@pytest.mark.parametrize("name", sorted(RENDERS))
def test_renders(name, tmp_path):
    """Imports with the notes expected, its camera as the file means it, and renders at 16 x 12
    (raymarch, 4 steps): finite, and lit where the file has lights the importer reads."""
    path = CORPUS / name
    fov, lit, notes = RENDERS[name]
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        raw = scene_dict(path)[0]  # the no-lights warning comes after the overrides (none here)
    text = " | ".join(str(w.message) for w in said)
    for note in notes:
        assert note in text, text
    assert (NO_LIGHTS in text) == (not lit)
    assert raw["camera"]["fov"] == pytest.approx(fov, rel=1e-12)
    out = tmp_path / "x.exr"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["render", str(path), "--method", "raymarch", "--steps", "4", "--width", "16", "--height", "12",
                     "--spp", "1", "--out", str(out), "--quiet"]) == 0
    image = read_exr(out)[0]
    assert np.all(np.isfinite(image)) and (np.max(image) > 0.0) == lit


@pytest.mark.parametrize("name", sorted(REFUSES))
def test_refuses_naming_its_features(name, capsys):
    """Exit status 2, no traceback, and every feature named, one line each, after a line counting them."""
    path = CORPUS / name
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["describe", str(path)]) == 2
    err = capsys.readouterr().err.splitlines()
    wanted = REFUSES[name]
    if len(wanted) > 1:
        assert err[0].startswith(f"error: {path}: {len(wanted)} problems, one a line with its fix"), err[0]
        err = err[1:]
    assert len(err) == len(wanted), err
    for line, part in zip(err, wanted):
        assert part in line and "; " in line, (line, part)
    with pytest.raises(UserError):
        io.read_scene(path)


@pytest.mark.parametrize("name", sorted(AREA_LIGHTS))
def test_area_lights_render_once_the_renderer_takes_them(name, tmp_path):
    """Imported whole with the notes expected and rendered, lit (two Houdini files light a shape's
    medium with a sphere light)."""
    path = CORPUS / name
    fov, notes = AREA_LIGHTS[name]
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        raw = scene_dict(path)[0]
    text = " | ".join(str(w.message) for w in said)
    assert all(note in text for note in notes) and NO_LIGHTS not in text, text
    assert raw["camera"]["fov"] == pytest.approx(fov, rel=1e-5)
    out = tmp_path / "x.exr"
    args = ["render", str(path), "--method", "raymarch", "--steps", "4", "--width", "16", "--height", "12", "--spp", "1",
            "--out", str(out), "--quiet"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        status = main(args)
    image = read_exr(out)[0]
    assert status == 0 and np.all(np.isfinite(image)) and np.max(image) > 0.0


def stripped(name, tmp_path, cut: str, drop=()) -> Path:
    """A copy of corpus file `name` ending before `cut`, without the `drop` texts (what the importer
    refuses), in a folder tree like the corpus's (for `<path>` and includes)."""
    text = (CORPUS / name).read_text()
    text = text[:text.index(cut)] if cut else text
    for part in drop:
        assert part in text
        text = text.replace(part, "")
    copy = tmp_path / name
    copy.parent.mkdir(parents=True, exist_ok=True)
    (tmp_path / "mitsuba-data" / "common").mkdir(parents=True, exist_ok=True)
    copy.write_text(text + ("</scene>\n" if name.endswith(".xml") and cut else ""))
    return copy


def test_emitters_read_as_the_files_mean(tmp_path):
    """The emitters of the corpus, worked out by hand from each file (the files' refused parts cut away:
    `stripped`). pbrt files whose camera is a plain LookAt are read with world x negated (pbrt.py)."""
    def light(path):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return io.read_scene(path)["light"]

    # Houdini: Translate 0 1.5 0, Rotate -90 1 0 0, "rgb L" [0.5 0.75 1] x "float scale" 5; twosided (a sphere
    # seen from outside: the same); the sphere at the origin of that frame, radius 0.5
    assert light(CORPUS / "houdini-pbrt-v4/TestLights/test_spherelight.pbrt") == [
        {"type": "sphere", "center": [0.0, 1.5, 0.0], "radius": 0.5, "radiance": [2.5, 3.75, 5.0]}]
    # Translate 0 10 0; L the illuminant's white (1) x scale 10; radius 1
    for name in ("test_exterior_cam", "test_exterior_cam_interior_obj", "test_interior_homogeneous"):
        assert light(CORPUS / f"houdini-pbrt-v4/TestMediums/{name}.pbrt") == [
            {"type": "sphere", "center": [0.0, 10.0, 0.0], "radius": 1.0, "radiance": [10.0, 10.0, 10.0]}]
    # killeroo-simple: Translate 150 0 20, Translate 0 120 0, "rgb L" [2000 2000 2000], radius 3; mirrored x
    simple = stripped("pbrt-v4-scenes/killeroo-simple.pbrt", tmp_path, "AttributeBegin\n    Scale 0.5")
    assert light(simple) == [{"type": "sphere", "center": [-150.0, 120.0, 20.0], "radius": 3.0,
                              "radiance": [2000.0] * 3}]
    # killeroo-gold: a disk of radius 150 at z = 800 under ReverseOrientation: its +z turned to -z, L 50
    gold = stripped(GOLD, tmp_path, "AttributeBegin\n    Material \"diffuse\"\n        \"rgb reflectance\" [ 0.5")
    area, distant = light(gold)
    assert area == {"type": "disk", "center": [0.0, 0.0, 800.0], "normal": [0.0, 0.0, -1.0], "radius": 150.0,
                    "radiance": [50.0] * 3}
    assert distant["type"] == "directional"
    # Mitsuba's docs scene: a constant 0.1 and a unit sphere emitting 20, translated up 1 (its roughplastic cut);
    # their one-number spectra are flat spectra of emission, which Mitsuba 3.9.1's scalar_rgb reads as
    # v (1.20479, 0.948291, 0.908916) (test_mitsuba_spectra's stored readings; ours within its REL)
    sphere = stripped(SPHERE_LIGHT, tmp_path, "", drop=[
        '<bsdf type="roughplastic">\n            <rgb name="diffuse_reflectance" value="0.05, 0.05, 0.1"/>\n'
        '            <float name="alpha" value="0.1"/>\n        </bsdf>\n'])
    env, ball = light(sphere)
    white = np.array([1.20479, 0.948291, 0.908916])
    assert env.pop("radiance") == pytest.approx(0.1 * white, rel=4e-4) and env == {"type": "environment"}
    assert ball.pop("radiance") == pytest.approx(20.0 * white, rel=4e-4)
    assert ball == {"type": "sphere", "center": [0.0, 1.0, 0.0], "radius": 1.0}
    # the Cornell box: the luminaire mesh (343 548.8 227 ... 213 548.8 227) moved down 0.5, one-sided downward
    raw = io.read_scene(CORPUS / "mitsuba-data/scenes/cbox/cbox-rgb.xml")
    (lamp,) = [s for s in raw["shape"] if "emission" in s]
    assert lamp["emission"] == [18.387, 10.9873, 2.75357] and "two_sided" not in lamp
    assert sorted(map(tuple, lamp["vertices"])) == [(213.0, 548.3, 227.0), (213.0, 548.3, 332.0),
                                                     (343.0, 548.3, 227.0), (343.0, 548.3, 332.0)]
    t = np.asarray(lamp["vertices"])[np.asarray(lamp["faces"])]
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    assert np.all(n[:, 1] < 0) and np.allclose(n[:, [0, 2]], 0.0)
    assert np.allclose(lamp["normals"], [0.0, -1.0, 0.0])  # Mitsuba's recomputed normals of a flat quad


STAND_IN = """Shape "loopsubdiv" "integer levels" [ 1 ]
    "point3 P" [ 0 0 60  50 0 -20  -25 43 -20  -25 -43 -20 ]
    "integer indices" [ 0 1 2  0 2 3  0 3 1  1 3 2 ]
"""


def test_killeroo_simple_reads_whole_with_a_stand_in_model(tmp_path):
    """pbrt-v4-scenes' killeroo-simple with a stand-in for its left-out model (a tetrahedron's Loop
    subdivision in `geometry/killeroo.pbrt`): the file reads whole; its two `coateddiffuse` materials
    become diffuse surfaces of their reflectances (0.4 0.2 0.2 and 0.4 0.5 0.4), each said in a note
    naming its line; the floor and wall keep their 0.5 0.5 0.8; the sphere light renders them."""
    copy = tmp_path / "pbrt-v4-scenes" / "killeroo-simple.pbrt"
    (copy.parent / "geometry").mkdir(parents=True)
    copy.write_text((CORPUS / "pbrt-v4-scenes/killeroo-simple.pbrt").read_text())
    (copy.parent / "geometry" / "killeroo.pbrt").write_text(STAND_IN)
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        raw = io.read_scene(copy)
    notes = [str(w.message) for w in said if '"coateddiffuse" read as "diffuse"' in str(w.message)]
    assert [n.split(":")[1] for n in notes] == ["51", "56"], notes
    assert sorted({tuple(s["reflectance"]) for s in raw["shape"]}) == [(0.4, 0.2, 0.2), (0.4, 0.5, 0.4),
                                                                        (0.5, 0.5, 0.8)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        img = render(copy, "analytic", width=16, height=16, spp=1)
    assert np.all(np.isfinite(img.array)) and np.count_nonzero(img.array.max(axis=-1) > 0.0) > 100


def test_an_environment_lit_file_renders_as_its_author_lit_it(tmp_path):
    """Mitsuba's docs scene (its roughplastic cut): a constant environment of 0.1 and a sphere emitting 20 (flat
    spectra: 0.1 and 20 times Mitsuba's equal-energy white, test_emitters_read_as_the_files_mean) over a diffuse ground
    (Mitsuba's default reflectance 0.5) filling the view, in vacuum: finite; the environment's layer lights every
    pixel, at most the unoccluded rho L = 0.05 white (the directions' cos theta are the midpoint rule in cos theta,
    exact for a horizontal surface's cosine: to rounding); what the camera sees emitted is the sphere's radiance
    exactly."""
    path = stripped(SPHERE_LIGHT, tmp_path, "", drop=[
        '<bsdf type="roughplastic">\n            <rgb name="diffuse_reflectance" value="0.05, 0.05, 0.1"/>\n'
        '            <float name="alpha" value="0.1"/>\n        </bsdf>\n'])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        img = render(path, "quadrature", width=16, height=12, spp=1, aov=["lights"])
    assert list(img.layers) == ["light0", "light1", "emission"] and np.all(np.isfinite(img.array))
    env, seen = img.layers["light0"], img.layers["emission"]
    sky, ball = (np.array(light["radiance"]) for light in io.read_scene(path)["light"])
    assert np.all(env[seen == 0.0] > 0.0) and np.all(env <= 0.5 * sky * (1 + 1e-12))
    for c in range(3):
        assert set(np.unique(seen[..., c])) == {0.0, ball[c]}
