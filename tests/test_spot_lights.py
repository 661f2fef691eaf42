"""Spot lights (issue 10): the closed-form air-light and the quadrature against the independent
oracle (tests/oracle.py: scipy quad in the distance, cone crossings found by bracketing), on random
segments and on the hard cases: cone angles from 1 to 179 degrees, hard edges, rays along the
cone's edge and core, rays through the apex, the light looking away from the camera. Requirement:
within 10 x precision (analytic, precision 1e-6) and 1e-9 (quadrature, rtol 1e-12).

Also the scene-file contract: bad spot lights and spot lights in methods that cannot take them
give one line and exit 2, with nothing written.

The three falloff curves (`falloff` = "smoothstep", "mitsuba", "gltf") against the oracle's curves
written from their specifications (pbrt-v4, Mitsuba 3's spot.cpp, KHR_lights_punctual): values,
the glTF band's trigonometric form, random segments, and a room with a plate shadowing the beam
rendered by every method that takes spot lights, judged as the methods' own error laws say.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from raytrace.cli import main
from raytrace.lights import CURVES, DIRECTIONAL, GLTF, MITSUBA, SMOOTHSTEP, SPOT as SPOT_KIND, Light, Lights, \
    band_trig, falloff, light_sample
from raytrace.media.phase import HG, ISOTROPIC, RAYLEIGH
from raytrace.methods import analytic as A
from raytrace.methods import quadrature as Q
from raytrace.methods.geometry import segment_light_table

from . import oracle
from .conftest import box_room

PRECISION = 1e-6
PHASES = [(ISOTROPIC, 0.0, "isotropic"), (RAYLEIGH, 0.0, "rayleigh"), (HG, 0.5, "hg"), (HG, 0.9, "hg"),
          (HG, -0.5, "hg")]


def spot(axis, cone, start):
    axis = np.asarray(axis, float)
    return axis / np.linalg.norm(axis), math.cos(math.radians(cone)), math.cos(math.radians(start))


def renderer_pair(o, w, ell, p, sp, kt, ks, code, g, precision=PRECISION, curve="smoothstep"):
    """(analytic, quadrature, analytic stats) for one segment, through the renderer's geometry."""
    xh, h, da, row = segment_light_table(o[None], w[None], p[None], sp[0][None],
                                         np.array([[sp[1], sp[2], CURVES[curve]]]), np.zeros(1, np.int64), 1.0)
    wp = A.working_precision(precision)
    coeffs = A.make_coeffs(code, g, A.ANISO_EXACT, 6, wp)
    st = A.new_stats()
    an = A.airlight(xh[0], h[0], da[0], ell, kt, ks, 1.0, code, g, wp, 1000, A.ANISO_EXACT, 6, coeffs, row[0], st)
    qu = Q.airlight_one(xh[0], h[0], ell, kt, ks, code, g, row[0], 1e-12, Q.N10, Q.W10, Q.N20, Q.W20,
                        np.zeros(3))
    return an, qu, st


def check(o, w, ell, p, sp, kt, ks, code, g, name, curve="smoothstep"):
    o, w, p = (np.asarray(v, float) for v in (o, w, p))
    w = w / np.linalg.norm(w)
    ref = oracle.airlight(o, w, ell, p, 1.0, kt, ks, name, g, sp, curve)
    an, qu, st = renderer_pair(o, w, ell, p, sp, kt, ks, code, g, curve=curve)
    assert math.isfinite(an) and an >= 0.0 and math.isfinite(qu)
    if ref == 0.0:
        assert an == 0.0 and qu == 0.0
        return st
    assert abs(an - ref) <= 10 * PRECISION * ref, (an, ref, abs(an / ref - 1))
    assert abs(qu - ref) <= 1e-9 * ref, (qu, ref, abs(qu / ref - 1))
    return st


@pytest.mark.parametrize("code,g,name", PHASES)
def test_random_spot_segments_match_the_oracle(code, g, name):
    """24 random segments per phase function: random light, axis, cone in [1, 179] degrees and
    core in [0, cone] (a quarter with hard edges), lengths 0.5-6 and rays to infinity."""
    rng = np.random.default_rng(100 + int(10 * g) + code)
    bands = lit = 0
    for _ in range(24):
        o, p = rng.uniform(-2, 2, 3), rng.uniform(-2, 2, 3)
        w = rng.normal(size=3)
        cone = float(rng.uniform(1.0, 179.0))
        start = cone if rng.random() < 0.25 else float(rng.uniform(0.0, cone))
        ell = math.inf if rng.random() < 0.2 else float(rng.uniform(0.5, 6.0))
        st = check(o, w, ell, p, spot(rng.normal(size=3), cone, start), 0.3, 0.2, code, g, name)
        bands += st[A.ST_BANDS]
        lit += st[A.ST_EVALS] > st[A.ST_ZERO]
    assert bands > 0 and lit > 8  # the cases exercise the smoothstep band's closed form


@pytest.mark.parametrize("code,g,name", PHASES)
@pytest.mark.parametrize("cone,start", [(1.0, 0.5), (1.0, 1.0), (30.0, 20.0), (90.0, 0.0), (179.0, 120.0),
                                        (179.0, 179.0)])
def test_beam_crossing_the_view(code, g, name, cone, start):
    """A ray crossing the beam 3 units from the light, perpendicular to the axis and through it, for
    cone angles from 1 to 179 degrees (pieces too short in angle for the closed form go to the
    quadrature, counted)."""
    check([-4.0, 0.0, 3.0], [1.0, 0.0, 0.0], 8.0, [0.0, 0.0, 0.0], spot([0.0, 0.0, 1.0], cone, start), 0.2, 0.15,
          code, g, name)


@pytest.mark.parametrize("code,g,name", PHASES)
def test_ray_along_the_core_edge_sees_a_point_light(code, g, name):
    """A ray on a generator line of the core (cosine to the axis = cos_start all along, F = 1) gets
    the point light's air-light; on the cone's edge (F = 0) it gets none; just inside the edge, a
    little off the generator line, the oracle's value."""
    sp = spot([0.0, 0.0, 1.0], 40.0, 25.0)
    u = np.array([math.sin(math.radians(25.0)), 0.0, math.cos(math.radians(25.0))])
    p = np.zeros(3)
    an, qu, _ = renderer_pair(p + 0.5 * u, u, 5.0, p, sp, 0.3, 0.2, code, g)
    pt, _, _ = renderer_pair(p + 0.5 * u, u, 5.0, p, (sp[0], -3.0, -2.0), 0.3, 0.2, code, g)
    assert an == pytest.approx(pt, rel=10 * PRECISION) and qu == pytest.approx(pt, rel=1e-9)
    e = np.array([math.sin(math.radians(40.0)), 0.0, math.cos(math.radians(40.0))])
    an, qu, _ = renderer_pair(p + 0.5 * e, e, 5.0, p, sp, 0.3, 0.2, code, g)
    assert an == 0.0 and qu == 0.0
    check(p + 0.5 * e + np.array([-0.01, 0.003, 0.0]), e, 5.0, p, sp, 0.3, 0.2, code, g, name)


@pytest.mark.parametrize("code,g,name", PHASES)
def test_light_looking_away_from_the_camera(code, g, name):
    """The camera behind the spot, looking past it into the beam, and straight down its axis."""
    sp = spot([0.0, 0.0, -1.0], 25.0, 15.0)
    check([0.3, 0.1, 2.0], [0.05, -0.02, -1.0], 10.0, [0.0, 0.0, 0.0], sp, 0.2, 0.15, code, g, name)
    check([1.0, 0.0, 2.0], [-0.3, 0.0, -1.0], math.inf, [0.0, 0.0, 0.0], sp, 0.2, 0.15, code, g, name)


@pytest.mark.parametrize("code,g,name", PHASES)
def test_ray_through_the_apex_is_finite_and_agrees(code, g, name):
    """A ray through the light itself: the point light is regularised (geometry.H_MIN_REL), the
    value is huge but finite, and the closed form agrees with the quadrature of the same integrand;
    the part beyond the light is inside the cone, the part before it outside."""
    sp = spot([0.0, 0.0, -1.0], 30.0, 20.0)
    o, w = np.array([0.0, 0.0, 3.0]), np.array([0.0, 0.0, -1.0])
    an, qu, _ = renderer_pair(o, w, 6.0, np.zeros(3), sp, 0.2, 0.15, code, g)
    assert math.isfinite(an) and an > 0.0 and an == pytest.approx(qu, rel=10 * PRECISION)
    before, _, _ = renderer_pair(o, w, 2.9, np.zeros(3), sp, 0.2, 0.15, code, g)
    assert before == 0.0


def test_falloff_is_pbrt_smoothstep():
    ce, cs = math.cos(math.radians(30.0)), math.cos(math.radians(20.0))
    mid = 0.5 * (ce + cs)
    f = lambda c, ce, cs: falloff(c, ce, cs, SMOOTHSTEP)  # noqa: E731
    assert f(1.0, ce, cs) == 1.0 and f(ce, ce, cs) == 0.0 and f(-1.0, ce, cs) == 0.0
    assert f(mid, ce, cs) == pytest.approx(0.5)
    assert f(ce + 0.25 * (cs - ce), ce, cs) == pytest.approx(0.25**2 * (3 - 0.5))
    assert f(cs, cs, cs) == 1.0 and f(np.nextafter(cs, 0.0), cs, cs) == 0.0


def test_light_sample_against_the_lights_own_geometry():
    """light_sample's direction, distance and factor, against a spot built from degrees (its falloff
    from the angle's cosine) and against Lights.irradiance for every kind."""
    axis = np.array([0.0, -1.0, 0.0])
    ce, cs = math.cos(math.radians(30.0)), math.cos(math.radians(10.0))
    lights = Lights.of([Light(np.array([1.0, 2.0, 3.0]), np.array([1.0, 2.0, 3.0])),
                        Light(np.array([0.0, 3.0, 0.0]), np.ones(3), SPOT_KIND, axis, ce, cs, MITSUBA),
                        Light(np.zeros(3), np.full(3, 2.0), DIRECTIONAL, np.array([0.6, -0.8, 0.0]))])
    rng = np.random.default_rng(5)
    for p in rng.uniform(-2.0, 2.0, (200, 3)):
        for li in range(3):
            ux, uy, uz, dist, f = light_sample(lights.kind, lights.position, lights.axis, lights.cone, li, *p)
            if li == 2:
                assert (ux, uy, uz, dist, f) == (-0.6, 0.8, -0.0, math.inf, 1.0)
                continue
            rel = lights.position[li] - p
            assert dist == pytest.approx(np.linalg.norm(rel), rel=1e-15)
            np.testing.assert_allclose([ux, uy, uz], rel / np.linalg.norm(rel), rtol=0, atol=1e-15)
            angle = math.degrees(math.acos(np.clip(-rel @ axis / np.linalg.norm(rel), -1, 1)))
            want = 1.0 if li == 0 or angle <= 10.0 else max(0.0, (30.0 - angle) / 20.0)
            assert f == pytest.approx(want, abs=1e-12)
            e = lights.irradiance(li, (p - lights.position[li])[None, :], np.array([dist]))[0]
            np.testing.assert_allclose(lights.intensity[li] * f / dist**2, e, rtol=1e-13)
    assert light_sample(lights.kind, lights.position, lights.axis, lights.cone, 1, 0.0, 3.0, 0.0)[3:] == (0.0, 0.0)


SPOT = {"type": "spot", "position": [0.0, 1.5, -1.0], "look_at": [0.0, -2.0, -1.0], "intensity": 20.0,
        "cone_angle": 30.0, "falloff_start": 20.0}


@pytest.mark.parametrize("change,message", [
    ({"cone_angle": 0.0}, "cone_angle: must be in (0, 180)"),
    ({"cone_angle": 180.0}, "cone_angle: must be in (0, 180)"),
    ({"falloff_start": 35.0}, "falloff_start: must be in [0, cone_angle = 30]"),
    ({"falloff_start": -1.0}, "falloff_start: must be in [0, cone_angle = 30]"),
    ({"look_at": [0.0, 1.5, -1.0]}, "look_at: look_at equals position"),
    ({"look_at": None, "direction": [0.0, 0.0, 0.0]}, "direction: direction is zero"),
    ({"direction": [0.0, -1.0, 0.0]}, "needs exactly one of look_at or direction"),
    ({"look_at": None}, "needs exactly one of look_at or direction"),
    ({"cone": 30.0}, "unknown key"),
])
def test_bad_spot_lights_are_one_line_errors(write_scene, tmp_path, capsys, change, message):
    light = {k: v for k, v in {**SPOT, **change}.items() if v is not None}
    path = write_scene(box_room(light=[light]))
    out = tmp_path / "x.exr"
    assert main(["render", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "light[0]" in err and message in err, err
    assert not out.exists()


@pytest.mark.parametrize("args,message", [
    (["--method", "lecocq"], "--method lecocq: it does not take spot lights"),
    (["--method", "sun"], "--method sun: it does not take spot lights"),
    (["--method", "analytic", "--anisotropic", "taylor", "--set", 'medium.phase="rayleigh"'],
     "--anisotropic taylor (render.anisotropic): the paper's Taylor series takes no spot or area light"),
    (["--method", "analytic", "--anisotropic", "taylor", "--set", 'medium.phase="rayleigh"', "--set",
      'light[0]={type="quad",corners=[[-0.5,1.5,-0.5],[0.5,1.5,-0.5],[0.5,1.5,0.5],[-0.5,1.5,0.5]],radiance=10.0}'],
     "--anisotropic taylor (render.anisotropic): the paper's Taylor series takes no spot or area light"),
])
def test_methods_that_cannot_take_spot_lights_refuse(write_scene, tmp_path, capsys, args, message):
    """A spot light (and, for Taylor's series, an area light's emitter points: rows with a cone) refused in
    one line, exit status 2, nothing written."""
    path = write_scene(box_room(light=[SPOT]))
    out = tmp_path / "x.exr"
    assert main(["render", str(path), "--out", str(out), "--quiet", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and message in err, err
    assert not out.exists()


@pytest.mark.parametrize("shadows", [False, True])
def test_stage_scene_analytic_equals_quadrature(shadows):
    """The bundled stage (three spot lights: narrow soft, wide hard-edged, a wide wash whose cone holds the whole view; HG
    0.6), small: analytic at 1e-6 within 10 x precision of quadrature in every lit pixel, with and
    without volumetric shadows (the lit intervals inside the cones)."""
    import raytrace

    over = ["camera.width=48", "camera.height=32", "camera.spp=1"]
    an = raytrace.render("stage", method="analytic", precision=PRECISION, overrides=over, threads=1,
                         volumetric_shadows=shadows)
    qu = raytrace.render("stage", method="quadrature", rtol=1e-12, overrides=over, threads=1,
                         volumetric_shadows=shadows)
    lit = qu.array > 0
    assert lit.mean() > 0.9
    assert np.max(np.abs(an.array - qu.array)[lit] / qu.array[lit]) <= 10 * PRECISION
    assert an.stats["spot_band_pieces"] > 0


# ---- the falloff curves ----------------------------------------------------------------------------

OTHER_CURVES = ["mitsuba", "gltf"]


@pytest.mark.parametrize("cone,start", [(30.0, 20.0), (60.0, 0.0), (150.0, 100.0)])
def test_falloff_curves_at_their_landmarks(cone, start):
    """Mitsuba's curve is linear in the angle (half way in angle: 1/2, a quarter from the cone: 1/4),
    glTF's the ramp in the cosine squared (half way in cosine: 1/4); all three are 1 on the core's edge
    and 0 on the cone's, and hard-edged when the angles are equal; the oracle's curves agree."""
    ce, cs = math.cos(math.radians(cone)), math.cos(math.radians(start))
    for curve in (SMOOTHSTEP, MITSUBA, GLTF):
        assert falloff(cs, ce, cs, curve) == 1.0 and falloff(ce, ce, cs, curve) == 0.0
        assert falloff(ce, ce, ce, curve) == 1.0 and falloff(np.nextafter(ce, -2.0), ce, ce, curve) == 0.0
    for frac, want in ((0.5, 0.5), (0.25, 0.25), (0.9, 0.9)):
        c = math.cos(math.radians(cone - frac * (cone - start)))
        assert falloff(c, ce, cs, MITSUBA) == pytest.approx(want, rel=1e-12)
    assert falloff(0.5 * (ce + cs), ce, cs, GLTF) == pytest.approx(0.25, rel=1e-12)
    axis = np.array([0.0, 0.0, 1.0])
    for angle in np.linspace(start, cone, 7):
        u = np.array([math.sin(math.radians(angle)), 0.0, math.cos(math.radians(angle))])
        for name, code in CURVES.items():
            assert falloff(float(u @ axis), ce, cs, code) == pytest.approx(
                oracle.emission((axis, ce, cs), u, name), rel=1e-12, abs=1e-14)


def test_gltf_band_as_a_trigonometric_polynomial():
    """lights.band_trig's coefficients for the glTF curve reproduce t^2, t = (c - cos_end) /
    (cos_start - cos_end), c = A sin(phi) - B cos(phi), at random phi (no cubic term)."""
    rng = np.random.default_rng(7)
    a, b = np.zeros(4), np.zeros(4)
    for _ in range(50):
        A, B = rng.uniform(-0.7, 0.7, 2)
        ce = float(rng.uniform(-0.9, 0.8))
        cs = float(rng.uniform(ce + 0.01, 1.0))
        band_trig(A, B, ce, cs, GLTF, a, b)
        assert a[3] == 0.0 and b[3] == 0.0
        for phi in rng.uniform(0.0, math.pi, 5):
            t = (A * math.sin(phi) - B * math.cos(phi) - ce) / (cs - ce)
            got = sum(a[m] * math.cos(m * phi) + b[m] * math.sin(m * phi) for m in range(4))
            assert got == pytest.approx(t * t, rel=1e-11, abs=1e-11 * max(1.0, 1.0 / (cs - ce) ** 2))


def _random_curve_segments(curve, code, g, name, count, seed):
    rng = np.random.default_rng(seed)
    totals = np.zeros(A.STATS_SIZE)
    for _ in range(count):
        o, p = rng.uniform(-2, 2, 3), rng.uniform(-2, 2, 3)
        cone = float(rng.uniform(5.0, 120.0))
        start = cone if rng.random() < 0.15 else float(rng.uniform(0.0, 0.8 * cone))
        ell = math.inf if rng.random() < 0.2 else float(rng.uniform(0.5, 6.0))
        # the ray aimed near the beam, so that most segments cross its band
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        w = p + 2.0 * axis + rng.normal(scale=0.7, size=3) - o
        totals += check(o, w, ell, p, spot(axis, cone, start), 0.3, 0.2, code, g, name, curve)
    return totals


@pytest.mark.parametrize("curve", OTHER_CURVES)
@pytest.mark.parametrize("code,g,name", [PHASES[0], PHASES[2]])
def test_curve_segments_match_the_oracle(curve, code, g, name):
    """Random segments near the beam (cones 5-120 degrees, some hard-edged, rays to infinity): analytic
    within 10 x precision, quadrature within 1e-9 of the oracle. glTF bands keep the closed form
    (trigonometric moments); Mitsuba's bands, not polynomial in the cosine, go to the band quadrature,
    counted."""
    st = _random_curve_segments(curve, code, g, name, 8, 11 + code)
    if curve == "gltf":
        assert st[A.ST_BANDS] > 0
    else:
        assert st[A.ST_BANDS] == 0 and st[A.ST_PIECE_QUAD] > 0


@pytest.mark.slow
@pytest.mark.parametrize("curve", OTHER_CURVES)
@pytest.mark.parametrize("code,g,name", PHASES)
def test_curve_segments_match_the_oracle_many(curve, code, g, name):
    """As above, 40 segments for every phase function."""
    _random_curve_segments(curve, code, g, name, 40, 101 + int(10 * g) + code)


CURVE_LIGHT = [0.0, 1.5, -1.0]
CURVE_PLATE = (0.5, (-0.5, 0.5), (-1.5, -0.5))  # one unit below the light, in its beam: a shadow in the shaft


def curve_room(curve, width=8, height=6):
    """A box room (grey walls, grey HG fog) lit by a spot tilted toward +x, the plate in its beam."""
    y, (x0, x1), (z0, z1) = CURVE_PLATE
    s = box_room(camera={"position": [0.0, 0.0, 3.5], "look_at": [0.0, 0.0, -1.0], "fov": 80.0, "width": width,
                         "height": height, "spp": 1},
                 medium={"sigma_a": 0.05, "sigma_s": 0.2, "phase": {"type": "hg", "g": 0.5}},
                 light=[{"type": "spot", "position": CURVE_LIGHT, "look_at": [1.5, -2.0, -1.5], "intensity": 20.0,
                         "cone_angle": 60.0, "falloff_start": 20.0, "falloff": curve}])
    s["shape"][0]["reflectance"] = 0.5
    s["shape"].append({"primitive": "quad", "corners": [[x0, y, z0], [x1, y, z0], [x1, y, z1], [x0, y, z1]],
                       "reflectance": 0.0})
    return s


def curve_twin(s, shadows):
    """The oracle's image of `curve_room`: per pixel centre, the ray to the nearer of the wall and the
    (black) plate; the wall's diffuse term unless the plate shadows it; the air-light of the spot with
    its curve, over the plate's lit pieces if `shadows`."""
    cam, light = s["camera"], s["light"][0]
    lo, hi = np.array(s["shape"][0]["min"], float), np.array(s["shape"][0]["max"], float)
    ks = s["medium"]["sigma_s"]
    kt = ks + s["medium"]["sigma_a"]
    sp, curve, p = oracle.spot_of(light), light["falloff"], np.array(CURVE_LIGHT)
    img = np.zeros((cam["height"], cam["width"]))
    for j in range(cam["height"]):
        for i in range(cam["width"]):
            o, d = oracle.camera_ray(cam, i, j)
            t, n = oracle.box_exit(o, d, lo, hi)
            tp = oracle.plate_hit(o, d, CURVE_PLATE)
            if t < tp and not oracle.plate_blocks(o, d, t, p, CURVE_PLATE):
                to, dist, e, _ = oracle.lamp_at(light, o + t * d)
                img[j, i] = 0.5 / math.pi * e * math.exp(-kt * (dist + t)) * max(0.0, float(n @ to))
            img[j, i] += oracle.shadowed_airlight(o, d, min(t, tp), p, 20.0, kt, ks, "hg", 0.5,
                                                  [CURVE_PLATE] if shadows else [], sp, curve)
    return img[..., None] * np.ones(3)


_TWINS: dict = {}


def curve_reference(curve, shadows):
    if (curve, shadows) not in _TWINS:
        _TWINS[curve, shadows] = curve_twin(curve_room(curve), shadows)
    return _TWINS[curve, shadows]


def check_curve_room(curve, shadows):
    """Every method that takes spot lights on `curve_room` against the twin: quadrature within 1e-9,
    analytic (precision 1e-6) within 10 x its precision, both exactly 0 where the twin is; raymarch
    and montecarlo (its default and exact-CDF sampling) by their error laws (tests/test_methods.py's
    statistic)."""
    import raytrace
    from raytrace.methods import registry

    from .test_methods import statistic

    ref = curve_reference(curve, shadows)
    lit = ref > 0
    assert ref.min() >= 0.0 and lit.mean() > 0.4  # the rest sees no lit fog and no lit wall
    runs = [("quadrature", {"rtol": 1e-12}), ("analytic", {"precision": PRECISION}),
            ("raymarch", registry()["raymarch"].error_law.params), ("montecarlo", registry()["montecarlo"].error_law.params),
            ("montecarlo", {**registry()["montecarlo"].error_law.params, "sampling": "cdf"})]
    for name, params in runs:
        img = raytrace.render(curve_room(curve), method=name, threads=1, seed=3, volumetric_shadows=shadows, **params)
        if name in ("quadrature", "analytic"):
            rel = np.max(np.abs(img.array - ref)[lit] / ref[lit])
            assert rel <= (1e-9 if name == "quadrature" else 10 * PRECISION) and np.all(img.array[~lit] == 0.0), name
            if name == "analytic" and curve != "smoothstep":  # the curve's bands: closed form or counted quadrature
                assert img.stats["spot_band_pieces" if curve == "gltf" else "spot_pieces_by_quadrature"] > 0
        else:
            law = registry()[name].error_law
            assert statistic(law, img.array, ref, img.variance) <= law.tolerance, (name, params)


def test_curve_room_with_the_plate_shadow_in_the_beam():
    """With volumetric shadows the plate's shadow lies in the shaft (the twin integrates the lit
    pieces between its analytic boundaries): Mitsuba's curve, whose bands analytic integrates by its
    band quadrature (the other curves: the slow test below)."""
    check_curve_room("mitsuba", True)


@pytest.mark.slow
@pytest.mark.parametrize("curve,shadows", [("gltf", True), ("smoothstep", True), ("smoothstep", False),
                                           ("mitsuba", False), ("gltf", False)])
def test_curve_room_every_method_against_the_twin(curve, shadows):
    """The same room for the other curves, and without volumetric shadows (the plate still blocks the
    view and shadows the walls)."""
    check_curve_room(curve, shadows)


@pytest.mark.slow
@pytest.mark.parametrize("curve", OTHER_CURVES)
def test_curve_room_twin_shows_the_shadow_and_the_curve(curve):
    """The checks above are not vacuous: the shadow is in view (a tenth of the pixels lose more than
    10 % of their light) and each curve's image differs from the smoothstep's by more than 5 % somewhere."""
    ref = curve_reference(curve, True)
    assert np.mean(ref < 0.9 * curve_reference(curve, False)) > 0.1
    lit = ref > 0
    assert np.max(np.abs(ref[lit] / curve_reference("smoothstep", True)[lit] - 1.0)) > 0.05


@pytest.mark.parametrize("curve", OTHER_CURVES)
def test_falloff_key_is_checked(write_scene, tmp_path, capsys, curve):
    """The key is parsed (its curve reaches the lights) and a wrong name is one line, exit 2."""
    import raytrace

    assert raytrace.load(box_room(light=[SPOT | {"falloff": curve}])).lights[0].curve == CURVES[curve]
    assert raytrace.load(box_room(light=[SPOT])).lights[0].curve == SMOOTHSTEP
    path = write_scene(box_room(light=[SPOT | {"falloff": curve.upper()}]))
    out = tmp_path / "x.exr"
    assert main(["render", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "light[0].falloff" in err and "smoothstep, mitsuba, gltf" in err, err
    assert not out.exists()
