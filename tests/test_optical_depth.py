"""Optical depth of height fogs and of the spherical atmosphere, and their inverses, against mpmath
quadrature of the defining integrals (seed 004 eq. 26, 30, 34, 40, 42) at 30 digits.

Worst relative errors measured on this grid (docs/optical_depth.md §4): Chapman function 1.8e-15
above the horizon, 6.6e-14 below it (where C ~ e^{a^2}, a^2 = z mu^2/(1 + sin chi) up to ~500
here, so mu's own rounding moves C by ~2 a^2 eps); atmosphere column 6.8e-15 over ground,
inside-layer and near-space (30 H) origins of both Earth layers (H = 8 km, 1.2 km) and a small
planet (R/H = 10), all directions (exactly horizontal, +-1e-8, grazing the ground within 1e-9 rad,
straight down), to infinity, to the ground, short (0.01 H), finite and long (1e3 H) segments;
2.1e-14 from one Earth radius up (test_far_space); exponential fog 1.3e-14 (1.5e-15 for
horizontal rays), linear fog 4.4e-16. Inverses: tau(t(tau)) = tau to 1e-14 relative, or within
one ulp of t times the extinction there when that is coarser (a tiny tau far along the ray).
"""
import math

import mpmath as mp
import numpy as np
import pytest

from raytrace.media import chapman as ch
from raytrace.media import fog as hf

mp.mp.dps = 30
RTOL = 1e-12
INF = math.inf

# (radius, scale height): Earth's air and aerosols, and a small planet with R/H = 10
PLANETS = [(6360e3, 8e3), (6360e3, 1.2e3), (10e3, 1e3)]
HEIGHTS = [0.0, 0.5, 3.0, 10.0, 30.0]  # origin altitudes in scale heights (30: near space)
MUS = [1.0, 0.7, 0.2, 1e-3, 1e-8, 0.0, -1e-8, -1e-3, -0.2, -0.7, -1.0]


def _mp(x):
    return mp.inf if x == INF else mp.mpf(x)


def ref_column(h, mu, t0, t1, R, H):
    """int_{t0}^{t1} exp(-(|o + t d - c| - R)/H) dt at 30 digits, broken where the altitude is
    2 .. 90 scale heights above its minimum on the segment and cut beyond (e^{-90})."""
    h, mu, R, H, t0, t1 = map(_mp, (h, mu, R, H, t0, t1))
    r0 = R + h
    tp = -r0 * mu
    b2 = r0 * r0 * (1 - mu * mu)
    alt = lambda t: mp.sqrt(b2 + (t - tp) ** 2) - R  # noqa: E731
    tm = min(max(tp, t0), t1)
    hm = alt(tm)
    pts = {t0, tm}
    if t1 < mp.inf:
        pts.add(t1)
    for k in (2, 12, 45, 90):
        d = mp.sqrt((R + hm + k * H) ** 2 - b2)
        pts.update(t for t in (tp - d, tp + d) if t0 < t < t1)
    pts = sorted(pts)
    if t1 == mp.inf and alt(pts[-1]) - hm < 89 * H:
        pts.append(mp.inf)
    return mp.exp(-hm / H) * mp.quad(lambda t: mp.exp(-(alt(t) - hm) / H), pts, method="gauss-legendre")


def grazing_mus(hh, R):
    """Directions tangent to the ground rotated by -1e-9 and +1e-9 rad (hitting, missing)."""
    mu_g = -math.sqrt(1.0 - (R / (R + hh)) ** 2)
    th = math.acos(mu_g)
    return [math.cos(th + 1e-9), math.cos(th - 1e-9)]


def _atmosphere_cases():
    cases = []
    for R, H in PLANETS:
        for k in HEIGHTS:
            hh = k * H
            mus = MUS + (grazing_mus(hh, R) if hh > 0 else [])
            for mu in mus:
                tg = ch.ground_distance(hh, mu, R)
                segs = [(0.0, tg), (0.0, min(0.01 * H, tg)), (0.0, min(1e3 * H, tg))]
                segs.append((2 * H, 7 * H) if tg > 7 * H else (tg / 3, 0.9 * tg))
                cases += [(hh, mu, t0, t1, R, H) for t0, t1 in segs]
    return cases


ATMOSPHERE = _atmosphere_cases()


@pytest.fixture(scope="module")
def atmosphere_refs():
    return np.array([float(ref_column(*c)) for c in ATMOSPHERE])


def _rel(got, ref):
    got, ref = np.asarray(got, float), np.asarray(ref, float)
    both_inf = np.isinf(got) & np.isinf(ref)
    with np.errstate(invalid="ignore"):
        return np.where(both_inf, 0.0, np.abs(got - ref) / np.where(ref == 0, 1.0, np.abs(ref)))


def test_reference_quadrature():
    """The reference itself: C(z, pi/2) = z e^z K1(z) (seed eq. 47) and C(z, 0) = 1."""
    for z in (3.0, 100.0, 1e6):
        exact = z * mp.exp(z) * mp.besselk(1, z)
        assert abs(ref_column(0.0, 0.0, 0.0, INF, z, 1.0) / exact - 1) < 1e-25
        assert abs(ref_column(0.0, 1.0, 0.0, INF, z, 1.0) - 1) < 1e-25


def test_gauss_legendre_table():
    x, w = np.polynomial.legendre.leggauss(16)
    assert np.allclose(ch._GL_X, x[8:], rtol=1e-15, atol=0) and np.allclose(ch._GL_W, w[8:], rtol=1e-15, atol=0)


def test_chapman_function():
    zs = [3.0, 10.0, 100.0, 5300.0, 1e5, 1e6]
    mus = [1.0, 0.5, 0.1, 1e-3, 1e-6, 0.0, -1e-6, -1e-3, -0.1, -0.5, -1.0]
    got, ref = [], []
    for z in zs:
        for mu in mus:
            r = ref_column(0.0, mu, 0.0, INF, z, 1.0)
            got.append(ch.chapman(z, mu))
            ref.append(float(r) if r < 1e300 else INF)
    err = _rel(got, ref)
    assert err.max() <= RTOL, err.max()


def test_atmosphere_column(atmosphere_refs):
    c = np.array(ATMOSPHERE).T
    got = ch.atmosphere_column_np(*c)
    err = _rel(got, atmosphere_refs)
    worst = int(np.argmax(err))
    assert err.max() <= RTOL, (err.max(), ATMOSPHERE[worst])
    assert np.all(np.isfinite(got)) and np.all(got >= 0.0)


def test_far_space():
    """From one planet radius up (grazing, hitting and missing the planet) the answer's condition
    number in mu is ~ r0 mu^2 / H (~1e4 for the 1.2 km layer): still within 1e-12 (2.1e-14)."""
    R, H = 6360e3, 1.2e3
    for mu in [-0.9, -0.8, grazing_mus(R, R)[1], -0.5, 0.0, 0.5]:
        tg = ch.ground_distance(R, mu, R)
        ref = float(ref_column(R, mu, 0.0, tg, R, H))
        got = ch.atmosphere_column(R, mu, 0.0, tg, R, H)
        assert abs(got - ref) <= RTOL * ref, (mu, got, ref)


def test_atmosphere_optical_depth_scales():
    R, H = 6360e3, 8e3
    assert ch.atmosphere_optical_depth(0.0, 0.0, -1.0, 0.0, INF, R, H) == 0.0
    a = ch.atmosphere_optical_depth(2.5e-5, 100.0, 0.1, 0.0, INF, R, H)
    assert a == pytest.approx(2.5e-5 * ch.atmosphere_column(100.0, 0.1, 0.0, INF, R, H), rel=1e-15)


def test_through_the_planet_is_inf_not_nan():
    R, H = 6360e3, 1.2e3
    assert ch.atmosphere_column(1e3, -0.5, 0.0, INF, R, H) == INF
    assert ch.atmosphere_column(1e3, -1.0, 0.0, 2 * R, R, H) == INF
    assert ch.atmosphere_column(1e3, 0.0, 1e30, 1e300, R, H) == 0.0


@pytest.mark.parametrize("t0, t1", [(0.0, 2.0), (2.0, 3.0)], ids=["ends at the centre", "starts at the centre"])
def test_a_radial_ray_through_the_centre_is_finite(t0, t1):
    """A ray straight down through the planet's centre (impact parameter 0) with a segment end on
    the centre (s = r = 0 there): was 0/0 (ZeroDivisionError compiled, nan in Python), found by the
    slow fuzz run (a planet of radius 100 seen from 1e30 away, where the segment's end rounds onto the
    centre). Radially the column is int exp(-(r - R)/H) dr over the r the segment covers."""
    R, H, h = 1.0, 0.5, 1.0  # from altitude 1 (r = 2) down: the centre is at t = 2
    r_lo, r_hi = sorted((abs(2.0 - t0), abs(2.0 - t1)))
    ref = mp.quad(lambda r: mp.exp(-(r - R) / H), [r_lo, r_hi])
    got = ch.atmosphere_column(h, -1.0, t0, t1, R, H)
    assert got == pytest.approx(float(ref), rel=RTOL)


def test_ground_distance():
    for R, H in PLANETS:
        for hh in (0.0, 0.5 * H, 10 * H, R):
            for mu in [-1.0, -0.5, -1e-3] + grazing_mus(hh, R) if hh > 0 else [-1.0, -0.5]:
                t = ch.ground_distance(hh, mu, R)
                if t == INF:
                    continue
                r0, t_ = mp.mpf(R + hh), mp.mpf(t)
                rr = mp.sqrt(r0 * r0 + 2 * r0 * mp.mpf(mu) * t_ + t_ * t_)
                assert abs(rr - R) <= 1e-15 * (R + hh), (R, hh, mu)
    assert ch.ground_distance(0.0, 0.0, 6360e3) == INF
    assert ch.ground_distance(10.0, -1e-6, 6360e3) == INF  # passes above the ground


def _targets(total):
    fr = [1e-9, 1e-3, 0.3, 0.9, 1.0 - 1e-6]
    return [f * total for f in fr] if total < INF else [1e-6, 1.0, 1e3, 1e6]


def _resolution(sigma0, t, density):
    """How far tau(t0, t) can be from any target at the double t nearest the root: one ulp of t
    times the extinction there (the test's 1e-12 applies above it)."""
    return 2.0 * sigma0 * density * np.spacing(t)


def test_atmosphere_distance():
    """tau(t0, t(tau)) = tau to 1e-12 relative, or t is within two ulps of the root (when
    tau / sigma(t) is below ~1e12 ulp(t), i.e. a tiny tau far along the ray)."""
    worst = 0.0
    for R, H in PLANETS:
        for k in (0.0, 0.5, 10.0):
            hh = k * H
            for mu in [1.0, 0.2, 0.0, -0.2, -1.0] + (grazing_mus(hh, R) if hh > 0 else []):
                tg = ch.ground_distance(hh, mu, R)
                for t0 in (0.0, 3 * H):
                    if t0 >= tg:
                        continue
                    total = ch.atmosphere_column(hh, mu, t0, tg, R, H)
                    for tau in _targets(total):
                        t = ch.atmosphere_distance(2.0, hh, mu, t0, 2.0 * tau, R, H, tg)
                        assert t0 <= t <= tg
                        got = ch.atmosphere_column(hh, mu, t0, t, R, H)
                        r0, s0 = R + hh, (R + hh) * mu
                        alt = hh + t * (2 * s0 + t) / (math.hypot(r0 * math.sqrt(1 - mu * mu), s0 + t) + r0)
                        slack = _resolution(1.0, t, math.exp(-alt / H))
                        worst = max(worst, max(0.0, abs(got - tau) - slack) / tau)
                    assert ch.atmosphere_distance(1.0, hh, mu, t0, 1.01 * total, R, H, tg) == INF
    assert worst <= RTOL, worst


# ---- height fogs ------------------------------------------------------------------------------

FOG_H = 500.0
FOG_HEIGHTS = [-3 * FOG_H, -0.5 * FOG_H, 0.0, 0.7 * FOG_H, 10 * FOG_H]
FOG_MUS = [1.0, 0.3, 1e-9, 0.0, -1e-9, -0.3, -1.0]
FOG_SEGS = [(0.0, 1.0), (0.0, 50.0 * FOG_H), (0.0, INF), (3 * FOG_H, 8 * FOG_H), (1e5, 1e5 + 1e-3), (0.0, 1e12)]


def _fog_breaks(h, mu, t0, t1, H, extra=()):
    pts = {t0} | ({t1} if t1 < mp.inf else set()) | {t for t in extra if t0 < t < t1}
    if mu != 0:
        pts |= {t for t in (t0 + k * H / abs(mu) for k in (1, 4, 16, 40, 90)) if t < t1}
    pts = sorted(pts)
    if t1 == mp.inf and (mu == 0 or pts[-1] < t0 + 89 * H / abs(mu)):
        pts.append(mp.inf)
    return pts


def ref_exponential(h, mu, t0, t1, H):
    h, mu, t0, t1, H = map(_mp, (h, mu, t0, t1, H))
    if t1 == mp.inf and mu <= 0:
        return mp.inf
    x = lambda t: (h + mu * t) / H  # noqa: E731
    xm = min(x(t0), x(t1)) if t1 < mp.inf else x(t0)
    pts = _fog_breaks(h, mu, t0, t1, H)
    return mp.exp(-xm) * mp.quad(lambda t: mp.exp(-(x(t) - xm)), pts)


def ref_linear(h, mu, t0, t1, H):
    h, mu, t0, t1, H = map(_mp, (h, mu, t0, t1, H))
    c = lambda t: max(mp.mpf(0), 1 - (h + mu * t) / H)  # noqa: E731
    zero = [(H - h) / mu] if mu != 0 else []
    if t1 == mp.inf and (mu < 0 or (mu == 0 and c(t0) > 0)):
        return mp.inf
    pts = _fog_breaks(h, mu, t0, t1, H, zero)
    return mp.quad(c, pts)


FOG_CASES = [(h, mu, t0, t1) for h in FOG_HEIGHTS for mu in FOG_MUS for t0, t1 in FOG_SEGS]


@pytest.mark.parametrize("kernel,ref", [(hf.exponential_optical_depth_np, ref_exponential),
                                        (hf.linear_optical_depth_np, ref_linear)])
def test_fog_optical_depth(kernel, ref):
    sigma0 = 0.03
    c = np.array(FOG_CASES).T
    with np.errstate(over="ignore"):  # numpy notices the inf that overflowing densities give
        got = kernel(sigma0, c[0], c[1], c[2], c[3], FOG_H)
    want = [float(sigma0 * ref(h, mu, t0, t1, FOG_H)) for h, mu, t0, t1 in FOG_CASES]
    err = _rel(got, want)
    assert err.max() <= RTOL, (err.max(), FOG_CASES[int(np.argmax(err))])
    assert not np.any(np.isnan(got))


def test_constant_fog():
    assert hf.constant_optical_depth(0.0, 0.0, INF) == 0.0
    assert hf.constant_optical_depth(0.5, 1.0, INF) == INF
    assert hf.constant_optical_depth(0.5, 1.0, 3.0) == 1.0
    assert hf.constant_distance(0.5, 1.0, 1.0) == 3.0
    assert hf.constant_distance(0.0, 1.0, 1.0) == INF


@pytest.mark.parametrize("forward,inverse", [(hf.exponential_optical_depth, hf.exponential_distance),
                                             (hf.linear_optical_depth, hf.linear_distance)])
def test_fog_distance(forward, inverse):
    """As test_atmosphere_distance, for the closed-form inverses (eq. 31, 35)."""
    sigma0, H = 0.03, FOG_H
    worst = 0.0
    for h in FOG_HEIGHTS:
        for mu in FOG_MUS:
            for t0 in (0.0, 2 * H):
                total = forward(sigma0, h, mu, t0, INF, H)
                if total == 0.0:
                    assert inverse(sigma0, h, mu, t0, 1.0, H) == INF
                    continue
                for tau in _targets(total):
                    t = inverse(sigma0, h, mu, t0, tau, H)
                    assert t0 <= t < INF
                    got = forward(sigma0, h, mu, t0, t, H)
                    density = forward(1.0, h, mu, t, t + 1e-6 * max(1.0, t), H) / (1e-6 * max(1.0, t))
                    slack = _resolution(sigma0, t, density)
                    worst = max(worst, max(0.0, abs(got - tau) - slack) / tau)
                if total < INF:
                    assert inverse(sigma0, h, mu, t0, 1.01 * total + 1e-300, H) == INF
    assert worst <= RTOL, worst


def test_exponential_fog_extremes():
    H = 10.0
    # far below the reference height looking up: the density at the origin overflows the ratio
    assert hf.exponential_optical_depth(1.0, -8000.0, -1e-3, 0.0, 10.0, H) == INF
    t = hf.exponential_distance(1.0, 1e4, -1.0, 0.0, 1.0, H)  # from 1000 H above, down to ~2.3 H
    assert hf.exponential_optical_depth(1.0, 1e4, -1.0, 0.0, t, H) == pytest.approx(1.0, rel=1e-12)
    assert hf.exponential_optical_depth(1.0, 0.0, -1.0, 0.0, INF, H) == INF
    assert hf.exponential_optical_depth(1.0, 0.0, 0.0, 0.0, INF, H) == INF


# ---- the atmosphere medium: columns clipped to the top and blocked by the ground, free paths ----

from raytrace.media import atmosphere as atm  # noqa: E402

EARTH_R, EARTH_TOP = 6360e3, 6420e3
LAYERS_H = np.array([8e3, 1.2e3])
LAYERS_KT = np.array([3.31e-5, 4.44e-6])  # blue Rayleigh, Mie extinction at the ground


def mp_shell(h, mu, R, top):
    """[t_in, t_out] (t >= 0) of the ray inside the sphere of radius `top`, at 30 digits, or None."""
    r0, mu = mp.mpf(R) + mp.mpf(h), mp.mpf(mu)
    b2 = r0 * r0 * (1 - mu * mu)
    if b2 >= mp.mpf(top) ** 2:
        return None
    half = mp.sqrt(mp.mpf(top) ** 2 - b2)
    t_in, t_out = -r0 * mu - half, -r0 * mu + half
    return (max(t_in, mp.mpf(0)), t_out) if t_out > 0 else None


def _space_cases():
    """Origins on the ground, inside the air, at the top, and in space (100 km, one and three
    radii up); directions up, horizontal, below the horizon, grazing the ground and the top."""
    cases = []
    for hh in (0.0, 5e3, 60e3, 100e3, EARTH_R, 3 * EARTH_R):
        mus = [1.0, 0.3, 0.0, -0.05, -0.3, -1.0]
        if hh > 0:
            mus += grazing_mus(hh, EARTH_R)
        if hh > 60e3:  # tangent to the top, rotated by -+1e-7 rad (entering, missing)
            mu_t = -math.sqrt(1.0 - (EARTH_TOP / (EARTH_R + hh)) ** 2)
            th = math.acos(mu_t)
            mus += [math.cos(th + 1e-7), math.cos(th - 1e-7)]
        cases += [(hh, mu) for mu in mus]
    return cases


SPACE_CASES = _space_cases()


def mp_ground(h, mu, R):
    """The first hit of the ground at 30 digits, or inf."""
    r0, mu = mp.mpf(R) + mp.mpf(h), mp.mpf(mu)
    disc = (r0 * mu) ** 2 - (r0 - R) * (r0 + R)
    if mu >= 0 or disc <= 0:
        return mp.inf
    return (r0 - R) * (r0 + R) / (-r0 * mu + mp.sqrt(disc))


def ref_clipped(h, mu, t1, H):
    """The column over [0, t1] (t1 None: to the ground or to infinity) inside the top sphere, with
    every end computed at 30 digits from (h, mu)."""
    shell = mp_shell(h, mu, EARTH_R, EARTH_TOP)
    t1 = mp_ground(h, mu, EARTH_R) if t1 is None else mp.mpf(t1)
    if shell is None or shell[0] >= t1:
        return mp.mpf(0)
    return ref_column(h, mu, shell[0], min(shell[1], t1), EARTH_R, H)


def test_columns_clipped_to_the_top_and_blocked_by_the_ground():
    """atmosphere.columns over [0, inf) and [0, ground]: False (transmittance 0) exactly when the
    ground is met; else the mpmath column of each layer over the part inside the top sphere, to
    1e-12 relative or, where a ray grazes the top or the ground from far away, to 4 ulps of mu's
    own effect (the answer's condition number in mu, measured by mpmath, times 4 eps: one ulp of
    mu moves the tangent chord's ends; measured worst 0.6 of that)."""
    worst = worst_cond = 0.0
    cols = np.empty(2)
    eps = np.finfo(float).eps
    for hh, mu in SPACE_CASES:
        tg = ch.ground_distance(hh, mu, EARTH_R)
        assert atm.columns(hh, mu, 0.0, INF, EARTH_R, EARTH_TOP, LAYERS_H, cols) == (tg == INF)
        for t1 in (None, 0.5 * tg if tg < INF else 1e5):
            assert atm.columns(hh, mu, 0.0, tg if t1 is None else t1, EARTH_R, EARTH_TOP, LAYERS_H, cols)
            for i, H in enumerate(LAYERS_H):
                ref = ref_clipped(hh, mu, t1, H)
                if ref == 0:
                    assert cols[i] == 0.0
                    continue
                d = mp.mpf(mu) * mp.mpf("1e-12") if mu != 0.0 else mp.mpf("1e-12")
                cond = abs(ref_clipped(hh, mp.mpf(mu) + d, t1, H) - ref_clipped(hh, mp.mpf(mu) - d, t1, H)) / (2 * d)
                cond = abs(float(cond * (mp.mpf(mu) if mu != 0.0 else 1) / ref))
                err = abs(cols[i] - float(ref)) / float(ref)
                worst = max(worst, err)
                worst_cond = max(worst_cond, err / max(RTOL, 4.0 * eps * cond))
    print(f"worst {worst:.3g}, worst against 4 eps cond {worst_cond:.3g}")
    assert worst_cond <= 1.0, (worst, worst_cond)


def test_free_path_through_layers():
    """atmosphere.free_path, the inverse of the summed layers' optical depth over a segment inside
    the air: sum_i kt_i column_i(A, x) = target by mpmath to 1e-12 (or within two ulps of x times
    the extinction there), for targets from 1e-9 to 1 - 1e-6 of the segment's total."""
    worst = 0.0
    cols = np.empty(2)
    row = np.empty((1, atm.ROW))
    for hh, mu in SPACE_CASES:
        w = np.array([math.sqrt(1.0 - mu * mu), mu, 0.0])
        o = np.array([[0.0, EARTH_R + hh, 0.0]])
        tg = ch.ground_distance(hh, mu, EARTH_R)
        atm.segment_rows(o, w[None, :], np.array([tg]), np.zeros((1, 3)), np.zeros((1, 3)), np.zeros(1, np.int64),
                         np.zeros(1, bool), 0.0, 0.0, 0.0, EARTH_R, EARTH_TOP, row)
        a, b = row[0, atm.A], row[0, atm.B]
        if not b > a:
            continue
        atm.columns(row[0, atm.H0], row[0, atm.MU0], a, b, EARTH_R, EARTH_TOP, LAYERS_H, cols)
        total = float(LAYERS_KT @ cols)
        for f in (1e-9, 1e-3, 0.3, 0.9, 1.0 - 1e-6):
            x = atm.free_path(row[0], a, b, f * total, LAYERS_KT, LAYERS_H, EARTH_R, EARTH_TOP, cols)
            assert a <= x <= b
            h0, mu0 = row[0, atm.H0], row[0, atm.MU0]  # mu from the direction vector: within an ulp of mu
            got = sum(k * ref_column(h0, mu0, a, x, EARTH_R, H) for k, H in zip(LAYERS_KT, LAYERS_H))
            ext = atm.extinction_at(x, row[0], LAYERS_KT, LAYERS_H, EARTH_R)
            slack = 2.0 * ext * np.spacing(x)
            worst = max(worst, max(0.0, abs(float(got) - f * total) - slack) / (f * total))
    print(f"free path: worst {worst:.3g} beyond the resolution of x")
    assert worst <= RTOL, worst
