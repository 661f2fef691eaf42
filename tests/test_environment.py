"""The environment light (issue 36; raytrace/lights/environment.py): constant or an equirectangular map,
importance-sampled into directional rows, seen by the rays that leave the scene.

- The scene file: it parses and describes as SCENE_FORMAT.md pins it; bad input is one line naming
  the key and the fix, exit 2, nothing written (radiance and map both or neither, a missing or negative
  map, [background] beside it, two of them, a homogeneous medium filling all space, methods that do
  not take it naming those that do).
- The sampling against independent arithmetic: the map's pdf against a histogram of its samples
  (chi-square), its integral over the sphere 1; the rows' irradiances L / pdf / N sum to the integral
  of L over the sphere (exactly for a constant and a grey map; unbiased for a coloured one: z-test of
  iid samples); the environment camera sees the map texel by texel, rotated as a shape is.
- Images against twins built from the geometry and scipy alone, through the renderer with the
  groups of directions shifted by each render's seed (Cranley–Patterson: each render an unbiased estimate),
  z-tests of the mean of R renders (seeds 1 ... R) with their sample variance: a Lambertian ground point
  under an opaque square plate in vacuum (rho L (1 - F), F the plate's form factor, by scipy), and camera
  rays up through a height fog (scipy over the ray of the exact direction integral, an E_2 exponential
  integral itself checked against scipy over directions). The default seed's render then lies within the
  same spread, and every pixel lit by the environment has an infinite error bound
  (tests/test_environment_variance.py: the variance each render reports).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy import integrate, special, stats

from raytrace import api
from raytrace.camera import generate_rays
from raytrace.cli import main
from raytrace.output.film import write_exr
from raytrace.lights import Lights, at_infinity, describe, environment
from raytrace.methods import resolve_params
from raytrace.rendering import renderer
from raytrace.scene.format import scene_from_text
from raytrace.scene.meshes import rotation_matrix

from .conftest import to_toml

ENV = {"type": "environment", "radiance": [0.2, 0.3, 0.5]}
VACUUM = {"sigma_a": 0.0, "sigma_s": 0.0}
FOG = {"type": "height_fog", "sigma_a": 0.02, "sigma_s": 0.1, "up": [0.0, 1.0, 0.0], "h0": 0.0, "scale_height": 2.0}
CAMERA = {"position": [0.0, 0.5, 3.0], "look_at": [0.0, 0.5, 0.0], "fov": 40.0, "width": 4, "height": 3}
RNG_SEED = 36


def scene(lights, medium=VACUUM, camera=CAMERA, shapes=(), path="env.toml"):
    return scene_from_text(to_toml({"camera": camera, "shape": list(shapes), "light": lights, "medium": medium}),
                           str(path), Path(path))


def a_map(height=8, width=16, grey=False):
    """A positive map with one black texel, float32-exact (EXR's precision)."""
    rng = np.random.default_rng(RNG_SEED)
    image = rng.uniform(0.1, 2.0, (height, width, 1 if grey else 3)) * np.array([1.0, 0.5, 0.25])
    image = np.broadcast_to(image, (height, width, 3)).astype(np.float32).astype(float)
    image[2, 3] = 0.0
    return image


def map_light(tmp_path, image, **keys):
    write_exr(tmp_path / "sky.exr", image)
    return scene([{"type": "environment", "map": "sky.exr", **keys}], path=tmp_path / "env.toml").lights[0]


def texel_solid_angles(height, width):
    """Each row's texel solid angle: the integral of sin(theta) dtheta dphi over it (scipy)."""
    return np.array([integrate.quad(math.sin, math.pi * r / height, math.pi * (r + 1) / height)[0]
                     for r in range(height)]) * 2.0 * math.pi / width


def texel_of(dirs, rotation, height, width):
    """(row, column) of world directions in the pinned mapping: local = R^T d, theta from +y, phi from -z
    toward +x, column 0 at phi = -pi."""
    local = dirs @ rotation
    theta = np.arccos(np.clip(local[:, 1], -1, 1))
    phi = np.arctan2(local[:, 0], -local[:, 2])
    return np.minimum((theta / math.pi * height).astype(int), height - 1), \
        np.floor((phi + math.pi) / (2 * math.pi) * width).astype(int) % width


def test_it_parses_and_describes(tmp_path):
    (light,) = scene([ENV]).lights
    assert describe(light) == ("environment, constant radiance [0.2, 0.3, 0.5], mean radiance [0.2, 0.3, 0.5]; "
                               f"{environment.COUNT} directions in {environment.GROUPS} groups a pixel sample "
                               "(importance-sampled, shifted by the seed and the sample; their spread is the variance)")
    light = map_light(tmp_path, a_map(), rotate=[0.0, 90.0, 0.0], scale=2.0)
    assert describe(light).startswith(f"environment, map {tmp_path / 'sky.exr'} (16 x 8), rotated, mean radiance")
    np.testing.assert_array_equal(light.emitter["map"], 2.0 * a_map())
    np.testing.assert_allclose(light.emitter["rotation"], rotation_matrix([0.0, 90.0, 0.0]), atol=1e-15)
    rows = Lights.of([light])
    assert len(rows) == environment.COUNT and rows.kinds() == {"directional", "environment"} and rows.cubature.all()


def test_the_stated_directions(write_scene, tmp_path, capsys):
    """`directions` sets the count of a pixel sample (a multiple of 2 GROUPS); anything else is one line, exit 2."""
    (light,) = scene([{**ENV, "directions": 256}]).lights
    assert len(environment.rows(light).kind) == 256 and describe(light).endswith(
        f"256 directions in {environment.GROUPS} groups a pixel sample (importance-sampled, shifted by the seed "
        "and the sample; their spread is the variance)")
    for bad in (6, 0, 64.0, True, "64"):
        path = write_scene({"camera": CAMERA, "light": [{**ENV, "directions": bad}], "medium": VACUUM})
        assert main(["render", str(path), "--out", str(tmp_path / "x.exr"), "--quiet"]) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and "light[0].directions: expected a multiple of" in err and "= 256" in err, err
        assert not (tmp_path / "x.exr").exists()


@pytest.mark.parametrize("light,extra,message", [
    ({"type": "environment"}, {}, "light[0]: missing radiance; add light[0].radiance = [0.2, 0.3, 0.5] or "),
    ({**ENV, "map": "sky.exr"}, {}, "light[0]: give either radiance (a constant environment) or map"),
    ({"type": "environment", "map": "nowhere.exr"}, {}, "light[0].map: environment map 'nowhere.exr' not found in"),
    ({"type": "environment", "map": 3}, {}, "light[0].map: expected a file name, got 3"),
    ({**ENV, "scale": -1.0}, {}, "light[0].scale: must be >= 0.0"),
    ({**ENV, "rotate": [0.0, 1.0]}, {}, "light[0].rotate: expected"),
    ({**ENV, "radius": 1.0}, {}, "light[0].radius: unknown key"),
    (ENV, {"background": {"radiance": 0.1}},
     "background: given with an environment light (light[0]), which replaces it"),
    (ENV, {"medium": {"sigma_a": 0.1, "sigma_s": 0.1}},
     "light[0].type: an environment light through a homogeneous medium filling all space arrives with zero"),
])
def test_bad_environments_are_one_line_errors(write_scene, tmp_path, capsys, light, extra, message):
    path = write_scene({"camera": CAMERA, "light": [light], "medium": VACUUM, **extra})
    out = tmp_path / "x.exr"
    assert main(["render", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and message in err, err
    assert not out.exists()


def test_a_second_environment_and_a_bad_map_are_refused(write_scene, tmp_path, capsys):
    path = write_scene({"camera": CAMERA, "light": [ENV, ENV], "medium": VACUUM})
    assert main(["describe", str(path)]) == 2
    assert "light[1].type: a second environment light (light[0] is one); keep one" in capsys.readouterr().err
    image = a_map()
    image[0, 0, 1] = -1.0
    write_exr(tmp_path / "sky.exr", image)
    path = write_scene({"camera": CAMERA, "light": [{"type": "environment", "map": "sky.exr"}], "medium": VACUUM})
    assert main(["describe", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "light[0].map: " in err and "holds negative or non-finite values" in err, err
    (tmp_path / "sky.exr").write_text("not an image")
    assert main(["describe", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "light[0].map: " in err and "is not a readable RGB OpenEXR image; give a linear" in err, err


@pytest.mark.parametrize("method", ["analytic", "lecocq", "sun"])
def test_methods_without_environment_light_refuse_it(write_scene, tmp_path, capsys, method):
    path = write_scene({"camera": CAMERA, "light": [ENV], "medium": VACUUM})
    assert main(["render", str(path), "--out", str(tmp_path / "x.exr"), "--quiet", "--method", method]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and f"--method {method}: " in err, err
    assert "environment" in err and "use --method quadrature, raymarch, montecarlo" in err, err


def test_the_pdf_matches_a_histogram_of_its_samples(tmp_path):
    """200 000 iid uniform points through the inverse distribution, counted per texel (in the pinned
    mapping, computed here): chi-square against n x the texel's probability luminance x solid angle /
    sum (scipy's solid angles), p > 1e-3; the pdf returned is the pdf of the direction
    (`environment.pdf`), is constant over each texel and integrates to 1; the black texel gets none."""
    image = a_map()
    light = map_light(tmp_path, image, rotate=[20.0, -35.0, 50.0])
    H, W = image.shape[:2]
    omega = texel_solid_angles(H, W)
    weight = (image @ [0.2126, 0.7152, 0.0722]) * omega[:, None]
    prob = weight / weight.sum()
    n = 200_000
    dirs, pdf, value = environment.directions(light, np.random.default_rng(RNG_SEED).random((n, 2)))
    np.testing.assert_allclose(np.linalg.norm(dirs, axis=1), 1.0, rtol=0, atol=1e-14)
    r, c = texel_of(dirs, rotation_matrix([20.0, -35.0, 50.0]), H, W)
    counts = np.zeros((H, W))
    np.add.at(counts, (r, c), 1)
    assert counts[2, 3] == 0
    keep = prob > 0
    assert stats.chisquare(counts[keep], n * prob[keep]).pvalue > 1e-3
    np.testing.assert_allclose(pdf, prob[r, c] / omega[r], rtol=1e-12)
    np.testing.assert_allclose(environment.pdf(light, dirs), pdf, rtol=1e-12)
    np.testing.assert_array_equal(value, light.emitter["map"][r, c])
    assert abs((prob / omega[:, None] * omega[:, None]).sum() - 1.0) < 1e-12


def test_the_weights_integrate_the_map(tmp_path):
    """The rows' irradiances sum to the integral of L over the sphere: 4 pi L for a constant and the exact
    sum of L x solid angle for a grey map, to rounding, at any count; for a coloured map, iid samples of
    L / pdf are unbiased: z-test of their mean (n = 100 000) against the exact integral."""
    for count in (2, 8, 64, 1000):  # (at least GROUPS; a multiple of GROUPS: rows of equal weight)
        rows = environment.rows(scene([ENV]).lights[0], count)
        np.testing.assert_allclose(rows.intensity.sum(axis=0), 4 * math.pi * np.array(ENV["radiance"]), rtol=1e-13)
        np.testing.assert_allclose(rows.intensity, np.broadcast_to(4 * math.pi / count * np.array(ENV["radiance"]),
                                                                   (count, 3)), rtol=1e-13)
    omega = texel_solid_angles(8, 16)
    grey = map_light(tmp_path, a_map(grey=True))
    exact = np.einsum("rcx,r->x", a_map(grey=True), omega)
    for count in (16, 64, 333):
        np.testing.assert_allclose(environment.rows(grey, count).intensity.sum(axis=0), exact, rtol=1e-12)
    image = a_map()
    light = map_light(tmp_path, image)
    exact = np.einsum("rcx,r->x", image, omega)
    _, pdf, value = environment.directions(light, np.random.default_rng(RNG_SEED + 1).random((100_000, 2)))
    ratio = value / pdf[:, None]
    z = (ratio.mean(axis=0) - exact) / (ratio.std(axis=0, ddof=1) / math.sqrt(len(ratio)))
    assert np.all(np.abs(z) < 4.0), z
    lattice = environment.rows(light, 4096).intensity.sum(axis=0)  # the default pattern converges
    assert np.all(np.abs(lattice / exact - 1) < np.abs(environment.rows(light, 16).intensity.sum(axis=0) / exact - 1))


@pytest.mark.parametrize("rotate,shift", [([0.0, 0.0, 0.0], 0), ([0.0, 90.0, 0.0], -4)])
def test_the_environment_camera_sees_the_map(tmp_path, rotate, shift):
    """In vacuum an environment camera at the map's size looking down -z (up +y) sees each texel at its
    pixel's centre: the map exactly; turned 90 degrees about y, the map's centre column (-z) lies along
    -x, a quarter turn to the left (`shift` columns); the same through `at_infinity`."""
    image = a_map()
    write_exr(tmp_path / "sky.exr", image)
    cam = {"type": "environment", "position": [0.0, 0.0, 0.0], "look_at": [0.0, 0.0, -1.0], "width": 16, "height": 8,
           "spp": 1}
    sc = scene([{"type": "environment", "map": "sky.exr", "rotate": rotate}], camera=cam, path=tmp_path / "env.toml")
    seen = api.render(sc, "quadrature").array
    np.testing.assert_array_equal(seen, np.roll(image, shift, axis=1))
    np.testing.assert_array_equal(at_infinity(sc.lights, np.zeros(3), np.array([[0.0, 0.0, -1.0]])),
                                  np.roll(image, shift, axis=1)[4:5, 8])
    plain = scene([], camera=cam)
    np.testing.assert_array_equal(at_infinity(plain.lights, np.array([0.1, 0.2, 0.3]), np.eye(3)),
                                  [[0.1, 0.2, 0.3]] * 3)


def shifted_renders(sc, r, method="quadrature", **kw):
    """R renders, seeds 1 ... R: each group of directions shifted by its own uniforms (Cranley–Patterson)."""
    return [api.render(sc, method, seed=seed, **kw) for seed in range(1, r + 1)]


def z_of(samples, reference):
    samples = np.asarray(samples)
    return (samples.mean(axis=0) - reference) / (samples.std(axis=0, ddof=1) / math.sqrt(len(samples)))


GROUND = {"primitive": "quad", "corners": [[-20.0, 0.0, 20.0], [20.0, 0.0, 20.0], [20.0, 0.0, -20.0],
                                           [-20.0, 0.0, -20.0]], "reflectance": 0.5}
PLATE = {"primitive": "quad", "corners": [[-1.0, 1.0, -1.0], [1.0, 1.0, -1.0], [1.0, 1.0, 1.0], [-1.0, 1.0, 1.0]],
         "reflectance": 0.8}
POINT_CAMERA = {"position": [0.0, 0.5, 0.6], "look_at": [0.0, 0.0, 0.0], "fov": 1.0, "width": 1, "height": 1, "spp": 1}


def test_a_ground_point_under_a_plate_against_its_form_factor():
    """A Lambertian ground (rho 0.5) under a constant environment L in vacuum, below an opaque 2 x 2
    plate at height 1 centred over the point the camera sees: radiance rho L (1 - F), F the plate's
    form factor from the point (scipy over the plate of cos^2 / (pi r^2), and the corner formula of
    a parallel rectangle). Seeds 1 ... 24: z-test; the default seed within 4 of their standard
    deviations; the bound infinite."""
    c = 1.0
    F = integrate.dblquad(lambda z, x: c * c / (math.pi * (x * x + z * z + c * c) ** 2), -1, 1, -1, 1,
                          epsabs=1e-13)[0]
    x = 1.0 / c
    corner = 2 * x / math.sqrt(1 + x * x) * math.atan(x / math.sqrt(1 + x * x)) / (2 * math.pi)
    assert abs(F - 4 * corner) < 1e-12
    L = np.array(ENV["radiance"])
    exact = 0.5 * L * (1.0 - F)
    sc = scene([ENV], camera=POINT_CAMERA, shapes=[GROUND, PLATE])
    renders = shifted_renders(sc, 24)
    values = np.array([img.array[0, 0] for img in renders])
    assert np.all(np.abs(z_of(values, exact)) < 4.0), (values.mean(axis=0), exact)
    default = api.render(sc, "quadrature")
    spread = values.std(axis=0, ddof=1)
    assert np.all(np.abs(default.array[0, 0] - exact) < 4.0 * spread), (default.array[0, 0], exact, spread)
    assert np.all(np.isinf(default.error_bound))


def test_an_open_horizontal_ground_is_lit_exactly():
    """Without the plate every group of directions lights the ground exactly: rho L (a group's cos theta nodes
    are a shifted lattice's folded by the tent u0 -> 1 - |2 u0 - 1|: in the upper hemisphere a rule symmetric
    about cos theta = 1/2, exact for the linear cosine of a horizontal surface), whatever the seed and sample;
    so the variance is 0."""
    for seed, spp in ((0, 1), (5, 3)):
        img = api.render(scene([ENV], camera={**POINT_CAMERA, "spp": spp}, shapes=[GROUND]), "quadrature", seed=seed)
        np.testing.assert_allclose(img.array[0, 0], 0.5 * np.array(ENV["radiance"]), rtol=1e-12)
        assert np.all(img.variance < 1e-30)


UP_CAMERA = {"position": [0.0, 0.5, 0.0], "look_at": [0.0, 1.5, -1.0], "fov": 30.0, "width": 2, "height": 2,
             "spp": 1}


def fog_twin(origin, direction, seen, lit, sigma_a, sigma_s, H):
    """Radiance along an upward ray through the exponential fog (density e^{-h/H}, isotropic) under an
    environment that is `seen` (rgb) along the ray and whose mean over the upper hemisphere is `lit`:
    seen T(inf) + int sigma_s(h) T(t) (lit / 2) E_2(sigma_t H e^{-h/H}) dt, where for an environment
    constant in theta over the upper hemisphere (1 / 4 pi) int L T_inf(w) dw = (lit / 2) int_0^1 e^{-a / mu}
    dmu = (lit / 2) E_2(a) (rays downward meet infinite optical depth)."""
    kt = sigma_a + sigma_s
    h0, mu = origin[1], direction[1]
    assert mu > 0
    depth = lambda t: kt * H * math.exp(-h0 / H) * (1.0 - math.exp(-mu * t / H)) / mu
    inscatter = lambda t: (sigma_s * math.exp(-(h0 + mu * t) / H) * math.exp(-depth(t)) * 0.5 *
                           special.expn(2, kt * H * math.exp(-(h0 + mu * t) / H)))
    air = integrate.quad(inscatter, 0.0, np.inf, epsabs=0.0, epsrel=1e-11, limit=200)[0]
    return np.asarray(seen) * math.exp(-kt * H * math.exp(-h0 / H) / mu) + np.asarray(lit) * air


def fog_by_directions(origin, direction, seen, axes, irradiance, sigma_a, sigma_s, H):
    """The radiance along an upward ray through the exponential fog of `fog_twin` lit by directional rows
    (travelling along `axes` (n, 3), `irradiance` (n, 3)) instead of the environment's integral: per row the air-light
    in closed form, in the density s = e^{-h/H} (dt = H ds / (mu s)): sigma_s H / (4 pi mu) int_0^s0 e^{-A (s0 - s)}
    e^{-B s} ds = sigma_s H / (4 pi mu) e^{-A s0} (e^{(A - B) s0} - 1) / (A - B), A = kt H / mu, B = kt H / mu_w
    (mu_w the up-cosine toward the light; none from below the horizon)."""
    kt, s0, mu = sigma_a + sigma_s, math.exp(-origin[1] / H), direction[1]
    mu_w = -np.asarray(axes)[:, 1]
    A, B = kt * H / mu, kt * H / np.where(mu_w > 0.0, mu_w, 1.0)
    g = np.where(mu_w > 0.0, sigma_s * H / (4.0 * math.pi * mu) * math.exp(-A * s0) * np.expm1((A - B) * s0) / (A - B), 0.0)
    return np.asarray(seen) * math.exp(-A * s0) + g @ np.asarray(irradiance)


def test_the_direction_integral_is_e2():
    a = 0.37
    by_directions = integrate.dblquad(lambda mu, phi: math.exp(-a / mu) / (4 * math.pi), 0.0, 2 * math.pi, 0.0, 1.0,
                                      epsabs=1e-13)[0]
    assert abs(by_directions - 0.5 * special.expn(2, a)) < 1e-12


@pytest.mark.parametrize("method", ["quadrature", "raymarch"])
def test_rays_up_through_height_fog_against_the_twin(method):
    """Camera rays up through a height fog under a constant environment (no shapes): quadrature (rtol
    1e-10) and raymarch (4096 steps, its own error under 1e-3 of the value), seeds 1 ... 16: the mean
    of 16 renders within 4 standard errors of the twin (raymarch: plus its step error); the default
    seed within 4 of their standard deviations."""
    sc = scene([ENV], medium=FOG, camera=UP_CAMERA)
    cam = sc.camera

    origins, dirs = generate_rays(cam)
    L = np.array(ENV["radiance"])
    twin = np.array([fog_twin(o, d, L, L, 0.02, 0.1, 2.0) for o, d in zip(origins, dirs)]).reshape(2, 2, 3)
    kw = {"rtol": 1e-10} if method == "quadrature" else {"steps": 4096}
    values = np.array([img.array for img in shifted_renders(sc, 16, method, **kw)])
    step = 0.0 if method == "quadrature" else 1e-3 * twin
    err = np.abs(values.mean(axis=0) - twin) - step
    sem = values.std(axis=0, ddof=1) / math.sqrt(len(values))
    assert np.all(err < 4.0 * sem), (values.mean(axis=0), twin, sem)
    default = api.render(sc, method, **kw)
    assert np.all(np.abs(default.array - twin) - step < 4.0 * values.std(axis=0, ddof=1)), (default.array, twin)
    assert np.all(np.isinf(default.error_bound))


def test_a_map_over_height_fog_against_the_twin(tmp_path):
    """A 2 x 4 map: four colours over the upper hemisphere, a bright lower one (sampled, but light from below
    meets infinite optical depth). The camera rays see their texel times T(inf); the fog is lit by the upper
    mean (the twin's E_2): seeds 1 ... 16, z-test of 16 renders of quadrature; the default seed within 4 of
    their standard deviations."""
    image = np.array([[[0.1, 0.2, 0.4], [0.4, 0.3, 0.1], [0.9, 0.8, 0.7], [0.2, 0.6, 0.2]], [[3.0, 3.0, 3.0]] * 4])
    write_exr(tmp_path / "sky.exr", image)
    sc = scene([{"type": "environment", "map": "sky.exr"}], medium=FOG, camera=UP_CAMERA, path=tmp_path / "env.toml")

    origins, dirs = generate_rays(sc.camera)
    r, c = texel_of(dirs, np.eye(3), 2, 4)
    assert np.all(r == 0)
    twin = np.array([fog_twin(o, d, image[0, k], image[0].mean(axis=0), 0.02, 0.1, 2.0)
                     for o, d, k in zip(origins, dirs, c)]).reshape(2, 2, 3)
    values = np.array([img.array for img in shifted_renders(sc, 16, rtol=1e-10)])
    sem = values.std(axis=0, ddof=1) / math.sqrt(len(values))
    assert np.all(np.abs(values.mean(axis=0) - twin) < 4.0 * sem), (values.mean(axis=0), twin, sem)
    default = api.render(sc, "quadrature", rtol=1e-10).array
    assert np.all(np.abs(default - twin) < 4.0 * values.std(axis=0, ddof=1)), (default, twin)


def test_montecarlo_integrates_the_same_rows():
    """montecarlo (64 samples per row) on the fog scene with a plate, with volumetric shadows, the camera's rays
    shaded with the same rows (one pixel sample's directions): unbiased against quadrature's value of them, its
    z-scores with its own variance have a mean square below 2, none beyond 5."""
    cam = {"position": [0.0, 0.5, 3.0], "look_at": [0.0, 1.5, 0.0], "fov": 60.0, "width": 4, "height": 3}
    sc = scene([ENV], medium=FOG, camera=cam, shapes=[PLATE])
    prep = renderer.prepare(sc)
    o, d = generate_rays(sc.camera)

    def shade(name, seed, **given):
        method = renderer.get_method(name)
        return renderer.shade_rays(prep, method, resolve_params(method, given, "test"), o, d,
                                   np.arange(len(o), dtype=np.uint64), seed, True)

    ref = shade("quadrature", 0, rtol=1e-10)[0]
    mc, _, var, _ = shade("montecarlo", 3, samples=64)
    z = (mc - ref) / np.sqrt(var)
    assert np.mean(z**2) < 2.0 and np.abs(z).max() < 5.0, (np.mean(z**2), np.abs(z).max())


@pytest.mark.parametrize("ior", [1.0, 1.33])
def test_a_fog_box_in_vacuum_under_a_plate(ior):
    """The interior case (media inside shapes, vacuum outside): a box of fog (index-matched or refractive)
    on the ground under the plate renders with quadrature and analytic (its closed forms inside take the
    environment's directional rows), which agree to 1e-9; rays that leave the scene see L exactly."""
    box = {"primitive": "box", "min": [-0.5, 0.0, -0.5], "max": [0.5, 0.8, 0.5],
           "interior": {"sigma_a": 0.2, "sigma_s": 0.6, "ior": ior}}
    cam = {"position": [0.0, 0.6, 3.0], "look_at": [0.0, 0.4, 0.0], "fov": 40.0, "width": 6, "height": 4}
    sc = scene([ENV], camera=cam, shapes=[GROUND, PLATE, box])
    quad = api.render(sc, "quadrature", rtol=1e-10).array
    ana = api.render(sc, "analytic", precision=1e-10).array
    np.testing.assert_allclose(ana, quad, rtol=1e-9, atol=0)
    np.testing.assert_array_equal(quad[0], np.broadcast_to(ENV["radiance"], (6, 3)))


def test_light_layers_sum_and_misses_are_emission(tmp_path):
    """The environment is one light layer (its rows share an owner); what rays leaving the scene see of
    it is in `emission`; the layers sum to the image."""
    cam = {"position": [0.0, 0.5, 3.0], "look_at": [0.0, 1.5, 0.0], "fov": 60.0, "width": 4, "height": 3}
    sc = scene([ENV, {"position": [0.0, 2.0, 0.0], "intensity": 1.0}], medium=FOG, camera=cam, shapes=[PLATE])
    img = api.render(sc, "quadrature", aov=["lights"])
    assert list(img.layers) == ["light0", "light1", "emission"]
    np.testing.assert_allclose(img.layers["light0"] + img.layers["light1"] + img.layers["emission"], img.array,
                               rtol=1e-12, atol=0)
    assert np.count_nonzero(img.layers["emission"]) and np.count_nonzero(img.layers["light0"])
    assert np.all(Lights.of(sc.lights).owner[:environment.COUNT] == 0)


def test_exporters_write_a_scaled_constant_back(tmp_path):
    """A constant environment's `scale` is part of its radiance in Mitsuba's `constant` and pbrt's `infinite`."""
    from raytrace.io import mitsuba, pbrt

    raw = {"camera": {**CAMERA, "spp": 1},
           "light": [{"type": "environment", "radiance": [0.1, 0.2, 0.3], "scale": 2.0}]}
    for module, name in ((mitsuba, "scene.xml"), (pbrt, "scene.pbrt")):
        module.export(raw, tmp_path / name, "test", False)
        (env,) = module.read_scene(tmp_path / name)["light"]
        assert env["type"] == "environment"
        np.testing.assert_allclose(env["radiance"], [0.2, 0.4, 0.6], rtol=1e-12)
