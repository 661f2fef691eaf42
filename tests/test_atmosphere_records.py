"""The atmosphere's integrand records: geometry.AtmosphereInX (marched by raymarch, held by montecarlo's
AtmospherePaths) and quadrature's AtmosphereIntegrand (in theta for point and spot lights) against
`atmosphere.inscatter` called directly, the spot falloff and 1/d^2 taken from the 3-D geometry."""
import math

import numba
import numpy as np
import pytest

from raytrace.lights import SMOOTHSTEP, falloff
from raytrace.media import atmosphere as atmo
from raytrace.media.phase import HG, ISOTROPIC, RAYLEIGH
from raytrace.media.integrand import integrand
from raytrace.methods.geometry import AtmosphereInX, atmosphere_in_x, atmosphere_row, segment_light_table
from raytrace.methods.quadrature import AtmosphereIntegrand

R, TOP = 6360e3, 6420e3
CENTER = np.array([0.0, -R, 0.0])
LAYERS = np.array([[atmo.EXPONENTIAL, 8000.0, 0.0], [atmo.EXPONENTIAL, 1200.0, 0.0], [atmo.TENT, 25e3, 15e3]])
KT = np.array([13.558e-6, 4.44e-6, 1.881e-6])
KS = np.array([13.558e-6, 3.996e-6, 0.0])
CODES = np.array([RAYLEIGH, HG, ISOTROPIC])
GS = np.array([0.0, 0.8, 0.0])
ORIGIN = np.array([0.0, 2.0, 0.0])
DIR = np.array([0.3, 0.45, -1.0]) / np.linalg.norm([0.3, 0.45, -1.0])
LAMP = np.array([800.0, 600.0, -3000.0])
AXIS = (ORIGIN + 1500.0 * DIR - LAMP) / np.linalg.norm(ORIGIN + 1500.0 * DIR - LAMP)  # the spot's cone crosses the ray
COS_END, COS_START = math.cos(0.6), math.cos(0.4)


@numba.njit
def _value(x, rec):
    return integrand(x, rec)


def _segment(light):
    """(row array, xh, h, cone row, axis or None) of the ray from ORIGIN along DIR to infinity."""
    directional = light == "sun"
    axis = np.array([-0.4226, -0.0698, 0.9036]) if directional else AXIS
    axis = axis / np.linalg.norm(axis)
    lcone = np.array([[COS_END, COS_START, SMOOTHSTEP] if light == "spot" else [-3.0, -2.0, SMOOTHSTEP]])
    o, w, lpos = ORIGIN[None], DIR[None], LAMP[None]
    xh, h, _, cone = segment_light_table(o, w, lpos, axis[None], lcone, np.array([0]), 1e4)
    rows = np.empty((1, atmo.ROW))
    atmo.segment_rows(o, w, np.array([math.inf]), lpos, axis[None], np.array([0]), np.array([directional]), *CENTER, R,
                      TOP, rows)
    return rows[0], directional, xh[0], h[0], cone[0], axis


def _record(row, directional, xh, h, cone):
    return AtmosphereInX(atmosphere_row(row), directional, xh, h, tuple(cone), KT, KS, CODES, GS, LAYERS, R, TOP,
                         np.empty(3))


def _reference(x, light, row, axis):
    """inscatter at x times, for a lamp, its falloff toward o + x w over the squared distance."""
    f = atmo.inscatter(x, row, light == "sun", KT, KS, CODES, GS, LAYERS, R, TOP, np.empty(3), -1.0)
    if light == "sun":
        return f
    r = ORIGIN + x * DIR - LAMP
    d2 = r @ r
    spot = falloff(r @ axis / math.sqrt(d2), COS_END, COS_START, SMOOTHSTEP) if light == "spot" else 1.0
    return f * spot / d2


def test_atmosphere_row_is_the_whole_row():
    assert atmosphere_row(np.arange(atmo.ROW, dtype=float)) == tuple(range(atmo.ROW))


@pytest.mark.parametrize("light", ["sun", "point", "spot"])
def test_records_name_the_atmospheres_integrand(light):
    row, directional, xh, h, cone, axis = _segment(light)
    rec = _record(row, directional, xh, h, cone)
    a, b = row[atmo.A], row[atmo.B]
    xs = a + (b - a) * np.linspace(0.0, 1.0, 41) ** 3  # dense near the camera, where a lamp is
    ref = np.array([_reference(x, light, row, axis) for x in xs])
    assert np.all(ref >= 0.0) and np.count_nonzero(ref) >= 10  # the spot's cone cuts some points off
    atol = 1e-12 * ref.max()
    np.testing.assert_allclose([_value(x, rec) for x in xs], ref, rtol=1e-12, atol=atol)
    quad = AtmosphereIntegrand(rec)
    if directional:
        np.testing.assert_allclose([_value(x, quad) for x in xs], ref, rtol=1e-12, atol=atol)
    else:  # x = x_h + h tan(theta): dx / dtheta = d^2 / h
        thetas = np.arctan((xs - xh) / h)
        d2 = h * h + (xs - xh) ** 2
        np.testing.assert_allclose([_value(t, quad) for t in thetas], ref * d2 / h, rtol=1e-10,
                                   atol=atol * d2.max() / h)


@pytest.mark.parametrize("light", ["sun", "point"])
def test_atmosphere_in_x_takes_the_cameras_optical_depth(light):
    """montecarlo passes the camera's optical depth tau to x it already has: the value is the
    integrand's with T_cam = exp(-tau)."""
    row, directional, xh, h, cone, _ = _segment(light)
    rec = _record(row, directional, xh, h, cone)
    cols = np.empty(3)
    for x in row[atmo.A] + np.array([10.0, 3e3, 4e4, 3e5]):
        assert atmo.columns(row[atmo.H0], row[atmo.MU0], 0.0, x, R, TOP, LAYERS, cols)
        tau = atmo.optical_depth(cols, KT)
        ref = atmosphere_in_x(x, rec, -1.0)
        assert ref > 0.0
        assert atmosphere_in_x(x, rec, tau) == pytest.approx(ref, rel=1e-13)
        assert atmosphere_in_x(x, rec, tau + 0.5) == pytest.approx(ref * math.exp(-0.5), rel=1e-13)
