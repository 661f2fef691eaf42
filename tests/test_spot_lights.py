"""Spot lights (issue 10): the closed-form air-light and the quadrature against the independent
oracle (tests/oracle.py: scipy quad in the distance, cone crossings found by bracketing), on random
segments and on the hard cases: cone angles from 1 to 179 degrees, hard edges, rays along the
cone's edge and core, rays through the apex, the light looking away from the camera. Requirement:
within 10 x precision (analytic, precision 1e-6) and 1e-9 (quadrature, rtol 1e-12).

Also the scene-file contract: bad spot lights and spot lights in methods that cannot take them
give one line and exit 2, with nothing written.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from raytrace.cli import main
from raytrace.lights import falloff
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


def renderer_pair(o, w, ell, p, sp, kt, ks, code, g, precision=PRECISION):
    """(analytic, quadrature, analytic stats) for one segment, through the renderer's geometry."""
    xh, h, da, row = segment_light_table(o[None], w[None], p[None], sp[0][None], np.array([[sp[1], sp[2]]]),
                                         np.zeros(1, np.int64), 1.0)
    wp = A.working_precision(precision)
    coeffs = A.make_coeffs(code, g, A.ANISO_EXACT, 6, wp)
    st = A.new_stats()
    an = A.airlight(xh[0], h[0], da[0], ell, kt, ks, 1.0, code, g, wp, 1000, A.ANISO_EXACT, 6, coeffs, row[0], st)
    qu = Q.airlight_one(xh[0], h[0], ell, kt, ks, code, g, row[0], 1e-12, Q._N10, Q._W10, Q._N20, Q._W20,
                        np.zeros(3))
    return an, qu, st


def check(o, w, ell, p, sp, kt, ks, code, g, name):
    o, w, p = (np.asarray(v, float) for v in (o, w, p))
    w = w / np.linalg.norm(w)
    ref = oracle.airlight(o, w, ell, p, 1.0, kt, ks, name, g, sp)
    an, qu, st = renderer_pair(o, w, ell, p, sp, kt, ks, code, g)
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
    assert falloff(1.0, ce, cs) == 1.0 and falloff(ce, ce, cs) == 0.0 and falloff(-1.0, ce, cs) == 0.0
    assert falloff(mid, ce, cs) == pytest.approx(0.5)
    assert falloff(ce + 0.25 * (cs - ce), ce, cs) == pytest.approx(0.25**2 * (3 - 0.5))
    assert falloff(cs, cs, cs) == 1.0 and falloff(np.nextafter(cs, 0.0), cs, cs) == 0.0


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
     "--anisotropic taylor (render.anisotropic): the paper's Taylor series takes no spot light"),
])
def test_methods_that_cannot_take_spot_lights_refuse(write_scene, tmp_path, capsys, args, message):
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
