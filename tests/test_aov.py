"""Output layers (rendering/aov.py): depth, normal and albedo of the camera rays' first hits against a pinhole
twin built from SCENE_FORMAT.md's camera convention (numpy only); the light layers and emission sum
to the image, and each light's layer is the render of the scene with that light alone, minus its
emission; the image itself is unchanged by asking for layers; the EXR channels, `diff --layer` and
the refusals."""
import copy
import math
import subprocess
import sys

import numpy as np
import OpenEXR
import pytest

import raytrace
from raytrace.errors import UserError

from .conftest import to_toml

FOG = {"sigma_a": 0.02, "sigma_s": 0.08, "phase": {"type": "hg", "g": 0.4}}
POINT = {"position": [0.2, 2.3, 0.4], "intensity": [6.0, 5.0, 4.0]}
SPOT = {"type": "spot", "position": [-1.5, 1.5, 1.0], "look_at": [0.0, 0.5, 0.0], "intensity": 20.0,
        "cone_angle": 35.0, "falloff_start": 20.0}
SUN = {"type": "directional", "direction": [0.3, -1.0, 0.2], "irradiance": [3.0, 3.0, 3.0]}
FLOOR = {"primitive": "quad", "corners": [[-4, 0, -4], [4, 0, -4], [4, 0, 4], [-4, 0, 4]], "reflectance": 0.5}
PLATE = {"primitive": "quad", "corners": [[-0.3, 1.6, -0.3], [0.3, 1.6, -0.3], [0.3, 1.6, 0.3], [-0.3, 1.6, 0.3]],
         "reflectance": 0.3}


def box(ior):
    return {"primitive": "box", "min": [-0.5, 0.01, -0.5], "max": [0.5, 1.0, 0.5],
            "interior": {"sigma_a": [0.3, 0.1, 0.05], "sigma_s": [0.6, 0.5, 0.4], "phase": {"type": "hg", "g": 0.3},
                         "ior": ior}}


def room(shapes, lights, medium=FOG):
    return {"camera": {"position": [0.3, 1.4, 3.2], "look_at": [0.0, 0.6, 0.0], "width": 14, "height": 10, "spp": 2,
                       "fov": 55},
            "shape": [FLOOR, PLATE] + shapes, "light": lights, "medium": medium, "background": {"radiance": [0.1, 0.2, 0.3]}}


CASES = {  # an index-matched box of fog lit through and shadowed, a refracting one, a spot, the sun in vacuum
    "matched, montecarlo": (room([box(1.0)], [POINT, SPOT]), "montecarlo"),
    "refractive, quadrature": (room([box(1.5)], [POINT, SPOT]), "quadrature"),
    "spot, raymarch": (room([box(1.0)], [SPOT, POINT]), "raymarch"),
    "sun in vacuum, analytic": (room([box(1.33)], [SUN, {**SUN, "direction": [-0.3, -1.0, 0.1]}],
                                     {"sigma_a": 0.0, "sigma_s": 0.0}), "analytic"),
}


@pytest.mark.parametrize("case", CASES)
def test_light_layers_and_emission_sum_to_the_unchanged_image(case):
    scene, method = CASES[case]
    plain = raytrace.render(copy.deepcopy(scene), method, threads=2)
    img = raytrace.render(copy.deepcopy(scene), method, threads=2, aov=["lights"])
    assert list(img.layers) == ["light0", "light1", "emission"]
    assert np.array_equal(img.array, plain.array)  # asking for layers changes no pixel
    total = img.layers["light0"] + img.layers["light1"] + img.layers["emission"]
    assert np.all(np.abs(total - img.array) <= 1e-12 * np.abs(img.array))
    for name in ("light0", "light1"):  # each light adds something of its own
        assert np.count_nonzero(img.layers[name]) > img.array.size // 4


def test_a_light_layer_is_the_scene_with_that_light_alone():
    scene = room([box(1.0)], [POINT, SPOT])
    img = raytrace.render(copy.deepcopy(scene), "quadrature", aov=["lights"])
    for i, light in enumerate(scene["light"]):
        alone = raytrace.render({**copy.deepcopy(scene), "light": [light]}, "quadrature")
        layer = img.layers[f"light{i}"] + img.layers["emission"]
        assert np.all(np.abs(layer - alone.array) <= 1e-12 * np.abs(alone.array))
    dark = raytrace.render({**copy.deepcopy(scene), "light": []}, "quadrature")
    assert np.array_equal(img.layers["emission"], dark.array)


def _pinhole(camera, width, height):
    """Unit directions (H, W, 3) of the pixel centres (SCENE_FORMAT.md's convention, spp = 1)."""
    eye, at = np.array(camera["position"], float), np.array(camera["look_at"], float)
    forward = (at - eye) / np.linalg.norm(at - eye)
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    k = math.tan(math.radians(camera["fov"]) / 2.0)
    i, j = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    d = (forward + ((2 * i / width - 1) * k * width / height)[..., None] * right
         + ((1 - 2 * j / height) * k)[..., None] * up)
    return eye, d / np.linalg.norm(d, axis=-1, keepdims=True)


def test_first_hit_layers_against_a_pinhole_twin():
    """A tilted wall z = -x tan(a) - 2 (reflectance per channel) and, in front of it, a sphere of
    radius 0.5 at (0.6, 0.3, -0.8) holding a medium (albedo 0: it reflects nothing), seen from the
    origin; misses have depth inf and zero normal and albedo."""
    a = math.radians(20.0)
    camera = {"position": [0.0, 0.0, 0.0], "look_at": [0.0, 0.0, -1.0], "fov": 60.0, "width": 24, "height": 18,
              "spp": 1}
    half = 1.2
    wall = [[x, y, -x * math.tan(a) - 2.0] for x, y in ((-half, -half), (half, -half), (half, half), (-half, half))]
    centre, radius = np.array([0.6, 0.3, -0.8]), 0.5
    scene = {"camera": camera, "light": [POINT],
             "shape": [{"primitive": "quad", "corners": wall, "reflectance": [0.2, 0.4, 0.6]},
                       {"primitive": "sphere", "center": centre.tolist(), "radius": radius, "segments": 256,
                        "interior": {"sigma_a": 0.1, "sigma_s": 0.1}}]}
    img = raytrace.render(scene, "quadrature", aov=["albedo", "depth", "normal"])
    assert list(img.layers) == ["depth", "normal", "albedo"]
    eye, d = _pinhole(camera, 24, 18)
    n = np.array([math.sin(a), 0.0, math.cos(a)])  # the wall's normal, toward the camera
    t_wall = -2.0 * math.cos(a) / (d @ n)  # n . (eye + t d) = n . (0, 0, -2) with eye = 0
    p = eye + t_wall[..., None] * d
    on_wall = (np.abs(p[..., 0]) < half) & (np.abs(p[..., 1]) < half)
    b = d @ (eye - centre)
    disc = b * b - (np.sum((eye - centre) ** 2) - radius**2)
    t_sphere = np.where(disc > 0.0, -b - np.sqrt(np.maximum(disc, 0.0)), np.inf)
    depth = np.where(t_sphere < np.inf, t_sphere, np.where(on_wall, t_wall, np.inf))
    rim = (disc > 0.0) & (disc < 0.02 * radius**2)  # the mesh of 256 segments differs from the sphere there
    edge = on_wall & ((np.abs(p[..., 0]) > half - 0.05) | (np.abs(p[..., 1]) > half - 0.05))  # pixel centres at
    exact = ~rim & ~edge  # the wall's edge may fall on either side in float32
    got = img.layers["depth"][..., 0]
    assert np.all(np.isinf(got[exact]) == np.isinf(depth[exact]))
    finite = exact & np.isfinite(depth)
    wall_only = finite & np.isinf(t_sphere)
    ball = finite & np.isfinite(t_sphere)
    assert np.allclose(got[wall_only], depth[wall_only], rtol=1e-6)
    sphere_n = (eye + t_sphere[..., None] * d - centre) / radius  # smooth shading: the sphere's own normal
    sagitta = radius * (1.0 - math.cos(math.sqrt(2.0) * math.pi / 256))  # how far inside a facet's corners reach
    cos = np.abs(np.einsum("ijk,ijk->ij", d, sphere_n))
    assert np.all(np.abs(got[ball] - depth[ball]) <= sagitta / cos[ball])
    assert np.allclose(img.layers["normal"][wall_only], n, atol=1e-6)
    assert np.allclose(img.layers["normal"][ball], sphere_n[ball], atol=2e-3)
    assert np.allclose(img.layers["albedo"][wall_only], [0.2, 0.4, 0.6])
    assert np.all(img.layers["albedo"][ball] == 0.0)
    miss = exact & np.isinf(depth)
    assert miss.any() and wall_only.any() and ball.any()
    assert np.all(img.layers["normal"][miss] == 0.0) and np.all(img.layers["albedo"][miss] == 0.0)


def test_layers_in_the_exr_and_diff_reads_them(tmp_path):
    scene = room([box(1.0)], [POINT, SPOT])
    img = raytrace.render(copy.deepcopy(scene), "quadrature", aov=["depth", "normal", "albedo", "lights"])
    path = tmp_path / "a.exr"
    img.save(path)
    with OpenEXR.File(str(path), separate_channels=True) as f:
        channels = f.channels()
        for name in ("depth.Z", "normal.X", "normal.Y", "normal.Z", "albedo.R", "light0.R", "light1.B", "emission.G"):
            assert name in channels
        assert np.array_equal(channels["light1.G"].pixels, img.layers["light1"][..., 1].astype(np.float32))
    assert np.array_equal(img.layer("depth").array[..., 2], img.layers["depth"][..., 0])
    with pytest.raises(UserError, match="no layer|not in this render"):
        img.layer("light7")
    other = tmp_path / "b.exr"
    raytrace.render(copy.deepcopy(scene), "raymarch", aov=["lights"]).save(other)
    run = [sys.executable, "render.py", "diff", str(path), str(other)]
    out = subprocess.run(run + ["--layer", "light1"], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    missing = subprocess.run(run + ["--layer", "depth"], capture_output=True, text=True)
    assert missing.returncode == 2 and "no layer 'depth'" in missing.stderr and len(missing.stderr.splitlines()) == 1


def test_bad_layers_are_refused_in_one_line(tmp_path):
    scene = room([], [POINT])
    with pytest.raises(UserError, match=r"render.aov: unknown layer 'shadow'; choose from depth, normal"):
        raytrace.render({**scene, "render": {"aov": ["shadow"]}}, "quadrature")
    with pytest.raises(UserError, match="not kept across progressive passes"):
        raytrace.render(copy.deepcopy(scene), "montecarlo", aov="lights", passes=2)
    path = tmp_path / "s.toml"
    path.write_text(to_toml(scene))
    out = tmp_path / "o.exr"
    cli = subprocess.run([sys.executable, "render.py", "render", str(path), "--aov", "depth,speed", "--out", str(out)],
                         capture_output=True, text=True)
    assert cli.returncode == 2 and "--aov" in cli.stderr and "'speed'" in cli.stderr
    assert len(cli.stderr.strip().splitlines()) == 1 and not out.exists()


def test_area_lights_and_emitters_seen_directly():
    """A quad light facing the camera over a floor, a disk lamp and an emissive box, in fog and in
    vacuum: one layer per scene light (an area light's emitter points together, the emissive shape
    last), the emitters' own radiance in `emission`, the layers summing to the image."""
    quad = {"type": "quad", "corners": [[-0.5, 0.6, -1.0], [0.5, 0.6, -1.0], [0.5, 1.4, -1.0], [-0.5, 1.4, -1.0]],
            "radiance": [2.0, 3.0, 4.0]}
    disk = {"type": "disk", "center": [1.5, 2.0, 0.0], "normal": [-1.0, -1.0, 0.0], "radius": 0.2, "radiance": 5.0}
    glow = {"primitive": "box", "min": [-1.6, 0.0, -0.3], "max": [-1.2, 0.4, 0.1], "emission": [0.5, 0.2, 0.1]}
    for medium in ({"sigma_a": 0.0, "sigma_s": 0.0}, FOG):
        scene = {"camera": {"position": [0.0, 1.0, 2.0], "look_at": [0.0, 1.0, -1.0], "fov": 70.0, "width": 15,
                            "height": 11, "spp": 1},
                 "shape": [FLOOR, glow], "light": [quad, disk], "medium": medium}
        img = raytrace.render(copy.deepcopy(scene), "quadrature", aov=["lights"])
        assert list(img.layers) == ["light0", "light1", "light2", "emission"]
        total = sum(img.layers.values())
        assert np.all(np.abs(total - img.array) <= 1e-12 * np.abs(img.array))
        for name in ("light0", "light1", "light2"):
            assert np.count_nonzero(img.layers[name]) > 0
        centre = img.layers["emission"][5, 7]  # the ray through the quad's centre sees its front
        if medium is FOG:
            assert np.all(img.layers["light0"][5, 7] > 0.0) and np.all(centre < [2.0, 3.0, 4.0])
        else:
            assert np.array_equal(centre, [2.0, 3.0, 4.0]) and np.all(img.layers["light0"][5, 7] == 0.0)
