"""Real scene files of other tools (tests/data/corpus/, sources and licences in tests/data/SOURCES.md):
each imports and renders as its format means it, or is refused naming the features that are not read;
none gives a traceback.

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
from raytrace.api import scene_dict
from raytrace.cli import main
from raytrace.errors import UserError
from raytrace.film import read_exr

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

AREA_PBRT = "AreaLightSource (area lights) is not read"
AREA_XML = "area emitters are not read"
ENVMAP = "envmap emitters are not read"
CHECKER = "textured reflectance"
# file -> what its refusal names, in order (a fatal problem first, then by file and line; the first line counts them)
REFUSES = {
    "houdini-pbrt-v4/TestCamera/test_camera_ortho.pbrt": ['Camera "orthographic" is not read'],
    "houdini-pbrt-v4/TestCamera/test_camera_persp_crop.pbrt": [
        '"float cropwindow" is not read', "the window's aspect 1.33333 differs from the film's 1280/720"],
    "houdini-pbrt-v4/TestCamera/test_camera_persp_dof.pbrt": ['"lensradius" > 0 (depth of field)'],
    "houdini-pbrt-v4/TestCamera/test_camera_spherical.pbrt": ['only "string mapping" "equirectangular" is read'],
    "houdini-pbrt-v4/TestLights/test_spherelight.pbrt": [AREA_PBRT],
    "houdini-pbrt-v4/TestMediums/test_exterior_cam.pbrt": [AREA_PBRT],
    "houdini-pbrt-v4/TestMediums/test_exterior_cam_interior_obj.pbrt": [AREA_PBRT],
    "houdini-pbrt-v4/TestMediums/test_interior_homogeneous.pbrt": [AREA_PBRT],
    "houdini-pbrt-v4/TestMediums/test_interior_cloud.pbrt": [AREA_PBRT, 'medium type "cloud" is not read'],
    "houdini-pbrt-v4/TestMediums/test_interior_nanovdb.pbrt": [AREA_PBRT, 'medium type "nanovdb" is not read'],
    "pbrt-v4-scenes/killeroo-simple.pbrt": ['included file "', AREA_PBRT, 'Material "coateddiffuse" is not read'],
    "mitsuba-data/scenes/cbox/cbox.xml": ["a spectrum sampled at wavelengths is not read"] * 5 + [AREA_XML],
    "mitsuba-data/scenes/cbox/cbox-rgb.xml": [AREA_XML],
    "mitsuba-tutorials/cbox.xml": ["conductor bsdfs are not read", AREA_XML],
    MEDIA + "test_hetero_sigmat_albedo_volpath.xml": [CHECKER, ENVMAP, "only homogeneous media", "sphere_base.obj"],
    MEDIA + "test_hetero_sigmat_volpath.xml": [CHECKER, ENVMAP, "only homogeneous media", "sphere_base.obj"],
    MEDIA + "test_hetero_spectral_sigmat_no_scattering_volpath.xml": [CHECKER, ENVMAP, "only homogeneous media",
                                                                      "sphere_base.obj"],
    MEDIA + "test_hetero_spectral_sigmat_volpathmis.xml": [CHECKER, ENVMAP, "only homogeneous media", "sphere_base.obj"],
    MEDIA + "test_homo_area_light_volpath.xml": [CHECKER, "sphere_tiny.obj", "thindielectric", AREA_XML],
    MEDIA + "test_homo_dielectric_envmap_volpath.xml": [ENVMAP, "sphere_tiny.obj", "sphere_base.obj"],
    MEDIA + "test_homo_emitter_inside_medium_volpath.xml": [CHECKER, ENVMAP, "thindielectric", "thindielectric",
                                                            "torus1.obj", AREA_XML, "roughplastic"],
    MEDIA + "test_homo_null_envmap_volpath.xml": [CHECKER, ENVMAP, "sphere_tiny.obj", "sphere_base.obj"],
    MEDIA + "test_homo_obj_inside_medium_volpath.xml": [CHECKER, ENVMAP, "thindielectric", "thindielectric",
                                                        "roughplastic", "torus2.obj"],
    MEDIA + "test_homo_roughdielectric_spot_volpath.xml": ["roughdielectric bsdfs"] * 2,
    MEDIA + "test_homo_spectral_sigmat_volpathmis.xml": [CHECKER, ENVMAP, "sphere_tiny.obj", "sphere_base.obj"],
    MEDIA + "test_surf_area_light_volpath.xml": [CHECKER, ENVMAP, "plastic bsdfs", "roughplastic", AREA_XML],
}


def scene_files():
    return sorted(str(p.relative_to(CORPUS)) for p in CORPUS.rglob("*") if io.importer(p) and p.is_file()
                  and p.parent.name not in ("include", "fragments"))


def test_every_file_has_an_expected_outcome_and_fits_the_budget():
    assert sorted(RENDERS) + sorted(REFUSES) and set(scene_files()) == set(RENDERS) | set(REFUSES)
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
