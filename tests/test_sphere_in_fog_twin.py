"""Houdini's pbrt-v4 exporter test TestMediums/test_exterior_cam_interior_obj_pointlight, as
benchmarks/sphere_in_fog.toml writes it (a sphere holding a medium, in fog, over a floor, lit by a
point light, seen from outside), with the exact sphere the pbrt importer reads, against a twin built
from the geometry alone (scipy, no project code): every pixel with volumetric shadows, by every method
that takes the scene, within its law.

The twin: along the camera ray o + t d, the light scattered at x(t) is sigma_s(x) p(cos) I / |L - x|^2
exp(-tau), tau the optical depth of the camera's path to x and of the light's path from x, each split
into its length inside the sphere (the chord of the segment, in closed form) and outside it; a floor
hit adds rho / pi I cos / |L - y|^2 exp(-tau). The integral is split where the ray enters and leaves
the sphere, where the light's segment to x(t) touches the sphere (the edge of its shadow in the fog:
the ray's crossings of the light's tangent cone, in closed form) and about the light's foot point,
scipy quad at 1e-11.
"""
from __future__ import annotations

import functools
import math
import pathlib

import numpy as np
import pytest
from scipy import integrate

from raytrace import api
from raytrace.errors import UserError
from raytrace.scene.format import scene_from_text

from .conftest import to_toml
from .oracle import camera_ray, phase

SCENE_FILE = pathlib.Path(__file__).resolve().parents[1] / "benchmarks" / "sphere_in_fog.toml"
CENTRE, R = np.array([0.0, 1.0, 0.0]), 1.0
LIGHT, INTENSITY = np.array([2.0, 4.0, 2.0]), 50.0
KA_OUT, KS_OUT = 0.01, 0.05
KA_IN, KS_IN, G_IN = 0.5, 1.0, 0.4
RHO = 0.5
# the floor made wide enough that every downward camera ray meets it (points under it are not lit)
CAMERA = {"position": [0.0, 2.2, 6.0], "look_at": [0.0, 0.8, 0.0], "fov": 40.0, "width": 10, "height": 8, "spp": 1}


@functools.cache
def scene_dict() -> dict:
    """benchmarks/sphere_in_fog.toml with an exact sphere whose medium scatters forward (HG 0.4), a wider
    floor and this test's small camera."""
    import tomllib

    sc = tomllib.loads(SCENE_FILE.read_text())
    floor, sphere = sc["shape"]
    assert sphere["center"] == CENTRE.tolist() and sphere["radius"] == R and sc["light"][0]["position"] == LIGHT.tolist()
    assert (sc["medium"]["sigma_a"], sc["medium"]["sigma_s"], floor["reflectance"]) == (KA_OUT, KS_OUT, RHO)
    assert (sphere["interior"]["sigma_a"], sphere["interior"]["sigma_s"]) == (KA_IN, KS_IN)
    floor = floor | {"corners": [[-1e3, 0.0, -1e3], [1e3, 0.0, -1e3], [1e3, 0.0, 1e3], [-1e3, 0.0, 1e3]]}
    sphere = sphere | {"exact": True, "interior": sphere["interior"] | {"phase": {"type": "hg", "g": G_IN}}}
    return sc | {"camera": CAMERA, "shape": [floor, sphere]}


def scene():
    return scene_from_text(to_toml(scene_dict()), "sphere_in_fog.toml")


def chord(x, u, length):
    """Length of the segment x + s u, 0 <= s <= length, inside the sphere."""
    b = float((x - CENTRE) @ u)
    q = b * b - (float((x - CENTRE) @ (x - CENTRE)) - R * R)
    if q <= 0.0:
        return 0.0
    return max(0.0, min(-b + math.sqrt(q), length) - max(-b - math.sqrt(q), 0.0))


def touches(x) -> float:
    """The light's segment from x: its squared distance to the centre less R^2 (negative: it crosses)."""
    u = LIGHT - x
    s = min(max(float((CENTRE - x) @ u) / float(u @ u), 0.0), 1.0)
    p = x + s * u - CENTRE
    return float(p @ p) - R * R


def shadow_edges(o, d) -> list:
    """The t where the light's segment to o + t d touches the sphere: the ray's crossings of the
    tangent cone from the light (apex L, axis toward the centre, cos^2 of its half-angle 1 - R^2 /
    |C - L|^2) beyond its circle of contact (axial distance |C - L| cos^2 from L), a quadratic in t."""
    a = (CENTRE - LIGHT) / np.linalg.norm(CENTRE - LIGHT)
    far = float(np.linalg.norm(CENTRE - LIGHT))
    c2 = 1.0 - (R / far) ** 2
    w = o - LIGHT
    wa, da, wd = float(w @ a), float(d @ a), float(w @ d)
    qa, qb, qc = da * da - c2, 2.0 * (wa * da - c2 * wd), wa * wa - c2 * float(w @ w)
    disc = qb * qb - 4.0 * qa * qc
    if disc < 0.0:
        return []
    roots = [(-qb - math.sqrt(disc)) / (2.0 * qa), (-qb + math.sqrt(disc)) / (2.0 * qa)]
    return [t for t in roots if t > 0.0 and wa + t * da >= far * c2]


def twin_pixel(i: int, j: int) -> np.ndarray:
    """The pixel centre's radiance (module docstring)."""
    o, d = camera_ray(CAMERA, i, j)
    t_floor = -o[1] / d[1] if d[1] < 0.0 else math.inf
    b = float((o - CENTRE) @ d)
    q = b * b - (float((o - CENTRE) @ (o - CENTRE)) - R * R)
    s0, s1 = (-b - math.sqrt(q), -b + math.sqrt(q)) if q > 0.0 else (math.inf, math.inf)
    kt_out, kt_in = KA_OUT + KS_OUT, KA_IN + KS_IN

    def depth(x, t):
        """Optical depth of the camera's path to x = x(t) and of the light's path from x."""
        to = LIGHT - x
        dist = math.sqrt(float(to @ to))
        inside_cam = max(0.0, min(t, s1) - s0)
        inside_light = chord(x, to / dist, dist)
        return kt_out * (t - inside_cam + dist - inside_light) + kt_in * (inside_cam + inside_light), to / dist, dist

    def f(t):
        x = o + t * d
        tau, u, dist = depth(x, t)
        inside = s0 < t < s1
        ks, g = (KS_IN, G_IN) if inside else (KS_OUT, 0.0)
        return ks * phase("hg", g, float(u @ d)) * INTENSITY / dist**2 * math.exp(-tau)

    end = t_floor if t_floor < math.inf else 2e3  # exp(-0.06 * 2e3): nothing beyond
    breaks = shadow_edges(o, d)
    for t in breaks:  # the segment touches there: crossing on one side, clear on the other
        assert abs(touches(o + t * d)) < 1e-9 and touches(o + (t - 1e-6) * d) * touches(o + (t + 1e-6) * d) < 0.0
    xh = float((LIGHT - o) @ d)
    h = float(np.linalg.norm(np.cross(LIGHT - o, d)))
    breaks += [s0, s1] + [x for x in (xh - 10 * h, xh - h, xh, xh + h, xh + 10 * h)]
    edges = [0.0] + sorted(x for x in breaks if 0.0 < x < end) + [end]
    out = sum(integrate.quad(f, a, c, epsabs=0.0, epsrel=1e-11, limit=400)[0] for a, c in zip(edges, edges[1:]))
    if t_floor < math.inf:
        y = o + t_floor * d
        tau, u, dist = depth(y, t_floor)
        out += RHO / math.pi * INTENSITY * max(0.0, u[1]) / dist**2 * math.exp(-tau)
    return np.full(3, out)


@functools.cache
def twin_image() -> np.ndarray:
    return np.array([[twin_pixel(i, j) for i in range(CAMERA["width"])] for j in range(CAMERA["height"])])


def test_the_scene_has_pixels_of_every_kind():
    """Rays through the sphere, through its shadow in the fog, onto the floor in its shadow and beside
    it, and into the sky: the twin's pieces all occur."""
    kinds = set()
    for j in range(CAMERA["height"]):
        for i in range(CAMERA["width"]):
            o, d = camera_ray(CAMERA, i, j)
            b = float((o - CENTRE) @ d)
            through = b * b - (float((o - CENTRE) @ (o - CENTRE)) - R * R) > 0.0
            floor = d[1] < 0.0
            shade = floor and touches(o - o[1] / d[1] * d) < 0.0
            kinds |= {("sphere", through), ("floor", floor), ("shadow", shade)}
    assert kinds == {(k, v) for k in ("sphere", "floor", "shadow") for v in (True, False)}


def test_quadrature_against_the_twin():
    """quadrature at rtol 1e-8 with volumetric shadows: every pixel within 1e-7 of the twin, inside its
    error bound (plus 1e-12 of the value for the bound's own rounding), the bound finite on every pixel
    (those with pieces whose light crosses the sphere too: the fog in its shadow, the floor behind it,
    media/convex_chords.py's rule and the exact sphere's chord rounding) and not vacuous: median at
    most 10 rtol of the value."""
    ref = twin_image()
    img = api.render(scene(), "quadrature", rtol=1e-8, volumetric_shadows=True)
    err = np.abs(img.array - ref)
    assert np.max(err / ref) < 1e-7, np.max(err / ref)
    assert np.all(err <= img.error_bound + 1e-12 * ref)
    assert np.all(np.isfinite(img.error_bound)) and np.median(img.error_bound / ref) <= 10 * 1e-8


def test_quadrature_bound_at_rtol_1e_10():
    """The same at rtol 1e-10 on the pixels whose fog lies in the sphere's shadow (rows 3 and 4, columns
    2 to 5: every one has pieces whose light crosses the sphere): within 1e-9 of the twin (scipy at
    1e-11), inside the bound plus the twin's own 1e-11, the bound at most 10 rtol of the value on the
    median, finite on every pixel: pixel (4, 4) holds a piece 2.4e-3 long that starts on the light's tangent
    cone (its chord 6e-8 there), a kink within END_SNAP of the scene's scale of the piece's start, taken as
    that start (media/convex_chords.py `boundary_kinks`; snapped within END_SNAP of the piece's length, the
    chord's rounding kept the rule from meeting 1e-10 and the bound was inf there)."""
    ref = twin_image()[3:5, 2:6]
    img = api.render(scene(), "quadrature", rtol=1e-10, volumetric_shadows=True, crop=(2, 3, 6, 5))
    err = np.abs(img.array - ref)
    assert np.max(err / ref) < 1e-9, np.max(err / ref)
    assert np.all(err <= img.error_bound + 1e-11 * ref)
    finite = np.isfinite(img.error_bound).all(axis=2)
    assert finite.all(), np.argwhere(~finite)
    assert np.median(img.error_bound[finite] / ref[finite]) <= 10 * 1e-10


def test_quadrature_bound_with_the_lamp_inside_the_sphere(monkeypatch):
    """The lamp moved inside the sphere, to (0, 1.3, 0.4): the light of every point of the fog outside
    crosses it (the chord ends at the lamp, so its rounding holds the distance's), at rtol 1e-8: every
    pixel within 1e-7 of the twin (no shadow edges now), inside its bound, the bound finite on every
    pixel and at most 10 rtol of the value on the median."""
    import sys

    light = np.array([0.0, 1.3, 0.4])
    sc = scene_dict() | {"light": [scene_dict()["light"][0] | {"position": light.tolist()}]}  # the cached one kept
    module = sys.modules[__name__]
    monkeypatch.setattr(module, "LIGHT", light)
    monkeypatch.setattr(module, "shadow_edges", lambda o, d: [])
    ref = np.array([[twin_pixel(i, j) for i in range(CAMERA["width"])] for j in range(CAMERA["height"])])
    img = api.render(scene_from_text(to_toml(sc), "lamp in the sphere"), "quadrature", rtol=1e-8,
                     volumetric_shadows=True)
    err = np.abs(img.array - ref)
    assert np.max(err / ref) < 1e-7, np.max(err / ref)
    assert img.stats["shadows: pieces through interiors (quadrature)"] > 0
    assert np.all(err <= img.error_bound + 1e-12 * ref)
    assert np.all(np.isfinite(img.error_bound)) and np.median(img.error_bound / ref) <= 10 * 1e-8


def test_analytic_refuses_naming_the_methods_that_take_it():
    """analytic has no closed form for a point light into a medium inside a shape; slab_approx is an
    approximation there, held to the slab note's formula elsewhere (tests/test_bounded_media.py)."""
    with pytest.raises(UserError, match="no closed form.*use --method quadrature, raymarch, montecarlo"):
        api.render(scene(), "analytic", volumetric_shadows=True)


def test_raymarch_converges_to_the_twin():
    """raymarch's error falls as its steps grow, to within 1e-3 of the twin at 1024 steps."""
    ref = twin_image()
    errors = [float(np.max(np.abs(api.render(scene(), "raymarch", steps=n, volumetric_shadows=True).array - ref)
                           / ref)) for n in (64, 1024)]
    assert errors[1] < errors[0] / 4 and errors[1] < 1e-3, errors


def test_montecarlo_is_unbiased_against_the_twin():
    """montecarlo, 64 samples, two seeds: z-scores against the twin with its own variance."""
    ref = twin_image()
    z = []
    for seed in (3, 4):
        img = api.render(scene(), "montecarlo", samples=64, seed=seed, volumetric_shadows=True)
        assert np.all(img.variance > 0.0)
        z.append((img.array - ref) / np.sqrt(img.variance))
    z = np.array(z)
    assert np.mean(z**2) < 1.6 and np.max(np.abs(z)) < 5.0, (np.mean(z**2), np.max(np.abs(z)))
