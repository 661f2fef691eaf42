"""Height fog (seed 004) and the directional sun, rendered (issue 11).

`quadrature` against an independent brute force (tests/oracle.fog_pixel: scipy quad of the single-
scattering integral, every optical depth itself a scipy quad of the density) to 1e-6 per
pixel-channel: box rooms (exponential fog with RGB coefficients and a tilted `up`, a linear fog
whose top cuts the room, point and spot lights) and a ground plane under a low sun with rays to
the sky. The homogeneous limit (huge scale height) is the homogeneous render; raymarch converges
to quadrature as O(step^2); bad input and the methods that refuse fog or the sun give one line
and exit 2.
"""
import math

import numpy as np
import pytest

import raytrace
from raytrace.cli import main
from raytrace.output.film import read_exr

from . import oracle
from .conftest import box_room

FOG = {"type": "height_fog", "sigma_a": [0.02, 0.04, 0.06], "sigma_s": [0.3, 0.2, 0.1], "h0": -1.0,
       "scale_height": 1.5, "phase": {"type": "hg", "g": 0.5}}
SPOT = {"type": "spot", "position": [0.5, 1.8, -1.0], "look_at": [0.0, -2.0, -1.5], "intensity": 30.0,
        "cone_angle": 30.0, "falloff_start": 20.0}
VALLEY = {
    "camera": {"position": [0.0, 1.0, 5.0], "look_at": [0.0, 0.7, 0.0], "fov": 60.0, "width": 6, "height": 4,
               "spp": 1},
    "shape": [{"primitive": "quad", "corners": [[-1e4, 0.0, -1e4], [1e4, 0.0, -1e4], [1e4, 0.0, 1e4],
                                               [-1e4, 0.0, 1e4]], "reflectance": [0.3, 0.35, 0.25]}],
    "light": [{"type": "directional", "direction": [0.4, -0.3, 0.85], "irradiance": [3.0, 2.6, 2.0]},
              {"position": [1.0, 1.5, -2.0], "intensity": 5.0}],
    "medium": {"type": "height_fog", "sigma_a": 0.01, "sigma_s": [0.08, 0.1, 0.12], "h0": 0.0, "scale_height": 1.2,
               "phase": {"type": "hg", "g": -0.4}},
}
CASES = {
    "exponential_hg_rgb_point_and_spot": (box_room(camera={**box_room()["camera"], "width": 6, "height": 4},
                                                   medium=FOG, light=[box_room()["light"][0], SPOT]), "box"),
    "tilted_up_rayleigh": (box_room(camera={**box_room()["camera"], "width": 5, "height": 4},
                                    medium={**FOG, "up": [0.3, 1.0, 0.2], "h0": 0.5, "scale_height": 0.7,
                                            "phase": "rayleigh"},
                                    light=[{"position": [0.25, 0.18, 0.0], "intensity": 5.0}]), "box"),
    "linear_top_in_the_room": (box_room(camera={**box_room()["camera"], "width": 5, "height": 4},
                                        medium={**FOG, "profile": "linear", "h0": -2.0, "scale_height": 3.0,
                                                "phase": "isotropic"}), "box"),
    "valley_low_sun_and_lamp": (VALLEY, "ground"),
}


def _render(scene, write_scene, tmp_path, *args):
    out = tmp_path / "img.exr"
    assert main(["render", str(write_scene(scene)), "--out", str(out), "--quiet", *args]) == 0
    return read_exr(out)[0]


@pytest.mark.parametrize("name", sorted(CASES))
def test_quadrature_matches_brute_force(name, write_scene, tmp_path):
    scene, geometry = CASES[name]
    img = _render(scene, write_scene, tmp_path, "--method", "quadrature")
    hit = oracle.box_hit(scene) if geometry == "box" else oracle.ground_hit
    cam = scene["camera"]
    ref = np.array([[oracle.fog_pixel(scene, i, j, hit) for i in range(cam["width"])] for j in range(cam["height"])])
    assert np.all(ref > 0)
    rel = np.abs(img - ref) / ref
    assert rel.max() < 1e-6, f"worst pixel {np.unravel_index(rel.argmax(), rel.shape)}: rel {rel.max():.3g}"


def test_huge_scale_height_is_the_homogeneous_medium():
    fog = box_room(medium={**FOG, "h0": 0.0, "scale_height": 1e9})
    hom = box_room(medium={"sigma_a": FOG["sigma_a"], "sigma_s": FOG["sigma_s"], "phase": FOG["phase"]})
    for method in ("quadrature", "raymarch"):
        a, b = (raytrace.render(s, method=method, threads=1).array for s in (fog, hom))
        assert np.max(np.abs(a - b) / b) < 1e-7  # the density varies by 4/1e9 across the room


def test_raymarch_converges_to_quadrature_as_step_squared():
    scene = CASES["exponential_hg_rgb_point_and_spot"][0]
    ref = raytrace.render(scene, method="quadrature", threads=1).array
    errs = [np.max(np.abs(raytrace.render(scene, method="raymarch", steps=n, threads=1).array - ref) / ref)
            for n in (256, 1024)]
    assert errs[1] < 1e-5 and errs[0] / errs[1] > 10.0, errs  # midpoint rule: 16 per 4x the steps


@pytest.mark.parametrize("name", ["exponential_hg_rgb_point_and_spot", "valley_low_sun_and_lamp"])
@pytest.mark.parametrize("sampling", ["equiangular", "freepath", "mis"])
def test_montecarlo_passes_a_z_test_against_quadrature(name, sampling):
    """Free-path draws by the inverse optical depth: the mean squared z-score of the per-pixel
    errors against the render's own variance is about 1 (test_methods' law: at most 3.5)."""
    scene = CASES[name][0]
    ref = raytrace.render(scene, method="quadrature", threads=1).array
    mc = raytrace.render(scene, method="montecarlo", samples=256, sampling=sampling, seed=7, threads=1)
    noisy = mc.variance > 0
    assert noisy.mean() > 0.5
    z2 = (mc.array - ref)[noisy] ** 2 / mc.variance[noisy]
    assert z2.mean() < 3.5, z2.mean()


def test_shadowed_quadrature_in_fog_matches_brute_force(write_scene, tmp_path):
    """A black plate under the lamp of a black room: the image is the fog's shadowed air-light, lit
    intervals integrated from their own start and attenuated by the fog from the camera."""
    from .conftest import PLATE, PLATE_LIGHT

    scene = box_room(camera={"position": [0.0, 0.0, 3.5], "look_at": [0.0, 0.0, -1.0], "fov": 80.0, "width": 6,
                             "height": 5, "spp": 1},
                     medium={**FOG, "h0": 0.0, "scale_height": 1.0},
                     light=[{"position": PLATE_LIGHT, "intensity": 20.0}])
    scene["shape"][0]["reflectance"] = 0.0
    scene["shape"].append(dict(PLATE))
    img = _render(scene, write_scene, tmp_path, "--method", "quadrature", "--volumetric-shadows")
    (x0, y0, z0), (x1, _, z1) = PLATE["corners"][0], PLATE["corners"][2]
    plate = (y0, (x0, x1), (z0, z1))
    room = oracle.box_hit(scene)

    def hit(o, d):
        t, n = room(o, d)
        return min(t, oracle.plate_hit(o, d, plate)), n

    ref = np.array([[oracle.fog_pixel(scene, i, j, hit, [plate]) for i in range(6)] for j in range(5)])
    lit = ref > 0
    assert lit.sum() >= 20 and np.all(img[~lit] == 0.0)
    rel = np.abs(img - ref)[lit] / ref[lit]
    assert rel.max() < 1e-6, rel.max()


def test_volumetric_shadows_in_fog_use_the_closed_form_in_front_of_each_segment():
    """Lit intervals start inside the ray: gather's transmittance from the camera to each
    interval must be the fog's; without an occluder the shadowed render is the unshadowed one."""
    scene = CASES["exponential_hg_rgb_point_and_spot"][0]
    a = raytrace.render(scene, method="quadrature", threads=1, volumetric_shadows=False).array
    b = raytrace.render(scene, method="quadrature", threads=1, volumetric_shadows=True).array
    assert np.max(np.abs(a - b) / a) < 1e-9


@pytest.mark.parametrize("change, message", [
    ({"scale_height": 0.0}, "medium.scale_height: must be positive"),
    ({"scale_height": -2.0}, "medium.scale_height: must be positive"),
    ({"up": [0.0, 0.0, 0.0]}, "medium.up: is zero"),
    ({"scale_hight": 2.0}, 'medium.scale_hight: unknown key; did you mean "scale_height"?'),
    ({"profile": "cubic"}, "medium.profile: 'cubic' is not one of exponential, linear"),
    ({"type": "heightfog"}, 'medium.type: \'heightfog\' is not one of homogeneous, height_fog, atmosphere; did you mean'),
    ({"particles": {}}, "medium.particles: the particle layer needs a homogeneous medium"),
])
def test_bad_fog_is_one_line_exit_2(change, message, write_scene, tmp_path, capsys):
    scene = box_room(medium={**FOG, **change})
    out = tmp_path / "x.exr"
    assert main(["render", str(write_scene(scene)), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and message in err, err
    assert not out.exists()


SUN = {"type": "directional", "direction": [0.3, -1.0, 0.2], "irradiance": 3.0}


@pytest.mark.parametrize("scene, args, message", [
    (box_room(medium=FOG), ["--method", "analytic"],
     "--method analytic: it does not take height_fog media (medium.type = \"height_fog\"); use --method quadrature, "
     "raymarch, montecarlo"),
    (box_room(medium=FOG), ["--method", "lecocq"], "--method lecocq: it does not take height_fog media"),
    (box_room(medium=FOG), ["--method", "sun"], "--method sun: it does not take height_fog media"),
    (box_room(medium=FOG), ["--method", "montecarlo", "--sampling", "cdf"],
     "method montecarlo: --sampling cdf inverts the homogeneous medium's closed-form air-light"),
    (box_room(medium={"sigma_a": 0.0, "sigma_s": 0.0}, light=[SUN]), ["--method", "analytic"],
     "--method analytic: it does not take directional lights (light.type = \"directional\"); use --method "
     "quadrature, raymarch, montecarlo"),
    (box_room(light=[SUN]), ["--method", "quadrature"],
     "light[0].type: a directional light through a homogeneous medium filling all space arrives with zero "
     "transmittance"),
    (box_room(medium=FOG), ["--method", "raymarch", "--volumetric-shadows", "--shadow-test", "samples"],
     "--shadow-test samples (render.shadow_test): not implemented in height_fog media"),
    (box_room(medium=FOG, light=[{**SUN, "direction": [0.0, 0.0, 0.0]}]), [], "light[0].direction: is zero"),
    (box_room(medium=FOG, light=[{"type": "directional", "direction": [0, -1, 0]}]), [],
     "light[0].irradiance: missing"),
    (box_room(medium=FOG, light=[{**SUN, "position": [0, 1, 0]}]), [], "light[0].position: unknown key"),
])
def test_refusals_are_one_line_exit_2(scene, args, message, write_scene, tmp_path, capsys):
    out = tmp_path / "x.exr"
    assert main(["render", str(write_scene(scene)), "--out", str(out), "--quiet", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and message in err, err
    assert not out.exists()


def test_sun_volumetric_shadows_without_occluders_change_nothing():
    """The valley's ground does not shadow the fog above it: with --volumetric-shadows the sun's
    segments stay whole (shadows/frusta.py) and the image is the unshadowed one."""
    a = raytrace.render(VALLEY, method="quadrature", threads=1, volumetric_shadows=False).array
    b = raytrace.render(VALLEY, method="quadrature", threads=1, volumetric_shadows=True)
    assert np.max(np.abs(a - b.array) / a) < 1e-9
    assert b.stats["shadows: lit intervals"] == b.stats["shadows: segments searched"] > 0  # every segment whole


def test_sun_in_vacuum_lights_surfaces_only():
    """No medium: the sun's irradiance E cos on the ground, (rho/pi) E cos exactly, no air-light."""
    scene = {**VALLEY, "medium": {"sigma_a": 0.0, "sigma_s": 0.0}, "light": VALLEY["light"][:1]}
    img = raytrace.render(scene, method="quadrature", threads=1).array
    cos = 0.3 / math.sqrt(0.4**2 + 0.3**2 + 0.85**2)
    ground = np.array([0.3, 0.35, 0.25]) / math.pi * np.array([3.0, 2.6, 2.0]) * cos
    assert np.allclose(img[-1], ground, rtol=1e-12) and np.all(img[0] == 0.0)


def test_bundled_valley_describes_and_renders(capsys):
    assert main(["describe", "valley_fog"]) == 0
    text = capsys.readouterr().out
    assert "light[0]: directional, travelling along" in text and "height_fog: coefficients at h0 = 0" in text
    img = raytrace.render("valley_fog", crop=(190, 90, 200, 100), threads=1).array
    assert np.all(np.isfinite(img)) and np.all(img > 0.0)


def test_gather_attenuates_each_segment_from_the_camera_ray_origin():
    """A segment starting at t0 inside a ray gets the fog's transmittance over [0, t0] of its camera
    ray (scipy quad of the density), not exp(-kt t0) and not from its own start."""
    from raytrace.methods import Segments
    from raytrace.scene.format import scene_from_dict
    from raytrace.segments import gather

    medium = scene_from_dict(box_room(medium={**FOG, "up": [0.3, 1.0, 0.2]}), "test").medium
    rng = np.random.default_rng(3)
    o = rng.normal(size=(6, 3))
    d = rng.normal(size=(6, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    t0 = rng.uniform(0.5, 4.0, 6)
    segs = Segments(o + t0[:, None] * d, d, np.ones(6), np.zeros(6, np.int64), np.arange(6), t0,
                    np.zeros(6, np.uint64), np.zeros(6, np.int64))
    got = gather(segs, np.ones((6, 3)), 6, medium)
    fog = oracle.Fog({**FOG, "up": [0.3, 1.0, 0.2]})
    want = np.array([np.exp(-(fog.ka + fog.ks) * fog.depth(o[i], d[i], t0[i])) for i in range(6)])
    assert np.allclose(got, want, rtol=1e-12, atol=0.0)


@pytest.mark.parametrize("profile", ["exponential", "linear"])
@pytest.mark.parametrize("method", ["quadrature", "raymarch", "montecarlo"])
def test_rays_into_the_dense_fog_below_stay_finite(method, profile):
    """Rays that miss everything and fall below h0 forever: the density overflows where the
    transmittance is 0, and the product must be 0, not nan (raytrace.render refuses non-finite
    pixels)."""
    scene = {"camera": {"position": [0, 1, 5], "look_at": [0, -0.5, 0], "width": 8, "height": 6, "fov": 90},
             "shape": [{"primitive": "box", "min": [-1, -1, -1], "max": [1, 0, 1]}],
             "light": [{"position": [0.5, 1.0, -1.0], "intensity": 10.0}, SUN],
             "medium": {"type": "height_fog", "sigma_a": 0.01, "sigma_s": 0.1, "scale_height": 0.5, "profile": profile}}
    img = raytrace.render(scene, method=method, threads=1).array
    assert np.all(np.isfinite(img)) and img.max() > 0.0
