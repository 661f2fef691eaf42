"""The tent layer of an atmosphere (Bruneton's ozone, `profile = "tent"`).

Its closed-form column (media/tent.py) against mpmath quadrature of the tent density along rays
at 30 digits, split at the three spheres and the tangent point, on a grid of ground, airborne,
grazing and from-space rays, to 1e-12 (or, where an ulp of mu moves the answer more, 4 eps times
its condition number in mu, as test_optical_depth's grazing rays); the free-path inverse through a
tent and an exponential layer; quadrature images against test_atmosphere's brute force extended
to tents to 1e-8; Monte Carlo by its z-test; bad keys as one line.
"""
import math

import mpmath as mp
import numpy as np
import pytest

import raytrace
from raytrace.cli import main
from raytrace.errors import UserError
from raytrace.media import atmosphere as atm
from raytrace.media import tent

from .test_atmosphere import GROUND, SMALL, SPACE, pixel

R, TOP = 6360e3, 6420e3
PEAK, HALF = 25e3, 15e3
EPS = np.finfo(float).eps
LAYERS = np.array([[atm.TENT, PEAK, HALF], [atm.EXPONENTIAL, 8e3, 0.0]])
KT = np.array([1.881e-6, 13.558e-6])  # ozone absorption at the peak, Rayleigh at the ground (green)

mp.mp.dps = 30


def mp_column(h, mu, t0, t1, peak=PEAK, half=HALF, radius=R):
    """The tent's column over [t0, t1] by mpmath quadrature, split where the density has kinks."""
    h, mu, t0, t1 = (mp.mpf(v) for v in (h, mu, t0, t1))
    r0 = radius + h
    s0, b2 = r0 * mu, r0 * r0 * (1 - mu * mu)

    def density(t):
        return max(mp.mpf(0), 1 - abs(mp.sqrt(b2 + (s0 + t) ** 2) - radius - peak) / half)

    breaks = [t0, t1] + ([-s0] if t0 < -s0 < t1 else [])
    for alt in (peak - half, peak, peak + half):
        disc = (radius + alt) ** 2 - b2
        if disc > 0:
            breaks += [t for t in (-s0 - mp.sqrt(disc), -s0 + mp.sqrt(disc)) if t0 < t < t1]
    return mp.quad(density, sorted(breaks))


def _rays():
    """(h, mu, end): rays from the ground, inside and above the tent, from space (one and three radii
    up), up, down, horizontal, and tangent to each of the tent's spheres (rotated by -+1e-7 rad);
    `end` where they meet the ground or leave the 100 km sphere."""
    out = []
    for h in (0.0, 5e3, 10e3, 25e3, 33e3, 50e3, 100e3, R, 3 * R):
        mus = [1.0, 0.5, 0.1, 0.01, 0.0, -0.01, -0.1, -1.0]
        for alt in (PEAK - HALF, PEAK, PEAK + HALF):
            if h > alt:
                th = math.acos(-math.sqrt(1.0 - ((R + alt) / (R + h)) ** 2))
                mus += [math.cos(th), math.cos(th + 1e-7), math.cos(th - 1e-7)]
        for mu in mus:
            r0 = R + h
            s0, b2 = r0 * mu, r0 * r0 * (1.0 - mu) * (1.0 + mu)
            if mu < 0.0 and R * R > b2:
                end = -s0 - math.sqrt(R * R - b2)
            else:
                end = -s0 + math.sqrt(max((R + 100e3) ** 2 - b2, 0.0))
            if end > 0.0:
                out.append((h, mu, end))
    return out


RAYS = _rays()


def _relative_error(got, h, mu, t0, t1):
    """|got - ref| / ref over the allowed error: 1e-12, or 4 eps times the condition number in mu."""
    ref = mp_column(h, mu, t0, t1)
    if ref == 0:
        return 0.0 if got == 0.0 else math.inf
    err = abs(got - float(ref)) / float(ref)
    if err <= 1e-12:
        return err / 1e-12
    d = mp.mpf(mu) * mp.mpf("1e-15") if mu != 0.0 else mp.mpf("1e-15")
    cond = abs((mp_column(h, mp.mpf(mu) + d, t0, t1) - mp_column(h, mp.mpf(mu) - d, t0, t1)) / (2 * d)
               * (mu if mu != 0.0 else 1) / ref)
    return err / max(1e-12, 4.0 * EPS * float(cond))


def _worst_column(rays, pieces):
    worst = 0.0
    for h, mu, end in rays:
        for f0, f1 in pieces:
            t0, t1 = f0 * end, f1 * end
            worst = max(worst, _relative_error(tent.tent_column(h, mu, t0, t1, R, PEAK, HALF), h, mu, t0, t1))
    print(f"{len(rays)} rays: worst {worst:.3g} of the allowed error")
    return worst


def test_tent_column_against_mpmath():
    """tent_column over whole rays and over pieces starting and ending inside the air (a third of
    the rays; all of them with -m slow)."""
    assert _worst_column(RAYS[::3], ((0.0, 1.0), (0.1, 0.7))) <= 1.0


@pytest.mark.slow
def test_tent_column_against_mpmath_every_ray():
    assert _worst_column(RAYS, ((0.0, 1.0), (0.1, 0.7), (0.5, 1.0))) <= 1.0


def test_columns_with_a_tent_layer():
    """atmosphere.columns with the layers table (tent and exponential): the tent's column is the
    mpmath one over the part inside the top sphere; the ground still blocks."""
    cols = np.empty(2)
    worst = 0.0
    for h, mu, end in RAYS[::3]:
        blocked = not atm.columns(h, mu, 0.0, math.inf, R, TOP, LAYERS, cols)
        assert blocked == (mu < 0.0 and (R + h) ** 2 * (1.0 - mu * mu) < R * R)
        a, b = atm.shell(h, mu, R, TOP)
        assert atm.columns(h, mu, 0.0, 0.5 * end, R, TOP, LAYERS, cols)
        lo, hi = max(0.0, a), min(0.5 * end, b)
        if hi > lo:
            worst = max(worst, _relative_error(cols[0], h, mu, lo, hi))
        else:
            assert cols[0] == 0.0
    assert worst <= 1.0


def test_free_path_through_a_tent_and_an_exponential_layer():
    """atmosphere.free_path inverts the summed optical depth: the mpmath depth at the x it returns
    is the target to 1e-12, or within two ulps of x times the extinction there."""
    row = np.empty((1, atm.ROW))
    cols = np.empty(2)
    worst = 0.0
    for h, mu, end in RAYS[1::4]:
        w = np.array([math.sqrt(1.0 - mu * mu), mu, 0.0])
        atm.segment_rows(np.array([[0.0, R + h, 0.0]]), w[None, :], np.array([end]), np.zeros((1, 3)),
                         np.zeros((1, 3)), np.zeros(1, np.int64), np.zeros(1, bool), 0.0, 0.0, 0.0, R, TOP, row)
        a, b = row[0, atm.A], row[0, atm.B]
        if not b > a:
            continue
        h0, mu0 = row[0, atm.H0], row[0, atm.MU0]
        atm.columns(h0, mu0, a, b, R, TOP, LAYERS, cols)
        total = float(KT @ cols)
        for f in (1e-6, 0.5, 1.0 - 1e-6):
            x = atm.free_path(row[0], a, b, f * total, KT, LAYERS, R, TOP, cols)
            assert a <= x <= b
            ref = KT[0] * mp_column(h0, mu0, a, x) + KT[1] * atm.atmosphere_column(h0, mu0, a, x, R, 8e3)
            slack = 2.0 * atm.extinction_at(x, row[0], KT, LAYERS, R) * np.spacing(x)
            worst = max(worst, max(0.0, abs(float(ref) - f * total) - slack) / (f * total))
    assert worst <= 1e-12, worst


OZONE = {"name": "ozone", "profile": "tent", "peak_altitude": 20.0, "half_width": 12.0,
         "sigma_a": [6.5e-3, 1.881e-2, 8.5e-4], "sigma_s": 2e-3}
TENTED = {**SMALL, "layer": SMALL["layer"] + [OZONE]}


def _worst_against_brute_force(scene, pixels):
    """The largest relative error per pixel-channel of the quadrature image (float64, in process)
    against test_atmosphere's `pixel`; pixels that miss the air must be black in both."""
    img = raytrace.render(scene, method="quadrature", threads=1).array
    worst = 0.0
    for i, j in pixels:
        ref = pixel(scene, i, j)
        if not np.any(img[j, i] > 0.0):
            assert np.all(ref == 0.0)
            continue
        worst = max(worst, float(np.max(np.abs(img[j, i] - ref) / ref)))
    return worst


@pytest.mark.parametrize("name, pixels", [("ground", [(3, 3), (0, 4)]), ("space", [(2, 1)])])
def test_quadrature_matches_brute_force_with_ozone(name, pixels):
    """test_atmosphere's small planet with a scattering, absorbing tent layer: quadrature against the
    brute force (which splits at the tent's spheres) to 1e-8 per pixel-channel."""
    assert _worst_against_brute_force({**{"ground": GROUND, "space": SPACE}[name], "medium": TENTED}, pixels) < 1e-8


@pytest.mark.slow
def test_quadrature_matches_brute_force_with_ozone_every_pixel():
    """pytest -m slow tests/test_ozone.py -k every (a few minutes): all 35 pixels of both views."""
    for scene in (GROUND, SPACE):
        pixels = [(i, j) for j in range(5) for i in range(7)]
        worst = _worst_against_brute_force({**scene, "medium": TENTED}, pixels)
        print(f"worst relative error {worst:.3g}")
        assert worst < 1e-8


@pytest.mark.parametrize("name, sampling", [("ground", "mis"), ("space", "freepath")])
def test_montecarlo_z_test_with_ozone(name, sampling):
    """256 samples (MIS: equiangular and free-path draws, the latter by Newton through the tent):
    the mean squared z-score against quadrature, over the render's own variance, is about 1."""
    scene = {**{"ground": GROUND, "space": SPACE}[name], "medium": TENTED}
    ref = raytrace.render(scene, method="quadrature", threads=1).array
    mc = raytrace.render(scene, method="montecarlo", samples=256, sampling=sampling, seed=3, threads=1)
    noisy = mc.variance > 0
    z2 = (mc.array - ref)[noisy] ** 2 / mc.variance[noisy]
    assert z2.mean() < 3.5, z2.mean()


@pytest.mark.parametrize("layer, message", [
    ({"profile": "tent", "half_width": 12.0}, "medium.layer[2].peak_altitude: missing"),
    ({"profile": "tent", "peak_altitude": 20.0}, "medium.layer[2].half_width: missing"),
    ({"profile": "tent", "peak_altitude": 20.0, "half_width": 0.0}, "medium.layer[2].half_width: must be positive"),
    ({"profile": "tent", "peak_altitude": 20.0, "half_width": 1e4}, "medium.layer[2].half_width: must be positive"),
    ({"profile": "tent", "peak_altitude": 20.0, "half_width": 12.0, "scale_height": 8.0},
     "medium.layer[2].scale_height: only an exponential layer has it"),
    ({"profile": "tent", "peak_altitude": -2000.0, "half_width": 12.0},
     "medium.layer[2].peak_altitude: must be at or above the ground"),
    ({"scale_height": 8.0, "peak_altitude": 20.0}, "medium.layer[2].peak_altitude: only a tent layer"),
    ({"profile": "cone", "scale_height": 8.0}, "medium.layer[2].profile: 'cone' is not one of exponential, tent"),
])
def test_bad_tent_keys(layer, message):
    scene = {**GROUND, "medium": {**SMALL, "layer": SMALL["layer"] + [layer]}}
    with pytest.raises(UserError, match="^scene dict: " + message.replace("[", r"\[").replace("]", r"\]")):
        raytrace.render(scene, method="quadrature", threads=1)


def test_describe_shows_the_tent(write_scene, capsys):
    assert main(["describe", str(write_scene({**GROUND, "medium": TENTED}))]) == 0
    out = capsys.readouterr().out
    assert "layer[2] ozone: sigma_a [0.0065, 0.01881, 0.00085], sigma_s [0.002, 0.002, 0.002] at the peak, " \
           "tent profile, peak altitude 20, half width 12, phase isotropic" in out
