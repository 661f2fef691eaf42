"""Environment maps beyond the nearest-texel equirectangular one (raytrace/lights/environment.py,
octahedral.py, bilinear.py; docs/environment.md):

- pbrt-v4's equal-area octahedral maps against a twin of Clarberg's mapping written here from the
  paper (Clarberg 2008, sec. 3: the square folded into a diamond per hemisphere, r = 1 - |1 - |u'| - |v'||
  the distance from the pole, phi linear along the diamond's edge): lookups, the round trip
  direction -> square -> direction to 1e-12, the Jacobian 4 pi (equal area) by finite differences, the
  seams' continuity;
- interpolated equirectangular maps ("bilinear", "mitsuba") against a numpy twin of bilinear
  interpolation between their nodes; their integral by Gauss-Legendre over each cell;
- the pdf of every kind against a histogram of its samples (chi-square over cells whose probability
  the twins give), the pdf returned equal to `pdf(w)` and to the twin's, grey maps' rows summing to
  the exact integral;
- a constant octahedral map renders as a constant sky; a pbrt-v4 file with an infinite light and an
  octahedral EXR imports (its frame, a mirrored world, "scale", "illuminance" as pbrt-v4 computes it)
  and renders what pbrt-v4's lookup gives; the TOML -> pbrt -> TOML round trip; refusals.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from raytrace import api
from raytrace.errors import UserError
from raytrace.io import pbrt
from raytrace.lights import describe, environment
from raytrace.output.film import write_exr
from raytrace.scene.format import scene_from_text
from raytrace.scene.meshes import rotation_matrix

from .conftest import to_toml
from .test_environment import a_map, map_light

VACUUM = {"sigma_a": 0.0, "sigma_s": 0.0}
CAMERA = {"position": [0.0, 0.5, 3.0], "look_at": [0.0, 0.5, 0.0], "fov": 40.0, "width": 4, "height": 3}
LUMA = np.array([0.2126, 0.7152, 0.0722])
ROTATE = [20.0, -35.0, 50.0]
RNG = 3636


def scene(lights, camera=CAMERA, shapes=(), path="env.toml"):
    return scene_from_text(to_toml({"camera": camera, "shape": list(shapes), "light": lights, "medium": VACUUM}),
                           str(path), Path(path))


def unit(n, seed=RNG):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1)[:, None]


# --------------------------------------------------------------- Clarberg's mapping, written from the paper

def clarberg_square_to_sphere(u, v):
    """Paper sec. 3: (u', v') = 2 (u, v) - 1; the distance from the nearer pole r = 1 - |1 - |u'| - |v'||
    (the diamond |u'| + |v'| <= 1 is the upper hemisphere: r = |u'| + |v'|; outside, the triangles fold
    onto the lower one); along the diamond of radius r, phi grows linearly from the +x axis: in the first
    quadrant phi = (pi / 4)(1 + (|v'| - |u'|) / r) (the lower fold swaps the roles of |u'|, |v'| about
    the square's corner, which leaves this expression as it is); z = +-(1 - r^2); the horizontal radius
    sqrt(1 - z^2) = r sqrt(2 - r^2)."""
    up, vp = 2.0 * u - 1.0, 2.0 * v - 1.0
    s = np.abs(up) + np.abs(vp)
    upper = s <= 1.0
    r = np.where(upper, s, 2.0 - s)
    phi = np.pi / 4.0 * (1.0 + (np.abs(vp) - np.abs(up)) / np.maximum(r, 1e-300))
    z = np.where(upper, 1.0 - r * r, r * r - 1.0)
    h = r * np.sqrt(2.0 - r * r)
    return np.stack([np.sign(up) * h * np.cos(phi), np.sign(vp) * h * np.sin(phi), z], axis=-1)


def clarberg_sphere_to_square(d):
    """The inverse: r = sqrt(1 - |z|), phi = atan2(|y|, |x|) in [0, pi/2]; on the diamond |v'| = r (2 phi / pi),
    |u'| = r - |v'|; below the horizon the point folds out to (1 - |v'|, 1 - |u'|); signs of x, y."""
    r = np.sqrt(1.0 - np.abs(d[:, 2]))
    phi = np.arctan2(np.abs(d[:, 1]), np.abs(d[:, 0]))
    b = r * phi * 2.0 / np.pi
    a = r - b
    a, b = np.where(d[:, 2] < 0, 1.0 - b, a), np.where(d[:, 2] < 0, 1.0 - a, b)
    return (np.sign(d[:, 0]) * a + 1.0) / 2.0, (np.sign(d[:, 1]) * b + 1.0) / 2.0


def pbrt_frame(world, rotation):
    """Our octahedral map's frame (its centre up, +y) as pbrt's: (x, -z, y) of R^T w."""
    local = world @ rotation
    return np.stack([local[:, 0], -local[:, 2], local[:, 1]], axis=1)


def test_the_octahedral_mapping_is_clarbergs():
    """square_to_sphere equals the twin at 20 000 random points and at the centre (+z), the corners
    (-z) and the edges' midpoints (the equator); it preserves area: |d/du x d/dv| = 4 pi by central
    differences; points mirrored across an edge of the square (pbrt's OctahedralSphere wrap: across
    u = 1 and v = 1/2) map to the same direction; sphere_to_square inverts it to 1e-12 everywhere,
    near the poles and the horizon too, and equals the paper's inverse."""
    from raytrace.lights import octahedral

    uv = np.random.default_rng(RNG).random((20_000, 2))
    np.testing.assert_allclose(octahedral.square_to_sphere(uv[:, 0], uv[:, 1]),
                               clarberg_square_to_sphere(uv[:, 0], uv[:, 1]), rtol=0, atol=1e-14)
    special = octahedral.square_to_sphere(np.array([0.5, 0.0, 1.0, 1.0, 0.5]), np.array([0.5, 0.0, 1.0, 0.5, 0.0]))
    np.testing.assert_allclose(special, [[0, 0, 1], [0, 0, -1], [0, 0, -1], [1, 0, 0], [0, -1, 0]], atol=1e-15)
    h = 1e-6
    inner = uv[(np.abs(uv - 0.5).max(axis=1) < 0.5 - 2 * h) & (np.abs(np.abs(2 * uv - 1).sum(axis=1) - 1) > 2 * h) &
               (np.abs(uv - 0.5).min(axis=1) > 2 * h)]
    du = (octahedral.square_to_sphere(inner[:, 0] + h, inner[:, 1]) -
          octahedral.square_to_sphere(inner[:, 0] - h, inner[:, 1])) / (2 * h)
    dv = (octahedral.square_to_sphere(inner[:, 0], inner[:, 1] + h) -
          octahedral.square_to_sphere(inner[:, 0], inner[:, 1] - h)) / (2 * h)
    np.testing.assert_allclose(np.linalg.norm(np.cross(du, dv), axis=1), 4 * math.pi, rtol=1e-6)
    t = np.random.default_rng(RNG + 1).random(1000)
    np.testing.assert_allclose(octahedral.square_to_sphere(np.ones_like(t), t),
                               octahedral.square_to_sphere(np.ones_like(t), 1.0 - t), atol=1e-14)
    np.testing.assert_allclose(octahedral.square_to_sphere(t, np.zeros_like(t)),
                               octahedral.square_to_sphere(1.0 - t, np.zeros_like(t)), atol=1e-14)
    d = np.concatenate([unit(20_000), [[0, 0, 1], [0, 0, -1], [1, 0, 0], [0, 1, 0], [-1, 0, 0]]])
    eps = np.array([1e-9, 1e-12, 1e-15])
    near = np.concatenate([np.stack([eps, eps, np.sqrt(1 - 2 * eps ** 2)], 1), np.stack([eps, -eps, -np.ones(3)], 1),
                           np.stack([np.ones(3), eps, eps], 1), np.stack([-np.ones(3), eps, -eps], 1)])
    d = np.concatenate([d, near / np.linalg.norm(near, axis=1)[:, None]])
    u, v = octahedral.sphere_to_square(d)
    assert np.all((0 <= u) & (u <= 1) & (0 <= v) & (v <= 1))
    np.testing.assert_allclose(octahedral.square_to_sphere(u, v), d, rtol=0, atol=1e-12)
    pu, pv = clarberg_sphere_to_square(d[:20_000])
    np.testing.assert_allclose(np.stack([u[:20_000], v[:20_000]], 1), np.stack([pu, pv], 1), atol=1e-7)


def test_an_octahedral_map_is_looked_up_at_its_texels(tmp_path):
    """Rays leaving the scene see, rotated and mirrored, the texel the twin's square coordinates of
    pbrt's frame fall in (row from v: the file's first scanline at v = 0); the pdf of a piecewise
    constant map there is P_texel N^2 / 4 pi."""
    image = a_map(8, 8)
    for mirror in (False, True):
        light = map_light(tmp_path, image, mapping="octahedral", rotate=ROTATE, mirror=mirror)
        R = rotation_matrix(ROTATE) @ np.diag([-1.0 if mirror else 1.0, 1.0, 1.0])
        d = unit(5000)
        u, v = clarberg_sphere_to_square(pbrt_frame(d, R))
        r, c = np.minimum((v * 8).astype(int), 7), np.minimum((u * 8).astype(int), 7)
        np.testing.assert_array_equal(environment.radiance(light, d), image[r, c])
        p = image @ LUMA / (image @ LUMA).sum()
        np.testing.assert_allclose(environment.pdf(light, d), p[r, c] * 64 / (4 * math.pi), rtol=1e-12)


# ------------------------------------------------------------------- the bilinear twin

def nodes_of(image, filt):
    """(theta nodes, phi nodes, node values (K, W + 1, 3)) of the interpolated map, from the docs' definition."""
    H, W = image.shape[:2]
    phi = 2 * math.pi * ((np.arange(W + 1) + 0.5) / W - 0.5)
    cols = np.arange(W + 1) % W
    if filt == "mitsuba":
        return math.pi * np.arange(H) / (H - 1), phi, image[:, cols]
    theta = np.r_[0.0, math.pi * (np.arange(H) + 0.5) / H, math.pi]
    return theta, phi, image[np.r_[0, np.arange(H), H - 1]][:, cols]


def twin_bilinear(image, filt, local):
    """L at local directions: (theta, phi) of the equirectangular mapping, phi moved into [phi_0, phi_0 + 2 pi),
    the cell found by comparison with every node, the bilinear weights."""
    theta_n, phi_n, val = nodes_of(image, filt)
    theta = np.arccos(np.clip(local[:, 1], -1, 1))
    phi = np.arctan2(local[:, 0], -local[:, 2])
    phi = phi_n[0] + np.mod(phi - phi_n[0], 2 * math.pi)
    i = np.minimum((theta[:, None] >= theta_n[None, :]).sum(1) - 1, len(theta_n) - 2)
    j = np.minimum((phi[:, None] >= phi_n[None, :]).sum(1) - 1, len(phi_n) - 2)
    s = ((theta - theta_n[i]) / (theta_n[i + 1] - theta_n[i]))[:, None]
    t = ((phi - phi_n[j]) / (phi_n[j + 1] - phi_n[j]))[:, None]
    return (1 - s) * (1 - t) * val[i, j] + (1 - s) * t * val[i, j + 1] + s * (1 - t) * val[i + 1, j] + \
        s * t * val[i + 1, j + 1]


def cell_integrals(image, filt, order=12):
    """(K - 1, W, 3): the integral of the twin's L x sin(theta) over each cell, Gauss-Legendre of `order`
    in theta and phi (the integrand is smooth in a cell)."""
    theta_n, phi_n, _ = nodes_of(image, filt)
    x, w = np.polynomial.legendre.leggauss(order)
    out = np.zeros((len(theta_n) - 1, len(phi_n) - 1, 3))
    for i in range(len(theta_n) - 1):
        a, b = theta_n[i], theta_n[i + 1]
        th = (a + b) / 2 + (b - a) / 2 * x
        for j in range(len(phi_n) - 1):
            c, e = phi_n[j], phi_n[j + 1]
            ph = (c + e) / 2 + (e - c) / 2 * x
            T, P = (m.ravel() for m in np.meshgrid(th, ph, indexing="ij"))
            local = np.stack([np.sin(T) * np.sin(P), np.cos(T), -np.sin(T) * np.cos(P)], 1)
            f = twin_bilinear(image, filt, local) * (np.sin(T) * np.outer(w, w).ravel())[:, None]
            out[i, j] = f.sum(0) * (b - a) * (e - c) / 4
    return out


@pytest.mark.parametrize("filt", ["bilinear", "mitsuba"])
def test_interpolated_maps_against_the_twin(tmp_path, filt):
    """At 5000 random directions (and the poles) L equals the twin's, rotated, to 1e-12; the light's mean
    radiance is the twin's integral / 4 pi; at the texel centres the map's own values ("bilinear"), at
    Mitsuba's nodes theta = pi r / (H - 1) its rows off the poles ("mitsuba")."""
    image = a_map(6, 8)
    light = map_light(tmp_path, image, filter=filt, rotate=ROTATE)
    R = rotation_matrix(ROTATE)
    d = np.concatenate([unit(5000), np.array([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]]) @ R.T])
    np.testing.assert_allclose(environment.radiance(light, d), twin_bilinear(image, filt, d @ R), rtol=1e-12,
                               atol=1e-14)
    np.testing.assert_allclose(light.intensity * 4 * math.pi, cell_integrals(image, filt).sum((0, 1)), rtol=1e-12)
    rows = np.arange(6) if filt == "bilinear" else np.arange(1, 5)  # (Mitsuba's poles: a row at one direction)
    theta = math.pi * (rows + 0.5) / 6 if filt == "bilinear" else math.pi * rows / 5
    phi = 2 * math.pi * ((np.arange(8) + 0.5) / 8 - 0.5)
    T, P = np.meshgrid(theta, phi, indexing="ij")
    local = np.stack([np.sin(T) * np.sin(P), np.cos(T), -np.sin(T) * np.cos(P)], -1).reshape(-1, 3)
    np.testing.assert_allclose(environment.radiance(light, local @ R.T), image[rows].reshape(-1, 3), rtol=1e-12,
                               atol=1e-14)


# ------------------------------------------------------------------- sampling

def chi_square(counts, prob, n):
    keep = prob > 0
    assert counts[~keep].sum() == 0
    return stats.chisquare(counts[keep], n * prob[keep] / prob[keep].sum() * counts[keep].sum() / n).pvalue


@pytest.mark.parametrize("filt", ["bilinear", "mitsuba"])
def test_interpolated_pdf_matches_a_histogram(tmp_path, filt):
    """200 000 iid points through the inverse distribution, counted per cell between the nodes (found
    here from each direction's angles): chi-square against the twin's cell integrals of the luminance,
    p > 1e-3; the pdf returned equals `pdf(w)` and the twin's Y(w) / Z (Z the Gauss-Legendre integral)."""
    image = a_map(6, 8)
    light = map_light(tmp_path, image, filter=filt, rotate=ROTATE)
    R = rotation_matrix(ROTATE)
    n = 200_000
    dirs, pdf, value = environment.directions(light, np.random.default_rng(RNG).random((n, 2)))
    np.testing.assert_allclose(np.linalg.norm(dirs, axis=1), 1.0, atol=1e-14)
    theta_n, phi_n, _ = nodes_of(image, filt)
    local = dirs @ R
    theta = np.arccos(np.clip(local[:, 1], -1, 1))
    phi = phi_n[0] + np.mod(np.arctan2(local[:, 0], -local[:, 2]) - phi_n[0], 2 * math.pi)
    i = np.minimum(np.searchsorted(theta_n, theta, side="right") - 1, len(theta_n) - 2)
    j = np.minimum(np.searchsorted(phi_n, phi, side="right") - 1, len(phi_n) - 2)
    counts = np.zeros((len(theta_n) - 1, len(phi_n) - 1))
    np.add.at(counts, (i, j), 1)
    cells = cell_integrals(image, filt) @ LUMA
    assert chi_square(counts, cells, n) > 1e-3
    z = cells.sum()
    np.testing.assert_allclose(pdf, twin_bilinear(image, filt, local) @ LUMA / z, rtol=1e-9)
    np.testing.assert_allclose(environment.pdf(light, dirs), pdf, rtol=1e-9)
    np.testing.assert_allclose(value, twin_bilinear(image, filt, local), rtol=1e-9, atol=1e-14)


def test_octahedral_pdf_matches_a_histogram(tmp_path):
    """The same for an 8 x 8 octahedral map, counted per texel (the twin's square coordinates):
    probabilities luminance / sum (equal solid angles); the black texel never drawn."""
    image = a_map(8, 8)
    light = map_light(tmp_path, image, mapping="octahedral", rotate=ROTATE)
    n = 200_000
    dirs, pdf, value = environment.directions(light, np.random.default_rng(RNG).random((n, 2)))
    u, v = clarberg_sphere_to_square(pbrt_frame(dirs, rotation_matrix(ROTATE)))
    r, c = np.minimum((v * 8).astype(int), 7), np.minimum((u * 8).astype(int), 7)
    counts = np.zeros((8, 8))
    np.add.at(counts, (r, c), 1)
    prob = image @ LUMA / (image @ LUMA).sum()
    assert counts[2, 3] == 0 and chi_square(counts, prob, n) > 1e-3
    np.testing.assert_allclose(pdf, prob[r, c] * 64 / (4 * math.pi), rtol=1e-12)
    np.testing.assert_allclose(environment.pdf(light, dirs), pdf, rtol=1e-12)
    np.testing.assert_array_equal(value, image[r, c])


@pytest.mark.parametrize("keys", [{"filter": "bilinear"}, {"filter": "mitsuba"}, {"mapping": "octahedral"}])
def test_grey_maps_rows_sum_to_the_exact_integral(tmp_path, keys):
    """A grey map: every row's L / pdf is the map's integral, so the rows sum to it at any count, to 1e-12
    (the twins' integral: Gauss-Legendre over the cells, or sum L x 4 pi / N^2); for a coloured map iid
    L / pdf are unbiased (z-test, n = 100 000)."""
    shape = (8, 8) if "mapping" in keys else (6, 8)
    grey = a_map(*shape, grey=True)
    exact = (grey.sum((0, 1)) * 4 * math.pi / 64 if "mapping" in keys else
             cell_integrals(grey, keys["filter"]).sum((0, 1)))
    light = map_light(tmp_path, grey, **keys)
    for count in (16, 64, 333):
        np.testing.assert_allclose(environment.rows(light, count).intensity.sum(axis=0), exact, rtol=1e-12)
    image = a_map(*shape)
    exact = (image.sum((0, 1)) * 4 * math.pi / 64 if "mapping" in keys else
             cell_integrals(image, keys["filter"]).sum((0, 1)))
    light = map_light(tmp_path, image, **keys)
    _, pdf, value = environment.directions(light, np.random.default_rng(RNG + 2).random((100_000, 2)))
    ratio = value / pdf[:, None]
    z = (ratio.mean(axis=0) - exact) / (ratio.std(axis=0, ddof=1) / math.sqrt(len(ratio)))
    assert np.all(np.abs(z) < 4.0), z


# ------------------------------------------------------------------- renders, pbrt files

GROUND = {"primitive": "quad", "corners": [[-20.0, 0.0, 20.0], [20.0, 0.0, 20.0], [20.0, 0.0, -20.0],
                                           [-20.0, 0.0, -20.0]], "reflectance": 0.5}


def test_a_constant_octahedral_map_renders_as_a_constant_sky(tmp_path):
    """L = [0.25, 0.375, 0.5] (float32-exact) as a 4 x 4 octahedral map and as a constant: rays leaving the scene see L
    exactly, the rows' irradiances sum to 4 pi L exactly, and an open Lambertian ground (rho 0.5) is rho L:
    exactly for the constant (each group's tent-folded cos theta nodes integrate the ground's cosine exactly); for
    the map (directions spread by the square, not by cos theta) within 4 of its standard errors (the variance
    layer) at the default 64 directions, within 1 % with `directions = 256` (rms 0.4 % over seeds) and within
    1e-3 with 4096 (and 4 standard errors)."""
    L = np.array([0.25, 0.375, 0.5])
    write_exr(tmp_path / "const.exr", np.broadcast_to(L, (4, 4, 3)).astype(np.float32))
    cam = {"position": [0.0, 1.0, 2.0], "look_at": [0.0, 0.0, 0.0], "fov": 90.0, "width": 4, "height": 4, "spp": 1}
    octahedral = {"type": "environment", "map": "const.exr", "mapping": "octahedral"}
    lights = {"map": [octahedral], "constant": [{"type": "environment", "radiance": L.tolist()}],
              "map, 256": [{**octahedral, "directions": 256}], "map, 4096": [{**octahedral, "directions": 4096}]}
    images = {}
    for name, light in lights.items():
        sc = scene(light, camera=cam, shapes=[GROUND], path=tmp_path / "env.toml")
        np.testing.assert_allclose(environment.rows(sc.lights[0]).intensity.sum(0), 4 * math.pi * L, rtol=1e-13)
        images[name] = api.render(sc, "quadrature")
    sky = np.zeros((4, 4), bool)
    sky[0] = True  # the top row looks 7 degrees above the horizon, the rest at the ground
    np.testing.assert_array_equal(images["map"].array[sky], images["constant"].array[sky])
    np.testing.assert_allclose(images["constant"].array[~sky], 0.5 * L * np.ones((12, 3)), rtol=1e-12)
    for name, rtol in (("map, 256", 1e-2), ("map, 4096", 1e-3)):
        np.testing.assert_allclose(images[name].array[~sky], 0.5 * L * np.ones((12, 3)), rtol=rtol)
    for name in ("map", "map, 4096"):
        z = (images[name].array[~sky] - 0.5 * L) / np.sqrt(images[name].variance[~sky])
        assert np.all(np.abs(z) < 4.0), (name, z)


PBRT = """LookAt 0 0 0  0 0 -1  0 1 0
Camera "spherical" "string mapping" "equirectangular"
Film "rgb" "integer xresolution" [ 32 ] "integer yresolution" [ 16 ] "string filename" [ "o.exr" ]
WorldBegin
LightSource "point" "point3 from" [ 1 2 3 ]
AttributeBegin
Rotate -90 1 0 0
Rotate 30 0 0 1
LightSource "infinite" "string filename" [ "octa.exr" ] {extra}
AttributeEnd
"""


def pbrt_lookup(image, world_dirs, to_light):
    """pbrt-v4's ImageLe: the texel of EqualAreaSphereToSquare(normalize(M^-1 w)) (the twin's), nearest."""
    d = world_dirs @ to_light.T
    u, v = clarberg_sphere_to_square(d / np.linalg.norm(d, axis=1)[:, None])
    n = image.shape[0]
    return image[np.minimum((v * n).astype(int), n - 1), np.minimum((u * n).astype(int), n - 1)]


@pytest.mark.parametrize("mirror", ["", "Scale -1 1 1\n"])
def test_a_pbrt_octahedral_map_imports_and_renders(tmp_path, mirror):
    """A spherical camera (its world read mirrored or not, as pbrt's image demands) under an infinite
    light with an 8 x 8 octahedral map turned by the CTM (Rotate -90 about x, 30 about z): rays leaving
    the scene see pbrt-v4's lookup of the file's world direction (ours with x negated where the reader
    negates the world's x: told by the point light at x = 1), times "scale"; with "illuminance" E the
    scale is E / k_e, k_e = 2 pi / N^2 x the sum over texels centred above the horizon of Y z (pbrt-v4's
    sum, here by the twin)."""
    image = a_map(8, 8)
    write_exr(tmp_path / "octa.exr", image)
    path = tmp_path / "s.pbrt"
    path.write_text(mirror + PBRT.format(extra='"float scale" [ 1.5 ]'))
    raw = pbrt.read_scene(path)
    point, env = raw["light"]
    assert env["map"] == str(tmp_path / "octa.exr") and env["mapping"] == "octahedral" and env["scale"] == 1.5
    x = point["position"][0]  # the reader's world x factor
    assert abs(x) == 1.0 and env.get("mirror", False) == (x < 0)  # our frame's handedness follows the world's
    raw["light"], raw["camera"]["spp"] = [env], 1
    sc = scene_from_text(to_toml(raw), str(tmp_path / "s.toml"), tmp_path / "s.toml")
    seen = api.render(sc, "quadrature").array.reshape(-1, 3)
    from raytrace.camera import generate_rays

    dirs = generate_rays(sc.camera)[1] * [x, 1.0, 1.0]  # pbrt's world
    c, s = math.cos(math.pi / 6), math.sin(math.pi / 6)
    M = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]) @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    np.testing.assert_allclose(seen, 1.5 * pbrt_lookup(image, dirs, np.linalg.inv(M)), rtol=1e-12)
    path.write_text(mirror + PBRT.format(extra='"float illuminance" [ 2 ]'))
    env = pbrt.read_scene(path)["light"][1]
    cc = (np.arange(8) + 0.5) / 8
    z = clarberg_square_to_sphere(*np.meshgrid(cc, cc))[..., 2]  # rows: v
    k_e = 2 * math.pi / 64 * np.sum(np.where(z > 0, (image @ LUMA) * z, 0.0))
    assert env["scale"] == pytest.approx(2.0 / k_e, rel=1e-12)


def test_a_pbrt_octahedral_map_round_trips(tmp_path):
    """TOML (an octahedral map turned, mirrored, scaled) -> pbrt -> TOML: the same map, scale, mapping,
    mirror and rotation (its matrix to 1e-12); the file names the map by its absolute path under a
    ConcatTransform; the twice-read light sees the same radiance along random directions."""
    write_exr(tmp_path / "octa.exr", a_map(8, 8))
    light = {"type": "environment", "map": "octa.exr", "mapping": "octahedral", "rotate": ROTATE, "mirror": True,
             "scale": 0.75}
    raw = {"camera": {**CAMERA, "spp": 1}, "light": [light], "medium": VACUUM}
    (tmp_path / "s.toml").write_text(to_toml(raw))
    out = tmp_path / "out" / "s.pbrt"
    out.parent.mkdir()
    pbrt.export(raw, out, str(tmp_path / "s.toml"), False)
    text = out.read_text()
    assert f'LightSource "infinite" "string filename" [ "{tmp_path / "octa.exr"}" ] "float scale" [ 0.75 ]' in text
    (back,) = pbrt.read_scene(out)["light"]
    assert back["map"] == str(tmp_path / "octa.exr") and back["scale"] == 0.75 and back["mapping"] == "octahedral"
    assert back["mirror"] is True
    np.testing.assert_allclose(rotation_matrix(back["rotate"]), rotation_matrix(ROTATE), atol=1e-12)
    first = scene([light], path=tmp_path / "s.toml").lights[0]
    second = scene([back], path=tmp_path / "b.toml").lights[0]
    d = unit(2000)
    np.testing.assert_array_equal(environment.radiance(second, d), environment.radiance(first, d))


@pytest.mark.parametrize("keys,shape,message", [
    ({"mapping": "octahedral"}, (4, 8), "light[0].map: {path} is 8 x 4: an octahedral map is square; give a square"),
    ({"mapping": "octahedral", "filter": "bilinear"}, (4, 4),
     "light[0].filter: an octahedral map is looked up nearest (as pbrt-v4), not 'bilinear'; remove light[0].filter"),
    ({"filter": "mitsuba"}, (2, 4), "light[0].map: {path} has 2 rows: the mitsuba filter needs at least 3; give a"),
    ({"filter": "cubic"}, (4, 8), "light[0].filter"),
    ({"mapping": "cube"}, (4, 8), "light[0].mapping"),
    ({"mirror": 1}, (4, 8), "light[0].mirror: expected true or false, got 1; write light[0].mirror = true"),
    ({"radiance": [1.0, 1.0, 1.0], "filter": "bilinear"}, None,
     "light[0].filter: applies to a map, not a constant radiance; remove light[0].filter")])
def test_bad_map_keys_are_one_line_errors(tmp_path, keys, shape, message):
    light = {"type": "environment", **keys}
    if shape:
        write_exr(tmp_path / "sky.exr", np.ones((*shape, 3), np.float32))
        light["map"] = "sky.exr"
    with pytest.raises(UserError) as err:
        scene([light], path=tmp_path / "env.toml")
    text = str(err.value)
    assert message.format(path=tmp_path / "sky.exr") in text and "\n" not in text, text


def test_describe_names_the_mapping_and_filter(tmp_path):
    light = map_light(tmp_path, a_map(8, 8), mapping="octahedral", mirror=True)
    assert describe(light).startswith(f"environment, map {tmp_path / 'sky.exr'} (8 x 8, octahedral), mirrored, mean")
    light = map_light(tmp_path, a_map(4, 8), filter="mitsuba")
    assert describe(light).startswith(f"environment, map {tmp_path / 'sky.exr'} (8 x 4, mitsuba), mean radiance")


def test_pbrt_map_refusals(tmp_path):
    """One line each, naming the file and line: a portal, "L" with "filename", a missing or non-EXR file,
    a non-square map, a stretched light frame, an "illuminance" of a map black above the horizon."""
    write_exr(tmp_path / "octa.exr", a_map(8, 8))
    write_exr(tmp_path / "wide.exr", a_map(4, 8))
    dark = a_map(8, 8)
    c = (np.arange(8) + 0.5) / 8
    dark[clarberg_square_to_sphere(*np.meshgrid(c, c))[..., 2] > 0] = 0.0
    write_exr(tmp_path / "dark.exr", dark)
    (tmp_path / "sky.png").write_bytes(b"")
    head = 'LookAt 0 0 0  0 0 -1  0 1 0\nCamera "perspective"\nWorldBegin\n'
    for world, needle in [
            ('LightSource "infinite" "string filename" "octa.exr" "point3 portal" [ 0 0 0 1 0 0 1 1 0 0 1 0 ]',
             '"point3 portal" (a portal light) is not read'),
            ('LightSource "infinite" "string filename" "octa.exr" "rgb L" [ 1 1 1 ]', 'both "L" and "filename"'),
            ('LightSource "infinite" "string filename" "none.exr"', "none.exr is not found"),
            ('LightSource "infinite" "string filename" "sky.png"', "sky.png is not an OpenEXR file"),
            ('LightSource "infinite" "string filename" "wide.exr"', "is 8 x 4: pbrt-v4's maps are square"),
            ('Scale 1 2 1 LightSource "infinite" "string filename" "octa.exr"', "a non-uniform scale or shear"),
            ('LightSource "infinite" "string filename" "dark.exr" "float illuminance" 3', "black above the horizon")]:
        (tmp_path / "s.pbrt").write_text(head + world + "\n")
        with pytest.raises(UserError) as err:
            pbrt.read_scene(tmp_path / "s.pbrt")
        assert needle in str(err.value) and "s.pbrt:4" in str(err.value) and "\n" not in str(err.value), str(err.value)
