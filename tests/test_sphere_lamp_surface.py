"""Surfaces lit by a sphere light: the unshadowed irradiance of the sphere at a surface point in a
homogeneous medium by the 1-D rule about its centre (raytrace/lights/sphere_irradiance.py), in place
of the emitter's rows, against references built from the geometry alone:
- the rule alone against scipy (nested quad over the cap's polar angle and azimuth, the transmittance
  exp(-kt s) to the sphere along each direction) and, in the vacuum, against the closed form of a sphere
  clipped by the horizon (Snyder's, in mpmath at 40 digits), at random points whose cap lies wholly
  above the horizon, straddles it or barely rises above it, 1.0001 to 100 radii from the centre;
- whole renders of a floor under a sphere lamp (above it, and sunk halfway into it: the floor's horizon
  cuts every cap), in the vacuum and in a medium that only absorbs (no air-light), against the same
  references times the transmittance to the camera: within 1e-6 at rtol and precision 1e-6, where
  the rows alone (capped at 512) are about 1e-3 off.
"""
from __future__ import annotations

import dataclasses
import math

import mpmath as mp
import numpy as np
import pytest
from scipy import integrate

from raytrace import api
from raytrace.lights import Lights
from raytrace.lights.cubature import AREA_LADDER
from raytrace.lights.sphere_irradiance import irradiance
from raytrace.methods import registry
from raytrace.rendering.renderer import prepare, shade_rays
from raytrace.scene.format import scene_from_text

from .conftest import to_toml

R = 0.3


def snyder(theta: float, d: float, radius: float) -> float:
    """E / L of a sphere of angular radius asin(radius / d) whose axis is at the angle theta from the
    normal, clipped by the horizon (Snyder's closed form, as in Lagarde and de Rousiers, "Moving
    Frostbite to PBR", 2014), in mpmath at 40 digits (the float form cancels where the horizon cuts)."""
    with mp.workdps(40):
        th, d, r = mp.mpf(theta), mp.mpf(d), mp.mpf(radius)
        ct, st, sa2 = mp.cos(th), mp.sin(th), (r / d) ** 2
        if ct * ct > sa2:
            return float(mp.pi * sa2 * max(ct, 0))
        x = mp.sqrt(1 / sa2 - 1)
        y = -x * ct / st
        sty = st * mp.sqrt(1 - y * y)
        return float(max((ct * mp.acos(y) - x * sty) * sa2 + mp.atan(sty / x), 0))


def cap_integral(theta: float, d: float, radius: float, kt: float) -> float:
    """E / L by scipy: int over the cap (beta from the axis, azimuth phi) of max(0, n·w) exp(-kt s) dw,
    s the distance to the sphere along w; split where the horizon starts cutting the circles of the
    cap and, along each circle, where it does."""
    ct, st, alpha = math.cos(theta), math.sin(theta), math.asin(radius / d)

    def along(beta):
        a, b = ct * math.cos(beta), st * math.sin(beta)
        s = d * math.cos(beta) - math.sqrt(max(0.0, radius * radius - (d * math.sin(beta)) ** 2))
        end = math.acos(-a / b) if b > abs(a) else (math.pi if a > 0.0 else 0.0)
        f = integrate.quad(lambda p: a + b * math.cos(p), 0.0, end, epsabs=0.0, epsrel=1e-12, limit=200)[0]
        return 2.0 * f * math.sin(beta) * math.exp(-kt * s)

    kink = abs(math.pi / 2 - theta)
    edges = [0.0, kink, alpha] if kink < alpha else [0.0, alpha]
    return sum(integrate.quad(along, lo, hi, epsabs=0.0, epsrel=1e-13, limit=200)[0] for lo, hi in zip(edges, edges[1:]))


def points(seed: int, count: int):
    """(theta, d) of `count` random points, a third each with the cap wholly above the horizon,
    straddling it, and barely above it (the edge a relative 1e-3 of alpha or less over it)."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(count):
        d = R * math.exp(rng.uniform(math.log(1.0001), math.log(100.0)))
        alpha = math.asin(R / d)
        theta = (rng.uniform(0.0, math.pi / 2 - alpha), rng.uniform(math.pi / 2 - alpha, math.pi / 2 + alpha),
                 math.pi / 2 + alpha - abs(rng.normal(0.0, 1e-3)) * alpha)[i % 3]
        out.append((theta, d))
    return out


def rule(theta, d, kt, tol):
    """The rule's E / L at the origin, normal at theta from the axis toward the centre (0, d, 0)."""
    n = np.array([[math.sin(theta), math.cos(theta), 0.0]])
    return irradiance([0.0, d, 0.0], R, np.ones(3), np.zeros((1, 3)), n, np.full(3, kt), tol)[0, 0]


@pytest.mark.parametrize("kt", [0.0, 0.15, 3.0])
def test_the_rule_against_scipy_over_the_cap(kt):
    """Within 1e-6 at tol 1e-6 and 1e-9 at tol 1e-9 of scipy (its own agreement with the closed form
    in the vacuum: 1e-9), 30 points of each kind of cap (1.0001 to 100 radii away)."""
    for theta, d in points(1, 30):
        ref = cap_integral(theta, d, R, kt)
        for tol in (1e-6, 1e-9):
            assert abs(rule(theta, d, kt, tol) / ref - 1.0) <= tol, (theta, d, kt, tol)


def test_the_rule_in_the_vacuum_against_the_closed_form():
    """In the vacuum the closed form of the clipped sphere, exact here (mpmath), confirms 1e-11 at tol
    1e-10 (measured about 2e-12) and 1e-6 at tol 1e-6, on 60 points; scipy agrees with it to 1e-9."""
    for theta, d in points(2, 60):
        ref = snyder(theta, d, R)
        assert abs(rule(theta, d, 0.0, 1e-6) / ref - 1.0) <= 1e-6, (theta, d)
        assert abs(rule(theta, d, 0.0, 1e-10) / ref - 1.0) <= 1e-11, (theta, d)
    for theta, d in points(3, 9):
        assert abs(cap_integral(theta, d, R, 0.0) / snyder(theta, d, R) - 1.0) <= 1e-9


def test_edge_cases():
    """0 wholly below the horizon and on or inside the sphere; pi (the hemisphere) a rounding's width
    outside it; pi sin^2 alpha cos theta wholly above in the vacuum; each channel's transmittance its own."""
    c = [0.0, 1.0, 0.0]
    down, up = np.array([[0.0, -1.0, 0.0]]), np.array([[0.0, 1.0, 0.0]])
    assert not irradiance(c, R, np.ones(3), np.zeros((1, 3)), down, np.zeros(3)).any()
    inside = np.array([[0.0, 1.0 - R, 0.0], [0.0, 1.1, 0.0], [0.0, 1.0 + R, 0.0]])
    assert not irradiance(c, R, np.ones(3), inside, np.repeat(up, 3, axis=0), np.zeros(3))[1:].any()
    # 1.0 - R rounds to a point 5.6e-17 outside: it sees a hemisphere of the lamp
    assert abs(irradiance(c, R, np.ones(3), inside[:1], up, np.zeros(3))[0, 0] / math.pi - 1.0) <= 1e-13
    e = irradiance(c, R, np.array([1.0, 2.0, 3.0]), np.zeros((1, 3)), up, np.array([0.0, 0.15, 3.0]))[0]
    assert abs(e[0] / (math.pi * R * R) - 1.0) <= 1e-14
    assert abs(e[1] / (2.0 * cap_integral(0.0, 1.0, R, 0.15)) - 1.0) <= 1e-12
    assert abs(e[2] / (3.0 * cap_integral(0.0, 1.0, R, 3.0)) - 1.0) <= 1e-12


KTS = (0.0, 0.15, 3.0)  # the absorbing medium's sigma_a per channel (sigma_s 0: no air-light)
CAMERA = {"position": [0.0, 2.0, 3.0], "look_at": [0.0, 0.0, 0.0], "fov": 50.0, "width": 8, "height": 6}
FLOOR = {"primitive": "quad", "corners": [[-20.0, 0.0, 20.0], [20.0, 0.0, 20.0], [20.0, 0.0, -20.0],
                                          [-20.0, 0.0, -20.0]], "reflectance": 0.5}


def floor_scene(height: float, medium):
    lamp = {"type": "sphere", "center": [0.0, height, 0.0], "radius": R, "radiance": 10.0}
    return scene_from_text(to_toml({"camera": CAMERA, "shape": [FLOOR], "light": [lamp], "medium": medium}), "lamp.toml")


def camera_rays(cam):
    """(row, column, origin, unit direction) of each pixel centre's ray of the camera table `cam`
    (`position`, `look_at`, vertical `fov` in degrees, `width`, `height`; +y up), row 0 at the top."""
    o = np.array(cam["position"])
    f = np.array(cam["look_at"]) - o
    f /= np.linalg.norm(f)
    right = np.cross(f, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, f)
    tan = math.tan(math.radians(cam["fov"]) / 2)
    w, h = cam["width"], cam["height"]
    for j in range(h):
        for i in range(w):
            d = f + (2 * (i + 0.5) / w - 1) * tan * w / h * right + (1 - 2 * (j + 0.5) / h) * tan * up
            yield j, i, o, d / np.linalg.norm(d)


def twin(height: float, kts):
    """(H, W, 3) the floor's radiance per pixel (NaN where the ray meets the lamp first): rho / pi L E
    exp(-kt t), E / L the closed form (kt 0) or scipy's cap integral, from the camera ray's hit on the
    plane y = 0 (t its distance) and the lamp's geometry alone."""
    c = np.array([0.0, height, 0.0])
    out = np.empty((CAMERA["height"], CAMERA["width"], 3))
    for j, i, o, d in camera_rays(CAMERA):
        t = -o[1] / d[1]
        oc = o - c
        disc = (d @ oc) ** 2 - (oc @ oc - R * R)
        if disc >= 0.0 and -(d @ oc) - math.sqrt(disc) < t:  # the lamp first
            out[j, i] = np.nan
            continue
        x = o + t * d
        dist = np.linalg.norm(c - x)
        theta = math.acos((c - x)[1] / dist)  # the floor's normal is +y
        for ch, kt in enumerate(kts):
            e = snyder(theta, dist, R) if kt == 0.0 else cap_integral(theta, dist, R, kt)
            out[j, i, ch] = 0.5 / math.pi * 10.0 * e * math.exp(-kt * t)
    return out


@pytest.mark.parametrize("height", [1.0, 0.2])
@pytest.mark.parametrize("medium", ["vacuum", "absorbing"])
def test_a_floor_under_a_sphere_lamp_against_the_twin(height, medium):
    """Every floor pixel within 1e-6 of the twin with quadrature (rtol 1e-6) and analytic (precision
    1e-6): the lamp 1 above the floor (every cap wholly above its horizon) and sunk to 0.2 (the
    floor's horizon cuts every cap). The rows alone, capped at 512, are about 1e-3 off."""
    kts = KTS if medium == "absorbing" else (0.0,) * 3
    sc = floor_scene(height, {"sigma_a": list(kts), "sigma_s": 0.0} if medium == "absorbing" else {})
    ref = twin(height, kts)
    floor = ~np.isnan(ref[..., 0])
    assert floor.sum() >= 40
    for method, params in (("quadrature", {"rtol": 1e-6}), ("analytic", {"precision": 1e-6})):
        img = api.render(sc, method, **params)
        rel = np.abs(img.array[floor] / ref[floor] - 1.0)
        assert rel.max() <= 1e-6, (method, rel.max())


@pytest.mark.parametrize("order", AREA_LADDER)
def test_the_sunk_lamps_floor_at_every_cubature_order(monkeypatch, order):
    """The floor under the lamp sunk to 0.2, 32x24, with the rows of every order the pilot may choose:
    every floor pixel within 1e-6 of the twin. Where nothing can hide the lamp (`_free`) the closed form
    applies even where the rows that emit toward a point are all blocked by the floor (they lie below its
    horizon): before, at order 16 one pixel at the lamp's foot was dark and one sampled 5x too bright."""
    cam = dict(CAMERA, width=32, height=24)
    monkeypatch.setitem(globals(), "CAMERA", cam)
    sc = floor_scene(0.2, {})
    ref = twin(0.2, (0.0,) * 3)
    floor = ~np.isnan(ref[..., 0])
    rays = list(camera_rays(cam))
    prep = prepare(sc)
    prep = dataclasses.replace(prep, lights=Lights.of(sc.lights, prep.emissive, (order,)), _memo={})
    rad = shade_rays(prep, registry()["quadrature"], {"rtol": 1e-6}, np.array([r[2] for r in rays]),
                     np.array([r[3] for r in rays]), np.arange(len(rays), dtype=np.uint64), 0)[0]
    img = rad.reshape(cam["height"], cam["width"], 3)
    rel = np.abs(img[floor] / ref[floor] - 1.0)
    assert rel.max() <= 1e-6, (order, np.argwhere(rel > 1e-6))


def test_points_the_rule_leaves_unconverged_are_counted():
    """`irradiance`'s `missed` counts the points where no three successive orders of its ladder agreed: at
    300 random points 1.0005 to 4 radii from the sphere in the vacuum, at tolerance 1e-12, none is counted
    and every point is within 1e-12 of Snyder's closed form (mpmath) (before, 6 near the sphere were
    counted, up to 3e-11 off); at 1e-16, below the rounding, every point whose cap the horizon cuts is counted
    and no other (the vacuum's wholly lit caps are exact); a render's summary carries the count
    ("surface: closed form not converged", 0 on the sunk lamp's floor at rtol 1e-6)."""
    rng = np.random.default_rng(1)
    n = 300
    pts = rng.normal(size=(n, 3))
    pts *= (1.0005 + 3.0 * rng.random(n) ** 3)[:, None] / np.linalg.norm(pts, axis=1)[:, None]
    nrm = rng.normal(size=(n, 3))
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    counted, good, cut = 0, 0, 0
    for p, nn in zip(pts, nrm):
        d = float(np.linalg.norm(p))
        ref = float(snyder(math.acos(max(-1.0, min(1.0, float(-p @ nn) / d))), d, 1.0))
        missed, below = np.zeros(1), np.zeros(1)
        e = irradiance([0.0, 0.0, 0.0], 1.0, np.ones(3), p[None, :], nn[None, :], np.zeros(3), 1e-12, missed)[0, 0]
        irradiance([0.0, 0.0, 0.0], 1.0, np.ones(3), p[None, :], nn[None, :], np.zeros(3), 1e-16, below)
        counted += int(missed[0])
        cuts = abs(float(-p @ nn)) < 1.0  # |cos theta| < sin alpha: the horizon cuts the cap
        cut += cuts
        assert below[0] == cuts, (p, nn)
        if ref > 0.0:
            assert abs(e / ref - 1.0) <= 1e-12, (p, nn, e, ref)
            good += 1
    assert counted == 0 and good >= 150 and cut >= 100
    stats = api.render(floor_scene(0.2, {}), "quadrature", rtol=1e-6).stats
    assert stats["surface: closed form not converged"] == 0


def test_smooth_shading_takes_the_rule_where_the_geometric_plane_leaves_the_cap_whole():
    """With a shading normal apart from the geometric one the rule (on the shading normal) applies where
    the cap lies wholly above the geometric plane, not where that plane cuts it (it bounds what is lit
    too); with equal normals everywhere."""
    lamp = floor_scene(1.0, {}).lights[0]
    from raytrace.lights import sphere

    x = np.zeros((3, 3))
    geometric = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    shading = np.array([[0.6, 0.8, 0.0], [0.6, 0.8, 0.0], [1.0, 0.0, 0.0]])
    e, applies = sphere.surface_irradiance(lamp, x, geometric, shading, np.zeros(3), 1e-9)
    assert applies.tolist() == [True, False, True]
    theta = math.acos(0.8)
    assert abs(e[0, 0] / (10.0 * snyder(theta, 1.0, R)) - 1.0) <= 1e-9
    assert abs(e[2, 0] / (10.0 * snyder(math.pi / 2, 1.0, R)) - 1.0) <= 1e-9
    assert not e[1].any()
