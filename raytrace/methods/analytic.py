"""`analytic`: the closed-form air-light of Pegoraro & Parker 2009 (PP09), to a requested precision
(METHODS.md §1, §3-6).

Scalar njit kernels, one (ray, light, colour channel) per call:

    Lm = int_0^ell exp(-kt x) ks Phi_c(cos phi(x)) I exp(-kt d(x)) / d(x)^2 dx

Geometry: light at signed projection ``xh`` on the ray, distance ``h`` > 0 from the ray line,
distance ``da`` from the ray origin; segment [0, ell], ell may be +inf.

Paths (counted in ``stats``):
  series    the paper's Fig. 2 loop for I0/I1 (used while rho_max <= rho_switch(precision));
  stable    scaled-E1 form (METHODS §5 boxed formula; exponentials folded into the optical path
            kt*(x + d), so nothing overflows for lights far behind the camera);
  near-line light (almost) on the ray line outside the segment: h -> 0 limit (closed forms), where
            its error bound meets the precision;
  fallback  the reference quadrature (quadrature.py) at precision / 10: segments so short in angle
            that the closed form's two end terms cancel beyond double precision, and, in the exact
            anisotropic mode, rays whose H = kt h is too large for the forward moment recurrence
            (all of a block's rays where no series of bounded length meets the precision); its
            evaluations that did not converge are counted too (ST_FALLBACK_CAPPED).

Anisotropic modes: ANISO_TAYLOR (PP09 eqs. 14-19, Maclaurin series of Phi in v with `terms`
coefficients, faithful incl. its divergence for v > R) and ANISO_EXACT (beyond the paper, in the
spirit of METHODS §6.5): the phase function as a Legendre series (exact for Rayleigh; for HG its
length follows `precision`), rewritten as a cosine series sum_k c_k cos(k phi) with positive,
well-conditioned weights, and integrated against e^{-H tan(phi/2)} through the Fourier moments
E_k = int e^{-H tan(phi/2)} e^{ik phi} dphi, which obey a three-term recurrence started from
I0 and I1 (legendre_moments.py). Forward, the recurrence is stable while H L is moderate; rays
beyond the measured limit H_max(precision) go to the quadrature fallback and are counted. For HG
a ladder of shorter series, each fitted only beyond an angle from the peak (FAR_ANGLES), serves
the rays that never look closer to it (`exact_coeffs`).

Below a precision of 1e-7 the kernels work 1000 times finer than requested (`working_precision`).
"""
import functools
import math

import numpy as np
from numba.core import types

from .. import error_bounds
from ..jit import exact_njit, njit
from . import AREA_LIGHTS, ErrorLaw, Interiors, Method, Param, Supports
from .geometry import by_channel, cone_row, v_of
from ..media.expint import VECTOR_BLOCK, g_scaled, en_scaled, i01_series_est, i01_series_lanes, vector_exp
from ..lights import (ENVIRONMENT, LAMBERT, band_slope, band_trig, cone_breaks, falloff, has_cone, polynomial_band,
                      segment_cone)
from ..lights.spot import CUT_TOL, cosine_at, lambert_trig
from ..media.legendre_moments import (FORWARD_ERR_PER_LOSS, cosine_moments_forward, cosine_moments_lanes, forward_loss,
                               hg_legendre, legendre_to_cosine, rayleigh_legendre, start_sensitivity, times_trig,
                               trig_moments_forward)
from ..media.phase import HG, INV_4PI, ISOTROPIC, RAYLEIGH, hg, phase_split, phase_value
from ..media.inside_rule import QUAD
from ..media.gauss import N10, N20, W10, W20
from .quadrature import CAPPED
from .quadrature import _rule as quad_rule
from .quadrature import airlight_one as quad_airlight

ANISO_TAYLOR = 0
ANISO_EXACT = 1

# ---- stats slots (float64 array of length STATS_SIZE, accumulated) ----
ST_EVALS = 0            # number of air-light evaluations (kernel calls)
ST_SERIES_ITERS = 1     # total iterations of the Fig. 2 loop
ST_SERIES = 2           # evaluations on the series path
ST_STABLE = 3           # evaluations on the stable scaled-E1 path
ST_NEARLINE = 4         # evaluations on the near-line (h -> 0) path
ST_FALLBACK = 5         # evaluations on the adaptive-quadrature fallback
ST_TAYLOR_OUT = 6       # Taylor evaluations whose v-interval leaves the convergence radius
ST_ZERO = 7             # trivial evaluations (ks = 0, empty segment)
ST_FALLBACK_FEVALS = 8  # integrand evaluations spent in the fallback
ST_SERIES_REJECTED = 9  # series results rejected by the rounding-error guard or max_iter (then stable)
ST_FALLBACK_CAPPED = 10  # fallback evaluations the quadrature did not converge (quadrature.CAPPED)
ST_BANDS = 11           # spot smoothstep-band pieces evaluated in closed form
ST_PIECE_QUAD = 12      # spot pieces integrated by quadrature (no closed form, or a narrow band's terms cancel)
STATS_SIZE = 13

# ---- switching criteria (measured, see tests / report) ----
# series loses ~log10(e^rho) digits: use it while 30*eps*e^rho <= precision, and (cost: the loop
# needs ~3 rho + 5 iterations of two complex products, 150-250 ns at rho 8-16, where the two scaled-E1
# evaluations near the imaginary axis take 600-1000 ns; a series its rounding guard rejects costs both)
# rho <= 16: measured, the series first is cheaper on average up to rho ~ 20 at precision 1e-3 (85% of
# them accepted at rho 16-18) and ~ 17 at 1e-6 (40%)
RHO_SWITCH_CAP = 16.0
CAP_PRECISION = 1e-7  # log(1e-7 / (30 eps)) = 16.5 > RHO_SWITCH_CAP: from here on rho_switch is the cap
# a-posteriori: series accepted if its rounding-error estimate <= SERIES_SAFETY*precision*I0
SERIES_SAFETY = 0.1
# relative accuracy of g_scaled (measured against mpmath: <= 2.3e-14), for the cancellation guard
G_REL_ERR = 3e-14
# near-line: light outside the segment, h/|x_end - xh| < NEARLINE_TOL at both ends, and the h -> 0
# limit within SERIES_SAFETY * precision (`_nearline`)
NEARLINE_TOL = 3e-6

_EPS = 2.220446049250313e-16
UNDERFLOW_PATH = 745.0  # e^{-745} is the smallest positive double


@njit
def rho_switch(precision):
    """Largest rho for which the Fig. 2 series meets `precision` (loss ~ 1e-16 e^rho * 30), at most
    RHO_SWITCH_CAP (reached from CAP_PRECISION on, where the logarithm is skipped)."""
    if precision >= CAP_PRECISION:
        return RHO_SWITCH_CAP
    r = math.log(precision / (30.0 * _EPS))
    if r > RHO_SWITCH_CAP:
        r = RHO_SWITCH_CAP
    return r


QUAD_RTOL_MIN = 1e-13  # the quadrature cannot resolve finer differences of its 10- and 20-point rules
LOSS_TABLE = 17  # points of the tables against H in the exact mode's coeffs
# layout of a coefficient block of the exact mode (`_block`): its range of v, the largest H of the
# forward recurrence and the final sum's ratio for the cosine series (point lights, full-intensity pieces),
# the sum's sensitivity to the start values (`_sensitivity`), the largest H and loss table of the series
# times a spot's smoothstep band (3 orders more), the series
B_VLO, B_VHI, B_HMAX, B_RATIO, B_SENS = 0, 1, 2, 3, 4
B_HMAX_BAND = B_SENS + LOSS_TABLE
B_LOSS_BAND = B_HMAX_BAND + 1
B_C = B_LOSS_BAND + LOSS_TABLE
BAND_ORDER = 3  # a polynomial band is at most cubic in the cosine to the spot axis: a degree-3 trig polynomial
# a band of a phase series longer than this is first tried by one Gauss-Legendre step (`_gauss_piece`):
# the series times the band's cubic cancels (HG g = 0.9 at 1e-6: 224 terms, the closed form met its
# bound on 10% of a box room's bands), and 30 integrand values cost less than 2 L + 7 L operations
BAND_GAUSS_FIRST = 48
BAND_MARGIN = 0.01  # a band's K1, L1 are computed this much finer than its polynomial's terms need
# a row of `evaluate_segments`' batch of moment recurrences (`checked_airlight`'s `pending`): the arguments of
# cosine_moments_forward, the start of the block in coeffs (0: nothing pending), the factor 2 I / h and, where
# the Fig. 2 loop that gives K1 and L1 is pending too (`_pending_series`), its precision (else 0; where it is
# pending, E1 and E2 hold their exponents until `_pending_series` takes their exponentials)
P_H, P_V1, P_V2, P_K1, P_L1, P_E1, P_E2, P_BLOCK, P_PREF, P_PREC = range(10)
PENDING = 10
NOTHING_PENDING = (0.0,) * PENDING  # a row with P_BLOCK 0


@njit
def _quadrature(xh, h, ell, kt, ks, intensity, phase_code, g, cone, precision, stats):
    """The reference quadrature (quadrature.py) to a tenth of the requested precision, its integrand
    evaluations counted, and whether it converged (not quadrature.CAPPED). Its Gauss-Legendre nodes are module constants of quadrature.py (numba
    freezes them, and they never change)."""
    qstats = np.zeros(3)
    rtol = max(0.1 * precision, QUAD_RTOL_MIN)
    val = quad_airlight(xh, h, ell, kt, ks, phase_code, g, cone, rtol, N10, W10, N20, W20, qstats)
    stats[ST_FALLBACK_FEVALS] += 30.0 * qstats[1]
    stats[ST_FALLBACK_CAPPED] += qstats[CAPPED]
    return intensity * val, qstats[CAPPED] == 0.0


@njit
def _fallback(xh, h, ell, kt, ks, intensity, phase_code, g, cone, precision, stats, quadrature):
    """The whole segment by `_quadrature`, counted: (value, converged); (nan, False) where
    `quadrature` is None (deferred, `checked_airlight`)."""
    if quadrature is None:
        return math.nan, False
    stats[ST_FALLBACK] += 1.0
    return _quadrature(xh, h, ell, kt, ks, intensity, phase_code, g, cone, precision, stats)


# ----------------------------------------------------------------------------------------------
# building blocks
# ----------------------------------------------------------------------------------------------
@njit
def _nearline(xh, h, da, ell, kt, ks, intensity, code, g, dmin, precision):
    """h -> 0 limit with the light on the line outside the segment, D = dmin from its nearer end,
    and whether it meets `precision`. Its relative error, to first order in (h/D)^2: (h/D)^2 from
    1/d^2, (h/D)^2 / 2 max|d ln Phi / d mu| from the phase function h/D off the line (HG:
    3|g| / (1 - |g|)^2, 3e4 at |g| = 0.99), kt h^2 / (2D) from the optical path; with the light
    behind a finite segment the two ends' terms cancel (the stable path's guard)."""
    slope = 0.0
    if code == RAYLEIGH:
        slope = 1.0
    elif code == HG:
        slope = 3.0 * abs(g) / ((1.0 - abs(g)) * (1.0 - abs(g)))
    e2 = (h / dmin) * (h / dmin)
    ok = e2 * (1.0 + 0.5 * slope + 0.5 * kt * dmin) <= SERIES_SAFETY * precision
    if xh > 0.0:
        # light ahead: x + d = xh constant, int dx/(xh-x)^2 = ell/(xh (xh-ell))
        val = phase_split(code, g, 1.0, 0.0, 2.0) * math.exp(-kt * da) * ell / (xh * (xh - ell))
        return intensity * ks * val, ok
    c = -xh
    s = 2.0 * kt
    val = math.exp(-kt * da) * en_scaled(2, s * c) / c
    if ell < math.inf:
        cb = c + ell
        end = math.exp(-kt * (c + 2.0 * ell)) * en_scaled(2, s * cb) / cb
        ok = ok and G_REL_ERR * (val + end) <= SERIES_SAFETY * max(precision, 1e-11) * (val - end)
        val -= end
    return intensity * ks * phase_split(code, g, -1.0, 2.0, 0.0) * val, ok


@njit
def _taylor_poly_part(H, va, vb, Ea, Eb, n):
    """sum_{j=0}^{n-2} (Eb vb^j - Ea va^j) C(-H, j, n) (PP-16/19, folded exponentials)."""
    s = 0.0
    invH = 1.0 / H
    for j in range(0, n - 1):
        # C(-H, j, n) = sum_i (-1)^{(n-i-j)/2} (i+j)!/j! (1/H)^{i+1}, i = (n-2-j)%2 .. n-2-j step 2
        c = 0.0
        i = (n - 2 - j) % 2
        while i <= n - 2 - j:
            f = 1.0
            for q in range(j + 1, i + j + 1):
                f *= q
            sg = 1.0 if ((n - i - j) // 2) % 2 == 0 else -1.0
            c += sg * f * invH ** (i + 1)
            i += 2
        tb = 0.0
        if vb < math.inf:
            tb = Eb * vb ** j
        s += (tb - Ea * va ** j) * c
    return s


@njit
def _spot_nearline(xh, h, dmin, cone, precision):
    """The spot falloff for the near-line limit (`_nearline`): on a segment within h/D of the line
    through the light the cosine to the axis is within dc = h / D of +-B (B ahead of the light,
    -B behind it); returns (factor, ok), ok if the falloff's variation over that range (slope at most
    `lights.band_slope` / (cos_start - cos_end)) is within the precision, or the range lies wholly
    outside the cone or inside its core."""
    c0 = cone[1] if xh < 0.0 else -cone[1]
    dc = h / dmin
    if c0 + dc <= cone[2]:
        return 0.0, True
    if c0 - dc >= cone[3]:
        return 1.0, True
    f = falloff(c0, cone[2], cone[3], cone[4])
    band = cone[3] - cone[2]
    return f, band > 0.0 and band_slope(cone[2], cone[3], cone[4]) * dc <= SERIES_SAFETY * precision * f * band


# the paths a piece took (`_piece`, `_band_piece`) or a point light's segment (`_point_airlight`), returned as
# bits of a number for `_count`
F_SERIES, F_REJECTED, F_STABLE, F_TAYLOR_OUT, F_BAND, F_ZERO, F_NEARLINE = 1, 2, 4, 8, 16, 32, 64


@njit(inline="always")
def _count(stats, iterations, flags):
    """A piece's or a segment's statistics: the Fig. 2 loop's iterations and the paths in `flags` (F_*)."""
    stats[ST_SERIES_ITERS] += iterations
    if flags & F_SERIES:
        stats[ST_SERIES] += 1.0
    if flags & F_REJECTED:
        stats[ST_SERIES_REJECTED] += 1.0
    if flags & F_STABLE:
        stats[ST_STABLE] += 1.0
    if flags & F_TAYLOR_OUT:
        stats[ST_TAYLOR_OUT] += 1.0
    if flags & F_BAND:
        stats[ST_BANDS] += 1.0
    if flags & F_ZERO:
        stats[ST_ZERO] += 1.0
    if flags & F_NEARLINE:
        stats[ST_NEARLINE] += 1.0


@njit
def _e1_ends(H, v1, v2, E1, E2, prec_i):
    """(K1, L1, rel, ok): I0, I1 over v1 < v < v2 by the scaled-E1 form at both ends, folded with the
    optical paths (E1, E2 = e^{-kt p} at the ends), and their relative accuracy rel; not ok where the
    piece is so short in angle that the two ends' terms cancel beyond what g's accuracy resolves."""
    ga = g_scaled(complex(H * v1, H))
    K1 = -E1 * ga.imag
    L1 = E1 * ga.real
    ends = abs(K1)
    if v2 < math.inf:
        gb = g_scaled(complex(H * v2, H))
        K1 += E2 * gb.imag
        L1 -= E2 * gb.real
        ends += E2 * abs(gb.imag)
    if G_REL_ERR * ends > SERIES_SAFETY * max(prec_i, 1e-11) * abs(K1):
        return K1, L1, 0.0, False
    return K1, L1, G_REL_ERR * ends / abs(K1) if K1 != 0.0 else prec_i, True


@njit(inline="always")
def _piece(H, kt, xh, v1, v2, p1, p2, phase_code, g, aniso_mode, terms, coeffs, precision, max_iter, aniso, defer,
           taylor_mode):
    """(S, ok, iterations, flags, K1, L1, E1, E2, start, prec_s) for the piece v1 < v < v2 of a segment
    (0 <= v1 < v2 <= inf) at the light's full intensity: S = int w(phi) Phi(cos phi) dphi / 2 (w = e^{-H v},
    folded with the optical paths p1, p2 = x + d at the ends; the Taylor mode's PP-19 sum approximates
    it); not ok: a closed form here would miss the precision (quadrature). Its statistics (the Fig. 2
    loop's iterations, the paths taken as F_* bits: `_count`) and the batch's row are returned, not
    written into arrays. Inlined into `checked_airlight` by numba (inline="always"): an array handed to
    a call costs numba a reference count (an atomic increment and decrement), and the call itself and
    its results passed through memory cost more (inlined, the kernel takes about 40 ns less per
    segment; the default scene's compile barely changes, as its isotropic medium prunes most of this
    function). `aniso` None: an isotropic
    phase function, and the anisotropic code is not compiled (such a piece is then not ok). `taylor_mode`
    None: the Taylor mode's code is not compiled (such a piece is then not ok: a spot light's, which `mode_for`
    refuses in that mode, or a render's in the exact mode). `defer`:
    the exact mode's moment recurrence is left to the caller (`_pending_recurrences`): S is then 0,
    start > 0 the start of the coefficient block in `coeffs`, and K1, L1, E1, E2 the recurrence's
    arguments with H, v1, v2 (start is 0 where nothing is left); where the Fig. 2 loop would give K1 and L1,
    it is left to the caller too (`_pending_series`): K1 and L1 are then 0, E1 and E2 the exponents -kt p1,
    -kt p2 (the caller takes their exponentials, a vector of segments at a time), prec_s > 0 the loop's
    precision (else 0), and the statistics are the caller's to count."""
    exact = phase_code != ISOTROPIC and aniso_mode == ANISO_EXACT
    start, n = 0, 0  # the block in coeffs (offsets, not a slice: a slice costs numba a reference count)
    prec_i = precision
    if aniso is not None:  # (numba prunes the branch where it is None: nothing of the blocks compiled)
        if exact:
            # I0, I1 folded with e^{-kt xh}: K1 = e^{-kt xh} I0, L1 = e^{-kt xh} I1. The exact anisotropic
            # mode's sum S is linear in them: their errors, at most prec_i K1 each, move S by at most
            # sens sum|c_k| prec_i K1 (sens tabulated against H in the block, `_sensitivity`), S >= min(Phi) K1,
            # block[B_RATIO] = 0.1 min(Phi) / sum|c_k|: a tenth of the precision
            start, n, sens = _block_at(coeffs, v1, v2, H, B_HMAX)
            if sens == math.inf:  # the moment recurrence would lose digits: quadrature
                return 0.0, False, 0.0, 0, 0.0, 0.0, 0.0, 0.0, 0, 0.0
            prec_i = max(1e-15, precision * coeffs[start + B_RATIO] / sens)
    rho_max = H * math.sqrt(1.0 + v2 * v2)
    iterations, flags = 0.0, 0
    use_series = rho_max <= RHO_SWITCH_CAP and rho_max <= rho_switch(prec_i)
    if use_series and defer and exact:  # (`exact` only where the anisotropic code is compiled)
        return 0.0, True, 0.0, 0, 0.0, 0.0, -kt * p1, -kt * p2, start, prec_i
    if use_series:
        i0, i1, it, err = i01_series_est(-H, v1, v2, prec_i, max_iter)
        iterations = float(it)
        # a-posteriori guard: estimated rounding error vs the requested precision; a loop that
        # used all max_iter iterations may not have converged
        if it >= max_iter or not (err <= SERIES_SAFETY * prec_i * i0):
            use_series = False
            flags |= F_REJECTED
        else:
            flags |= F_SERIES
            f = math.exp(-kt * xh)
            K1 = f * i0
            L1 = f * i1
            if phase_code == ISOTROPIC:
                return INV_4PI * K1, True, iterations, flags, 0.0, 0.0, 0.0, 0.0, 0, 0.0
    E1 = math.exp(-kt * p1)
    E2 = math.exp(-kt * p2)
    if not use_series:
        K1, L1, _, ok = _e1_ends(H, v1, v2, E1, E2, prec_i)
        if not ok:
            return 0.0, False, iterations, flags, 0.0, 0.0, 0.0, 0.0, 0, 0.0
        flags |= F_STABLE
    if phase_code == ISOTROPIC:
        return INV_4PI * K1, True, iterations, flags, 0.0, 0.0, 0.0, 0.0, 0, 0.0
    if aniso is None:  # (numba prunes the code below where it is None)
        return 0.0, False, iterations, flags, 0.0, 0.0, 0.0, 0.0, 0, 0.0

    if aniso_mode == ANISO_TAYLOR:
        if taylor_mode is None:  # (numba prunes the code below where it is None)
            return 0.0, False, iterations, flags, 0.0, 0.0, 0.0, 0.0, 0, 0.0
        # PP-19 with N = terms coefficients c_n of Phi in v
        R = 1.0
        if phase_code == HG and g > 0.0:
            R = (1.0 - g) / (1.0 + g)
        if v2 > R:
            flags |= F_TAYLOR_OUT
        acc = 0.0
        nmax = min(terms, coeffs.shape[0])
        for n in range(nmax):
            cn = coeffs[n]
            if cn == 0.0:
                continue
            sg = -1.0 if ((n % 4) // 2) == 1 else 1.0
            base = K1 if n % 2 == 0 else L1
            acc += cn * (_taylor_poly_part(H, v1, v2, E1, E2, n) + sg * base)
        return acc, True, iterations, flags, 0.0, 0.0, 0.0, 0.0, 0, 0.0

    # exact: Phi as a cosine series, its Fourier moments by the forward recurrence
    if defer:
        return 0.0, True, iterations, flags, K1, L1, E1, E2, start, 0.0
    S = 0.5 * cosine_moments_forward(H, v1, v2, K1, L1, E1, E2, coeffs[start + B_C:start + n])
    return S, True, iterations, flags, 0.0, 0.0, 0.0, 0.0, 0, 0.0


@njit
def _band_piece(H, kt, v1, v2, p1, p2, coeffs, precision, work):
    """(S, err, ok, flags) for the piece v1 < v < v2 of a segment in a spot's polynomial band (smoothstep,
    gltf or an emitter point's lambert, docs/spot_lights.md): S = int w(phi) Phi(cos phi) F dphi / 2 (folded
    as `_piece`'s), F the band's polynomial; err bounds its rounding; not ok: a closed form here would miss the
    precision (quadrature); flags: the paths taken (F_*, `_count`). `work`: F as a trigonometric series
    (a, b: `band_trig`, or `lambert_trig`, filled by the caller) in its first 2 (BAND_ORDER + 1) values, then
    scratch for 2 (len(coeffs) + BAND_ORDER) + 8 values."""
    start, n, loss = _block_at(coeffs, v1, v2, H, B_HMAX_BAND)
    if loss == math.inf:  # the moment recurrence would lose digits: quadrature
        return 0.0, 0.0, False, 0
    # F Phi as a trigonometric series of order L + 3 (gc, gs); its terms' size bounds the
    # cancellation of the final sum, so K1 and L1 are wanted that much more accurately
    a = work[:BAND_ORDER + 1]
    b = work[BAND_ORDER + 1:2 * BAND_ORDER + 2]
    c = coeffs[start + B_C:start + n]
    m = c.shape[0] + BAND_ORDER
    gc = work[2 * BAND_ORDER + 2:2 * BAND_ORDER + 2 + m]
    gs = work[2 * BAND_ORDER + 2 + m:2 * BAND_ORDER + 2 + 2 * m]
    size = times_trig(c, a, b, gc, gs)  # sum of |coefficients|
    prec_i = max(1e-15, precision * coeffs[start + B_RATIO] / loss)
    prec_i = max(1e-15, prec_i * BAND_MARGIN / (np.sum(np.abs(a)) + np.sum(np.abs(b))))
    # (a band's K1, L1 are wanted finer than the series' rounding on a piece short in angle allows:
    # the scaled-E1 ends at once)
    E1 = math.exp(-kt * p1)
    E2 = math.exp(-kt * p2)
    K1, L1, rel, ok = _e1_ends(H, v1, v2, E1, E2, prec_i)
    if not ok:
        return 0.0, 0.0, False, F_BAND
    # its moments' rounding (relative `rel` from K1, L1, times the recurrence's loss) is bounded by
    # |E_k| <= E_0 = 2 K1
    val = 0.5 * trig_moments_forward(H, v1, v2, K1, L1, E1, E2, gc, gs)
    return val, (rel + FORWARD_ERR_PER_LOSS) * loss * abs(K1) * size, True, F_BAND | F_STABLE


@njit
def airlight(xh, h, da, ell, kt, ks, intensity, phase_code, g, precision, max_iter,
             aniso_mode, terms, coeffs, cone, stats):
    """Air-light Lm of one light along one ray segment [0, ell] for one channel (`checked_airlight`'s
    value)."""
    return checked_airlight(xh, h, da, ell, kt, ks, intensity, phase_code, g, precision, max_iter, aniso_mode,
                            terms, coeffs, cone_row(cone), stats, True, True, True, False)[0]


@njit
def checked_airlight(xh, h, da, ell, kt, ks, intensity, phase_code, g, precision, max_iter,
                     aniso_mode, terms, coeffs, cone, stats, quadrature, spots, aniso, defer):
    """(Lm, met, pending): the air-light Lm of one light along one ray segment [0, ell] for one channel, and
    whether it is known to meet `precision` (error_bounds.py): False where a quadrature it fell back
    on did not converge (ST_FALLBACK_CAPPED) and in the Taylor mode of an anisotropic medium (the
    paper's series, an approximation with no bound); True on every other path, each of which is
    accepted only where its own error estimate meets the precision.

    xh: signed projection of the light on the ray; h (>0): light-to-line distance; da: light
    distance from the ray origin; ell: segment length (may be +inf); kt, ks: extinction and
    scattering; intensity: radiant intensity; phase_code/g: phase.py codes; precision and
    max_iter: Fig. 2 loop control; aniso_mode: ANISO_TAYLOR / ANISO_EXACT (ignored for
    isotropic); terms: number N of Taylor coefficients; coeffs: float64 array from
    `make_coeffs` (Taylor: c_0..c_{N-1}; exact: coefficient blocks, see `exact_coeffs`; spot
    lights need the exact mode's); cone: the segment's cone row as a tuple (geometry.cone_row; a spot light's
    segment is cut where it crosses the cone's edge and core, `lights.segment_cone`); stats:
    float64[STATS_SIZE] accumulator; quadrature: True, or None to defer the segments that need the
    reference quadrature: they return (nan, False), and the quadrature's code is not compiled in
    this specialisation (numba prunes the branches of an argument typed None); spots: True, or None
    to defer the segments of a light with a cone likewise (the spot code is then not compiled);
    aniso: True, or None to defer those in an anisotropic medium (its phase function's code);
    defer: whether a point light's moment recurrence in the exact mode is left to the caller
    (`evaluate_segments`' batch): the value returned is then 0, and `pending` its row of the batch
    (P_* offsets: P_BLOCK > 0, P_PREF the factor 2 I / h of the air-light); NOTHING_PENDING where
    nothing is left. Returned, not written into the batch: an array handed to a call costs numba a
    reference count. With `quadrature` None a segment left nan is not counted in `stats` (the pass
    with the quadrature counts it).

    A light without a cone takes `_point_airlight` (inlined), a spot light's segment `_spot_airlight`
    (compiled once on its own), an area light's emitter point `_lambert_airlight` (likewise).
    `evaluate_segments` makes the same choice itself, with
    `_point_airlight` inlined into its loop over the segments: that loop then hands no array to a call
    for a point light's segment (each costs numba a reference count: an atomic increment and
    decrement), and nothing of the spot's code is compiled into it.
    """
    if has_cone(cone[3]):
        if spots is None:
            return math.nan, False, NOTHING_PENDING
        if cone[4] == LAMBERT:
            val, met = _lambert_airlight(xh, h, da, ell, kt, ks, intensity, phase_code, g, precision, aniso_mode,
                                         coeffs, cone, stats, quadrature)
        else:
            val, met = _spot_airlight(xh, h, da, ell, kt, ks, intensity, phase_code, g, precision, max_iter,
                                      aniso_mode, terms, coeffs, cone, stats, quadrature, aniso)
        return val, met, NOTHING_PENDING
    val, met, pending, iterations, flags = _point_airlight(xh, h, da, ell, kt, ks, intensity, phase_code, g,
                                                           precision, max_iter, aniso_mode, terms, coeffs, cone,
                                                           stats, quadrature, aniso, defer, True)
    _tally(stats, quadrature, val, iterations, flags)
    return val, met, pending


@njit(inline="always")
def _tally(stats, quadrature, val, iterations, flags):
    """Counts a point light's segment (`_point_airlight`'s iterations and flags) unless it is left nan to a
    pass with the quadrature (`quadrature` None)."""
    if quadrature is not None or not math.isnan(val):
        stats[ST_EVALS] += 1.0
        _count(stats, iterations, flags)


# what the ends of a segment decide before a closed form (`_front`)
FRONT_ZERO, FRONT_VACUUM, FRONT_NEAR, FRONT_CLOSED = 0, 1, 2, 3


@njit
def _front(xh, h, da, ell, kt, ks, intensity, phase_code, g):
    """(kind, dmin) of a segment: FRONT_ZERO: no air-light (ks = 0, no intensity, an empty segment, or
    so thick optically that its bound underflows); FRONT_VACUUM: vacuum, or so thin that H = kt h
    underflows the closed form's logarithms (the quadrature fallback); FRONT_NEAR: the light outside the
    segment with the line passing within h << dmin of it, dmin its distance from the nearer end (the
    near-line limit, `_nearline`, where it meets the precision); FRONT_CLOSED: the closed form."""
    if ks <= 0.0 or intensity == 0.0 or not (ell > 0.0):
        return FRONT_ZERO, 0.0
    if not (kt * h > 1e-200):
        return FRONT_VACUUM, 0.0
    if kt * da > UNDERFLOW_PATH:
        # optically so thick that the bound I ks max(Phi) pi / h e^{-kt d_a} (the optical path x + d is
        # least, d_a, at the segment's start; int dx / d^2 <= pi / h) underflows: 0, and no inf * 0
        peak = max(phase_value(phase_code, g, 1.0), phase_value(phase_code, g, -1.0))
        if math.log(intensity) + math.log(ks) + math.log(math.pi * peak / h) - kt * da < -UNDERFLOW_PATH:
            return FRONT_ZERO, 0.0
    finite = ell < math.inf
    if xh < 0.0 or (finite and xh > ell):
        dmin = abs(xh)
        if finite and abs(xh - ell) < dmin:
            dmin = abs(xh - ell)
        if h < NEARLINE_TOL * dmin:
            return FRONT_NEAR, dmin
    return FRONT_CLOSED, 0.0


@njit
def _ends_of(xh, h, da, ell, kt, intensity):
    """(H, va, vb, pref, pa, pb) of a segment for the closed form: H = kt h, v = tan(phi / 2) at its ends,
    the factor 2 I / h and the optical paths x + d (light -> end -> camera) at its ends."""
    finite = ell < math.inf
    va = v_of(-xh, h)
    vb = v_of(ell - xh, h) if finite else math.inf
    pb = ell + math.sqrt(h * h + (ell - xh) * (ell - xh)) if finite else math.inf
    # (ks first in pref * (ks * S): ks up to 1.8e308 stays finite)
    return kt * h, va, vb, 2.0 * intensity / h, da, pb


@exact_njit
def _scaled(pref, ks, val):
    """pref * (ks * val), compiled without fastmath and called, not inlined by numba: `_point_airlight`,
    inlined into the loop over a tile's segments, would otherwise let the compiler reassociate the
    product there (ks and the constants taken out of the loop) and round it otherwise than a single call
    (`airlight`) does; as its own function (small: LLVM inlines it, keeping its exact arithmetic) a
    segment's value is the same bits in a batch or alone."""
    return pref * (ks * val)


@njit(inline="always")
def _point_airlight(xh, h, da, ell, kt, ks, intensity, phase_code, g, precision, max_iter, aniso_mode, terms,
                    coeffs, cone, stats, quadrature, aniso, defer, taylor_mode):
    """(Lm, met, pending, iterations, flags): `checked_airlight` of a light without a cone (`taylor_mode`: `_piece`'s).
    Its statistics but the fallback's (the Fig. 2 loop's iterations and the paths taken as F_* bits, `_count`) are
    returned, not written, so that its caller counts a segment left nan (deferred) not at all."""
    kind, dmin = _front(xh, h, da, ell, kt, ks, intensity, phase_code, g)
    if kind == FRONT_ZERO:
        return 0.0, True, NOTHING_PENDING, 0.0, F_ZERO
    if kind == FRONT_VACUUM:
        val, ok = _fallback(xh, h, ell, kt, ks, intensity, phase_code, g, cone, precision, stats, quadrature)
        return val, ok, NOTHING_PENDING, 0.0, 0
    taylor = phase_code != ISOTROPIC and aniso_mode == ANISO_TAYLOR
    if kind == FRONT_NEAR:
        val, ok = _nearline(xh, h, da, ell, kt, ks, intensity, phase_code, g, dmin, precision)
        # the limit where it meets the precision (else the closed form below, or the fallback
        # where its ends cancel); always in the Taylor mode, an approximation anyway, whose
        # polynomial part grows like 1/H^(N-1) as h -> 0
        if ok or taylor:
            return val, ok and not taylor, NOTHING_PENDING, 0.0, F_NEARLINE
    H, va, vb, pref, pa, pb = _ends_of(xh, h, da, ell, kt, intensity)
    val, ok, iterations, flags, K1, L1, E1, E2, start, prec_s = _piece(H, kt, xh, va, vb, pa, pb, phase_code, g,
                                                                       aniso_mode, terms, coeffs, precision, max_iter,
                                                                       aniso, defer, taylor_mode)
    if not ok:
        val, ok = _fallback(xh, h, ell, kt, ks, intensity, phase_code, g, cone, precision, stats, quadrature)
        return val, ok, NOTHING_PENDING, iterations, flags
    if start > 0:
        return 0.0, not taylor, (H, va, vb, K1, L1, E1, E2, float(start), pref, prec_s), iterations, flags
    return _scaled(pref, ks, val), not taylor, NOTHING_PENDING, iterations, flags


@njit
def _spot_airlight(xh, h, da, ell, kt, ks, intensity, phase_code, g, precision, max_iter, aniso_mode, terms,
                   coeffs, cone, stats, quadrature, aniso):
    """(Lm, met): `checked_airlight` of a spot light's segment, counted in `stats` (with `quadrature`
    None only where Lm is not nan: its statistics are gathered apart first)."""
    if quadrature is None:
        own = np.zeros(STATS_SIZE)
        val, met = _spot_body(xh, h, da, ell, kt, ks, intensity, phase_code, g, precision, max_iter, aniso_mode,
                              terms, coeffs, cone, own, quadrature, aniso)
        if not math.isnan(val):
            for k in range(STATS_SIZE):
                stats[k] += own[k]
        return val, met
    return _spot_body(xh, h, da, ell, kt, ks, intensity, phase_code, g, precision, max_iter, aniso_mode, terms,
                      coeffs, cone, stats, quadrature, aniso)


@njit(inline="always")
def _spot_body(xh, h, da, ell, kt, ks, intensity, phase_code, g, precision, max_iter, aniso_mode, terms, coeffs,
               cone, stats, quadrature, aniso):
    """`_spot_airlight`, counting into `stats` whatever the result: the segment cut where it crosses the
    cone's edge and core (`lights.segment_cone`), each piece in closed form (`_piece` at full intensity,
    `_band_piece` in a polynomial band) or, where that misses the precision, by quadrature."""
    stats[ST_EVALS] += 1.0
    kind, dmin = _front(xh, h, da, ell, kt, ks, intensity, phase_code, g)
    if kind == FRONT_ZERO:
        stats[ST_ZERO] += 1.0
        return 0.0, True
    if kind == FRONT_VACUUM:
        return _fallback(xh, h, ell, kt, ks, intensity, phase_code, g, cone, precision, stats, quadrature)
    taylor = phase_code != ISOTROPIC and aniso_mode == ANISO_TAYLOR
    if kind == FRONT_NEAR:
        val, ok = _nearline(xh, h, da, ell, kt, ks, intensity, phase_code, g, dmin, precision)
        f, ok_f = _spot_nearline(xh, h, dmin, cone, precision)
        val *= f
        ok = ok and ok_f
        if ok or taylor:  # (as `_point_airlight`'s)
            stats[ST_NEARLINE] += 1.0
            return val, ok and not taylor
    H, va, vb, pref, pa, pb = _ends_of(xh, h, da, ell, kt, intensity)
    work = np.zeros(25 + 2 * (coeffs.shape[0] + BAND_ORDER + 1) + 8)  # the one allocation of a spot segment
    pieces = work[:15].reshape((5, 3))
    vals = work[15:20]
    errs = work[20:25]
    n = segment_cone(cone[0], cone[1], cone[2], cone[3], va, vb, pieces)
    for i in range(n):
        if pieces[i, 2] == 0.0:
            continue
        if pieces[i, 2] == 2.0 and not polynomial_band(cone[4]):
            errs[i] = math.inf  # a band without a closed form (Mitsuba's curve): the band quadrature below
            continue
        v1, v2 = pieces[i, 0], pieces[i, 1]
        band = pieces[i, 2] == 2.0
        if band and _block_at(coeffs, v1, v2, H, B_HMAX_BAND)[1] - B_C > BAND_GAUSS_FIRST:
            fine, coarse = _gauss_piece(xh, h, kt, phase_code, g, cone, v1, v2)
            if abs(fine - coarse) <= SERIES_SAFETY * precision * fine:
                stats[ST_PIECE_QUAD] += 1.0
                vals[i] = fine
                continue
        p1 = pa if v1 == va else xh + h * v1
        p2 = pb if v2 == vb else xh + h * v2
        if band:
            band_trig(cone[0], cone[1], cone[2], cone[3], cone[4], work[25:26 + BAND_ORDER],
                      work[26 + BAND_ORDER:27 + 2 * BAND_ORDER])
            vals[i], errs[i], ok, flags = _band_piece(H, kt, v1, v2, p1, p2, coeffs, precision, work[25:])
            _count(stats, 0.0, flags)
        else:  # (defer False: a spot's piece runs its moment recurrence here; no Taylor mode)
            vals[i], ok, iterations, flags, _, _, _, _, _, _ = _piece(H, kt, xh, v1, v2, p1, p2, phase_code, g,
                                                                      aniso_mode, terms, coeffs, precision, max_iter,
                                                                      aniso, False, None)

            _count(stats, iterations, flags)
        if not ok:
            errs[i] = math.inf  # no closed form for this piece: quadrature below
    met = True
    total = 0.0
    for i in range(n):
        if errs[i] < math.inf:
            total += vals[i]
    out = pref * (ks * total)
    if np.sum(errs[:n]) > SERIES_SAFETY * precision * total:
        # pieces without a closed form, and narrow bands whose polynomial's terms cancel (each band
        # over its share of the error): quadrature over the piece's own stretch [x1, x2] of the
        # segment (x = x_h + h (v - 1/v) / 2)
        share = SERIES_SAFETY * precision * total / max(1.0, np.sum(errs[:n] > 0.0))
        for i in range(n):
            if errs[i] > share:
                stats[ST_PIECE_QUAD] += 1.0
                v1, v2 = pieces[i, 0], pieces[i, 1]
                old = pref * (ks * vals[i]) if errs[i] < math.inf else 0.0
                fine, coarse = _gauss_piece(xh, h, kt, phase_code, g, cone, v1, v2)
                if abs(fine - coarse) <= SERIES_SAFETY * precision * fine:
                    out += pref * (ks * fine) - old  # one 10/20-point Gauss-Legendre step suffices (smooth, short)
                    continue
                if quadrature is None:
                    return math.nan, False
                x1 = 0.0 if v1 == va else xh + 0.5 * h * (v1 - 1.0 / v1)
                x2 = ell if v2 == vb else xh + 0.5 * h * (v2 - 1.0 / v2)
                part, converged = _quadrature(xh - x1, h, x2 - x1, kt, ks, intensity, phase_code, g, cone, precision,
                                              stats)
                out += part * math.exp(-kt * x1) - old
                met = met and converged
    return out, met and not taylor


@njit
def _lambert_airlight(xh, h, da, ell, kt, ks, intensity, phase_code, g, precision, aniso_mode, coeffs, cone, stats,
                      quadrature):
    """(Lm, met): `checked_airlight` of an emitter point of an area light (a LAMBERT row, lights/area.py: F =
    max(c, 0)), with `_spot_airlight`'s values and statistics, without a cone's general cuts: the cosine
    c = A sin(phi) - B cos(phi) (lights/spot.py) changes sign once at most, where the ray crosses the emitter's
    plane (`_lit_piece`), so a segment has one lit piece at most, on which F Phi is a trigonometric series of
    first order in F (`_band_piece`: A sin(phi) - B cos(phi) times Phi's cosine series) or, where that misses
    the precision, a Gauss-Legendre step or the quadrature (as `_spot_body`'s). Counted in `stats` only
    where Lm is not nan (`quadrature` None: the pass with the quadrature counts it), in one place."""
    val, met, flags, quads = _lambert_body(xh, h, da, ell, kt, ks, intensity, phase_code, g, precision, aniso_mode,
                                           coeffs, cone, stats, quadrature)
    if quadrature is not None or not math.isnan(val):
        stats[ST_PIECE_QUAD] += quads
    _tally(stats, quadrature, val, 0.0, flags)
    return val, met


@njit(inline="always")
def _lambert_body(xh, h, da, ell, kt, ks, intensity, phase_code, g, precision, aniso_mode, coeffs, cone, stats,
                  quadrature):
    """`_lambert_airlight`'s (Lm, met, flags, pieces by quadrature): the paths taken (F_*, `_count`) and the
    pieces that a Gauss-Legendre step or the quadrature took, for its caller to count."""
    kind, dmin = _front(xh, h, da, ell, kt, ks, intensity, phase_code, g)
    if kind == FRONT_ZERO:
        return 0.0, True, F_ZERO, 0.0
    if kind == FRONT_VACUUM:
        val, ok = _fallback(xh, h, ell, kt, ks, intensity, phase_code, g, cone, precision, stats, quadrature)
        return val, ok, 0, 0.0
    taylor = phase_code != ISOTROPIC and aniso_mode == ANISO_TAYLOR
    if kind == FRONT_NEAR:
        val, ok = _nearline(xh, h, da, ell, kt, ks, intensity, phase_code, g, dmin, precision)
        f, ok_f = _spot_nearline(xh, h, dmin, cone, precision)
        ok = ok and ok_f
        if ok or taylor:  # (as `_point_airlight`'s)
            return val * f, ok and not taylor, F_NEARLINE, 0.0
    H, va, vb, pref, pa, pb = _ends_of(xh, h, da, ell, kt, intensity)
    v1, v2 = _lit_piece(cone[0], cone[1], va, vb)
    if not v2 > v1:  # dark
        return 0.0, not taylor, 0, 0.0
    if _block_at(coeffs, v1, v2, H, B_HMAX_BAND)[1] - B_C > BAND_GAUSS_FIRST:  # (as `_spot_body`'s bands)
        fine, coarse = _gauss_piece(xh, h, kt, phase_code, g, cone, v1, v2)
        if abs(fine - coarse) <= SERIES_SAFETY * precision * fine:
            return pref * (ks * fine), not taylor, 0, 1.0
    p1 = pa if v1 == va else xh + h * v1
    p2 = pb if v2 == vb else xh + h * v2
    work = np.empty(2 * (coeffs.shape[0] + BAND_ORDER + 1) + 8)
    lambert_trig(cone[0], cone[1], cone[2], cone[3], work[:BAND_ORDER + 1], work[BAND_ORDER + 1:2 * BAND_ORDER + 2])
    val, err, ok, flags = _band_piece(H, kt, v1, v2, p1, p2, coeffs, precision, work)
    if not ok:
        val, err = 0.0, math.inf  # no closed form for the piece: quadrature below
    out = pref * (ks * val)
    if not err > SERIES_SAFETY * precision * val:
        return out, not taylor, flags, 0.0
    # a narrow piece whose polynomial's terms cancel: one 10/20-point Gauss-Legendre step, else the
    # quadrature over the piece's own stretch [x1, x2] of the segment (x = x_h + h (v - 1/v) / 2)
    fine, coarse = _gauss_piece(xh, h, kt, phase_code, g, cone, v1, v2)
    if abs(fine - coarse) <= SERIES_SAFETY * precision * fine:
        return out + (pref * (ks * fine) - out), not taylor, flags, 1.0
    if quadrature is None:
        return math.nan, False, flags, 1.0
    x1 = 0.0 if v1 == va else xh + 0.5 * h * (v1 - 1.0 / v1)
    x2 = ell if v2 == vb else xh + 0.5 * h * (v2 - 1.0 / v2)
    part, converged = _quadrature(xh - x1, h, x2 - x1, kt, ks, intensity, phase_code, g, cone, precision, stats)
    return out + (part * math.exp(-kt * x1) - out), converged and not taylor, flags, 1.0


@njit
def _lit_piece(A, B, va, vb):
    """(v1, v2): the piece of va < v < vb (v = tan(phi / 2)) where c = A sin(phi) - B cos(phi) > 0, empty where
    v2 <= v1: `lights.segment_cone`'s pieces for a cone of 90 degrees (c = 0 at the roots of B v^2 + 2 A v - B,
    whose product is -1: one in (0, inf) at most; a root within CUT_TOL of an end is that end), each piece
    told lit or dark by c at a point inside it."""
    k, r, _ = cone_breaks(A, B, 0.0)
    lo, hi = va, vb
    if k > 0 and va * (1.0 + CUT_TOL) < r < vb * (1.0 - CUT_TOL):
        if cosine_at(A, B, va + 0.3 * (r - va)) > 0.0:
            return va, r
        lo = r
    inside = (1.0 + lo) * 3.2 if hi == math.inf else lo + 0.3 * (hi - lo)
    return (lo, hi) if cosine_at(A, B, inside) > 0.0 else (lo, lo)


@njit
def _block_at(coeffs, v1, v2, H, at):
    """(start, length, value): where in `coeffs` the exact mode's coefficient block for a piece
    v1 < v < v2 at H = kt h starts, its length, and at H the sum's sensitivity to the start values
    (at = B_HMAX, `_sensitivity`) or the band's forward recurrence's error amplification (at = B_HMAX_BAND),
    or inf where H is beyond the block's limit (the recurrence would lose digits: quadrature).
    The block is the shortest whose range of v holds the piece and whose recurrence limit (block[at],
    at = B_HMAX or B_HMAX_BAND, `_block`) admits H, else the full one (`exact_coeffs`: each block is
    preceded by its length, the full one first, the fitted ones after it from the widest range to the
    narrowest, each range inside the one before, so the scan stops at the first range that does not
    hold the piece; the blocks' starts are read from the directory at the end of `coeffs`, so that no
    block's address waits for the load of the length before it). The value is read from the block's
    table (nodes quadratic in H: the loss grows like exp(2 sqrt(H k))): B_SENS holds the sensitivity's
    bound on each interval between two nodes, B_LOSS_BAND the loss at the nodes, interpolated (at least
    1). Offsets, not slices: a slice costs numba a reference count, as does every array handed to a call
    (so the scan and the table are one call)."""
    last = coeffs.shape[0] - 1
    top = last - int(coeffs[last])  # the directory of the blocks' starts (`exact_coeffs`)
    start = 1
    for r in range(top + 1, last):  # the fitted blocks: their starts read at once, not block by block
        b = int(coeffs[r])
        if not (coeffs[b + B_VLO] <= v1 and v2 <= coeffs[b + B_VHI]):
            break
        if H <= coeffs[b + at]:
            start = b
    n = int(coeffs[start - 1])
    hmax = coeffs[start + at]
    if H > hmax:
        return start, n, math.inf
    x = (LOSS_TABLE - 1) * math.sqrt(H / hmax) if hmax > 0.0 else 0.0
    i = min(int(x), LOSS_TABLE - 2)
    if at == B_HMAX:
        return start, n, coeffs[start + B_SENS + i]  # (its bound on the interval)
    table = start + B_LOSS_BAND
    f = x - i
    return start, n, max(1.0, (1.0 - f) * coeffs[table + i] + f * coeffs[table + 1 + i])


@njit
def _gauss_piece(xh, h, kt, phase_code, g, cone, v1, v2):
    """(20-point, 10-point) Gauss-Legendre values of S = int w Phi F dphi / 2 (folded as `_piece`)
    over v1 < v < v2, in quadrature.py's variables: phi before the foot point (v < 1), psi = pi - phi
    after it, where the integrand is smooth in each."""
    fine = coarse = 0.0
    for piece in range(2):  # a variable, not the constants 0 and 1: quad_rule compiles once, not per constant
        if piece == 0:
            if not v1 < 1.0:
                continue
            a, b = 2.0 * math.atan(v1), 2.0 * math.atan(min(v2, 1.0))
        else:
            if not v2 > 1.0:
                continue
            a = 0.0 if v2 == math.inf else 2.0 * math.atan(1.0 / v2)
            b = 2.0 * math.atan(1.0 / max(v1, 1.0))
        fine += quad_rule(piece, a, b, xh, h, kt, phase_code, g, cone, N20, W20)
        coarse += quad_rule(piece, a, b, xh, h, kt, phase_code, g, cone, N10, W10)
    return 0.5 * fine, 0.5 * coarse


# ----------------------------------------------------------------------------------------------
# Python helpers: coefficient tables and stats summary
# ----------------------------------------------------------------------------------------------
def taylor_coeffs(phase_code, g, n_terms):
    """Maclaurin coefficients c_0..c_{N-1} of Phi_c((1-v^2)/(1+v^2)) in v (METHODS §6.2)."""
    from math import pi

    c = np.zeros(n_terms)
    if phase_code == ISOTROPIC:
        c[0] = INV_4PI
        return c
    if phase_code == RAYLEIGH:
        for n in range(0, n_terms, 2):
            k = n // 2
            c[n] = 3.0 / (8.0 * pi) * (1.0 if k == 0 else (-1.0) ** k * 2 * k)
        return c
    # HG: (1+g)/(4 pi (1-g)^2) (1+v^2)^{3/2} (1+s v^2)^{-3/2}, s = ((1+g)/(1-g))^2
    s = ((1.0 + g) / (1.0 - g)) ** 2
    pre = INV_4PI * (1.0 + g) / (1.0 - g) ** 2

    def gbin(alpha, k):  # generalised binomial coefficient
        r = 1.0
        for i in range(k):
            r *= (alpha - i) / (i + 1)
        return r

    for n in range(0, n_terms, 2):
        m = n // 2
        c[n] = pre * sum(gbin(1.5, k) * gbin(-1.5, m - k) * s ** (m - k) for k in range(m + 1))
    return c


MAX_LEGENDRE = 4096  # longest HG Legendre series tried (a power of 2: `hg_legendre_degree` doubles)
MAX_FAR_DEGREE = 400  # highest degree of a fitted block's series


def hg_legendre_degree(g, precision):
    """Smallest Legendre length L <= MAX_LEGENDRE whose truncated HG phase function is within
    precision / 2 of the true one, relatively, at every scattering angle, or None if there is none
    (the terms fall like |g|^l: g = 0.995 at precision 1e-3 needs more). Checked for |g| (g and -g
    need the same L, mu -> -mu) on a grid dense near the peak; the relative error of the air-light
    is bounded by the largest pointwise one, as both the phase function and the rest of the
    integrand are positive. Doubling, then bisection."""
    g = abs(g)
    if g == 0.0:
        return 0
    phi = np.concatenate([np.linspace(0.0, 0.2, 801), np.linspace(0.2, math.pi, 2001)])
    mu = np.cos(phi)
    exact = hg(g, 1.0 - mu, 1.0 + mu)

    def good(L):
        err = np.max(np.abs(np.polynomial.legendre.legval(mu, hg_legendre(g, L)) - exact) / exact)
        return err <= 0.5 * precision

    hi = 1
    while not good(hi):
        if hi >= MAX_LEGENDRE:
            return None
        hi *= 2
    lo = hi // 2
    while hi - lo > 1:  # the truncation error falls (essentially monotonically) with L
        mid = (lo + hi) // 2
        if good(mid):
            hi = mid
        else:
            lo = mid
    return hi


# radians from the peak: HG is also fitted on each range of scattering angles at least this far from its
# peak, a ladder of ever shorter series (g = 0.9 at 1e-6: 224 Legendre terms for the whole sphere, 186
# beyond 0.05 rad, 65 beyond 0.3, 33 beyond 0.6, 19 beyond 1.0); a ray uses the shortest whose range holds
# all its angles
FAR_ANGLES = (0.05, 0.075, 0.1, 0.125, 0.15, 0.2, 0.25, 0.3, 0.375, 0.45, 0.6, 0.8, 1.0, 1.3)
FAR_GAIN = 0.85  # a rung is kept if its series has at most this fraction of the terms of the last one kept


def _usable(precision, ratio):
    """Whether a block with this `ratio` (`_block`) can serve any ray: the forward recurrence's
    rounding, FORWARD_ERR_PER_LOSS times its loss (1 at H = 0), within precision * ratio."""
    return FORWARD_ERR_PER_LOSS <= precision * ratio


def _block(c, phase, v_lo, v_hi, precision):
    """One coefficient block of the exact mode, valid for rays with v_lo <= v_a, v_b <= v_hi (layout:
    the B_* offsets). `c` are cosine coefficients (the phase function is sum_k c_k cos(k phi) on the
    block's range of angles), `phase` the true phase function's values on that range. H_max is the
    largest H = kt h for which the forward moment recurrence keeps a relative accuracy of
    precision / 10 (larger H: quadrature; the bisection keeps lo within that accuracy, so H_max only
    errs low, 0 if not `_usable`); ratio = min(Phi) / (10 sum |c_k|) is the loss of the final sum
    where it cancels; the tables are indexed by H = H_max (i / (LOSS_TABLE - 1))^2 (`_block_at`). The
    point's table holds `_sensitivity`. The band's H_max and table (the recurrence's error amplification)
    are those of the series times a spot's smoothstep (order + 3: coefficient k of the product draws on
    c_{k-3} .. c_{k+3})."""
    ratio = 0.1 * float(np.min(phase)) / float(np.sum(np.abs(c)))
    tol = precision * ratio

    def limit(cc):
        lo, hi = 0.0, 1e4
        if FORWARD_ERR_PER_LOSS * forward_loss(hi, cc) <= tol:
            lo = hi
        for _ in range(60):  # bisection: the loss grows monotonically with H
            mid = 0.5 * (lo + hi)
            if FORWARD_ERR_PER_LOSS * forward_loss(mid, cc) <= tol:
                lo = mid
            else:
                hi = mid
        return [lo] + [forward_loss(lo * (i / (LOSS_TABLE - 1)) ** 2, cc) for i in range(LOSS_TABLE)]

    pad = np.pad(np.abs(c), (BAND_ORDER, 2 * BAND_ORDER))
    spread = np.max([pad[j:j + len(c) + BAND_ORDER] for j in range(2 * BAND_ORDER + 1)], axis=0)
    hmax, band = limit(c)[0], limit(spread)
    return np.concatenate(([v_lo, v_hi, hmax, ratio], _sensitivity(c, hmax), band, c))


SENS_SAMPLES = 8  # samples of the sensitivity in each interval of its table
# the sampled maximum of a smooth peak between samples errs low: by up to 1e-4 relative (measured, HG 0.5 at 1e-9)
SENS_MARGIN = 1.01


def _sensitivity(c, hmax):
    """The sensitivity table of a block: for the interval i between the nodes H = hmax (i / (LOSS_TABLE -
    1))^2 and H = hmax ((i + 1) / (LOSS_TABLE - 1))^2 the largest `start_sensitivity` / (2 sum |c_k|) on it
    (SENS_SAMPLES + 1 samples, times SENS_MARGIN); the last entry repeats the last interval's. S / 2 =
    sum_k c_k Re E_k / 2 then moves by at most sens sum |c_k| prec K1 where K1 and L1 err by at most
    prec K1 (`_piece`)."""
    m = (LOSS_TABLE - 1) * SENS_SAMPLES
    sens = SENS_MARGIN * start_sensitivity(hmax * (np.arange(m + 1) / m) ** 2, c) / (2.0 * np.sum(np.abs(c)))
    table = [np.max(sens[i * SENS_SAMPLES:(i + 1) * SENS_SAMPLES + 1]) for i in range(LOSS_TABLE - 1)]
    return np.array(table + table[-1:])


def _far_cosine_series(g, precision, phi_lo, phi_hi):
    """Cosine coefficients of a polynomial in mu = cos(phi) within precision / 20 (relatively) of the
    HG phase function on [phi_lo, phi_hi] (tighter than the full series' precision / 2: an interpolant's
    error is spread evenly over the range, so the air-light inherits nearly all of it; at precision / 2
    a fuzzed HG 0.25 room came out 3.2e-7 off at precision 1e-6, beyond analytic's declared law): Chebyshev interpolation on that range of mu, rewritten in
    T_k(mu) = cos(k phi) over [-1, 1]; None if no degree below MAX_FAR_DEGREE gets there, or if the
    block could not be `_usable` (its ratio is at most 0.1 min Phi / max Phi on the range, as
    sum |c_k| >= max |sum c_k cos(k phi)|). Also returns the phase function on the range."""
    from numpy.polynomial import chebyshev

    def phase(mu):
        return hg(g, 1.0 - mu, 1.0 + mu)

    mu = np.cos(np.linspace(phi_lo, phi_hi, 4001))
    exact = phase(mu)
    if not _usable(precision, 0.1 * np.min(exact) / np.max(exact)):
        return None, exact

    def fit(degree):
        p = chebyshev.Chebyshev.interpolate(phase, degree, domain=[math.cos(phi_hi), math.cos(phi_lo)])
        return p if np.max(np.abs(p(mu) - exact) / exact) <= 0.05 * precision else None

    # the least degree that fits, by doubling and bisection (the interpolant's error falls with the
    # degree); the degree returned is always one checked to fit
    lo, hi = 1, 2
    best = fit(hi)
    while best is None:
        if hi >= MAX_FAR_DEGREE - 1:
            return None, exact
        lo, hi = hi, min(2 * hi, MAX_FAR_DEGREE - 1)
        best = fit(hi)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        p = fit(mid)
        if p is None:
            lo = mid
        else:
            hi, best = mid, p
    return best.convert(domain=[-1.0, 1.0], kind=chebyshev.Chebyshev).coef, exact


def fitted_range(g, angle):
    """(phi_lo, phi_hi, v_lo, v_hi): the scattering angles at least `angle` from HG's peak (forward
    for g > 0, backward for g < 0) and their range of v = tan(phi / 2)."""
    if g > 0.0:
        return angle, math.pi, math.tan(0.5 * angle), math.inf
    return 0.0, math.pi - angle, 0.0, 1.0 / math.tan(0.5 * angle)


def exact_coeffs(phase_code, g, precision):
    """`coeffs` of the exact mode: blocks, each preceded by its length: the block valid for all rays,
    then for HG the fitted ones (`FAR_ANGLES`), from the widest range to the narrowest; then a
    directory: the start of each block (the index of its first entry) and, last, the number of blocks.

    The phase function is a cosine series (exact for Rayleigh; HG truncated after L Legendre terms,
    L from `precision`). HG's series is long where it is peaked (its terms fall like |g|^l), so
    shorter series fitted only away from the peak (scattering angles beyond each of FAR_ANGLES from
    it, `_far_cosine_series`) serve the rays whose whole segment sees the light from there, which are
    most rays; a rung is kept where it is FAR_GAIN shorter than the last one kept. See `_block` for
    the layout of a block. No series is cut short: where `precision` needs more than MAX_LEGENDRE
    terms, or the block could not be `_usable` anyway (HG: ratio = 0.1 ((1 - |g|) / (1 + |g|))^3,
    sum |c_k| being the peak value), the full block has H_max = 0 and sends its rays to the
    quadrature fallback (counted); a fitted block that could serve no ray is left out."""
    a = None
    if phase_code == RAYLEIGH:
        a = rayleigh_legendre()
    elif phase_code == HG:
        if _usable(precision, 0.1 * ((1.0 - abs(g)) / (1.0 + abs(g))) ** 3):
            L = hg_legendre_degree(g, precision)
            a = None if L is None else hg_legendre(g, L)
    else:
        a = np.array([INV_4PI])
    if a is None:  # H_max = 0: all its rays to the fallback
        full = np.concatenate(([0.0, math.inf, 0.0, 1.0], np.ones(LOSS_TABLE), [0.0], np.ones(LOSS_TABLE), [0.0]))
    else:
        full = _block(legendre_to_cosine(a), np.polynomial.legendre.legval(np.linspace(-1.0, 1.0, 2001), a), 0.0,
                      math.inf, precision)
    blocks = [full]
    terms = len(full) - B_C if full[B_HMAX] > 0.0 else math.inf
    if phase_code == HG and g != 0.0:
        for angle in FAR_ANGLES:
            phi_lo, phi_hi, v_lo, v_hi = fitted_range(g, angle)
            c, phase = _far_cosine_series(g, precision, phi_lo, phi_hi)
            if c is None or len(c) > FAR_GAIN * terms:
                continue
            far = _block(c, phase, v_lo, v_hi, precision)
            if far[B_HMAX] > 0.0:
                blocks.append(far)
                terms = len(c)
    starts = np.cumsum([1] + [1 + len(b) for b in blocks[:-1]])
    return np.concatenate([np.concatenate(([len(b)], b)) for b in blocks] + [starts, [len(blocks)]])


def coefficient_blocks(coeffs):
    """The blocks of an exact mode's `coeffs` (`exact_coeffs`), full one first."""
    nb = int(coeffs[-1])
    return [coeffs[b:b + int(coeffs[b - 1])] for b in coeffs[-1 - nb:-1].astype(int)]


@functools.lru_cache(maxsize=64)
def make_coeffs(phase_code, g, aniso_mode, terms, precision):
    """The `coeffs` argument of `airlight` for these settings (computed once per setting: the
    renderer asks for every tile)."""
    if aniso_mode == ANISO_TAYLOR:
        return taylor_coeffs(phase_code, g, max(int(terms), 1))
    return exact_coeffs(phase_code, g, precision)


def new_stats():
    return np.zeros(STATS_SIZE)


def summarize_stats(stats):
    """Dict summary of a stats array (possibly the sum of per-thread arrays)."""
    st = np.asarray(stats, dtype=float)
    n = st[ST_EVALS]
    nz = max(n, 1.0)
    return {
        "evaluations": int(n),
        "mean_iterations_per_evaluation": st[ST_SERIES_ITERS] / nz,  # PP09 Table 1, last row
        "mean_iterations_per_series_evaluation": st[ST_SERIES_ITERS] / max(st[ST_SERIES], 1.0),
        "series_fraction": st[ST_SERIES] / nz,
        "stable_fraction": st[ST_STABLE] / nz,
        "near_line_fraction": st[ST_NEARLINE] / nz,
        "fallback_fraction": st[ST_FALLBACK] / nz,
        "zero_fraction": st[ST_ZERO] / nz,
        "series_rejected_fraction": st[ST_SERIES_REJECTED] / nz,
        "taylor_out_of_range_fraction": st[ST_TAYLOR_OUT] / nz,
        "fallback_integrand_evaluations": int(st[ST_FALLBACK_FEVALS]),
        "fallback_not_converged": int(st[ST_FALLBACK_CAPPED]),
        "spot_band_pieces": int(st[ST_BANDS]),
        "spot_pieces_by_quadrature": int(st[ST_PIECE_QUAD]),
    }


# ----------------------------------------------------------------------------------------------
# the registered method
# ----------------------------------------------------------------------------------------------
@njit
def evaluate_segments(xh, h, da, ell, kt, ks, code, g, precision, max_iter, aniso_mode, terms, coeffs, cone, out,
                      met, stats, quadrature, spots, aniso, lamberts=True, points=True, taylor_mode=True, pending=None,
                      recurrences=True):
    """Unit-intensity air-light of every segment for one channel's coefficients, and whether each
    met the precision (`checked_airlight`'s choice, made here: a point light's path inlined, numba's
    inlining one level deep only, as each level types its callee's code again). With `quadrature` None
    (and `spots`, `aniso`, `lamberts` or `points`) the segments that need the reference quadrature (a spot's
    code, an anisotropic phase function's, an emitter point's, a point light's) are left nan, their statistics
    not counted (`evaluate_deferred`); returns how many. `taylor_mode` None: the Taylor mode's code is not
    compiled (`_piece`; `aniso_mode` is then the exact one). The exact mode's
    moment recurrences of point lights are run after the loop, batched (`_pending_recurrences`), in
    either pass, so that deferring changes no bit; their rows go to `pending` where it is given (an (S, PENDING)
    array), and with `recurrences` None they are left to the caller (`evaluate_deferred`: then not compiled
    into this kernel, the branch pruned by numba as the None arguments' are)."""
    batch = np.empty((xh.shape[0] if aniso is not None else 0, PENDING)) if pending is None else pending
    defer = aniso is not None
    left = 0
    for s in range(xh.shape[0]):
        row = (cone[s, 0], cone[s, 1], cone[s, 2], cone[s, 3], cone[s, 4])  # a tuple: a view costs a reference count
        p = NOTHING_PENDING
        if has_cone(row[3]):
            if row[4] == LAMBERT:
                if lamberts is None:
                    out[s], met[s] = math.nan, False
                else:
                    out[s], met[s] = _lambert_airlight(xh[s], h[s], da[s], ell[s], kt, ks, 1.0, code, g, precision,
                                                       aniso_mode, coeffs, row, stats, quadrature)
            elif spots is None:
                out[s], met[s] = math.nan, False
            else:
                out[s], met[s] = _spot_airlight(xh[s], h[s], da[s], ell[s], kt, ks, 1.0, code, g, precision, max_iter,
                                                aniso_mode, terms, coeffs, row, stats, quadrature, aniso)
        elif points is None:
            out[s], met[s] = math.nan, False
        else:
            out[s], met[s], p, iterations, flags = _point_airlight(xh[s], h[s], da[s], ell[s], kt, ks, 1.0, code, g,
                                                                   precision, max_iter, aniso_mode, terms, coeffs, row,
                                                                   stats, quadrature, aniso, defer, taylor_mode)
            if p[P_PREC] == 0.0:  # (a segment whose Fig. 2 loop is pending is counted with it: `_pending_series`)
                _tally(stats, quadrature, out[s], iterations, flags)
        if quadrature is None and math.isnan(out[s]):
            left += 1  # left to the second pass (its statistics counted there)
        if aniso is not None:
            for k in range(PENDING):
                batch[s, k] = p[k]
    if aniso is not None and points is not None and aniso_mode == ANISO_EXACT:  # (Taylor mode's coeffs: no blocks)
        left += _pending_series(batch, xh, h, ell, kt, ks, code, g, precision, max_iter, cone, out, met, stats,
                                quadrature)
        if recurrences is not None:
            _pending_recurrences(batch, coeffs, ks, out)
    return left


@njit
def _pending_series(pending, xh, h, ell, kt, ks, code, g, precision, max_iter, cone, out, met, stats, quadrature):
    """The Fig. 2 loops that `_piece` left pending (P_PREC > 0), side by side (`i01_series_lanes`), each segment
    then taken on as `_piece` goes on from its loop: the loop's result accepted (K1, L1 into the segment's row
    of the recurrences' batch) or rejected by its guard (the scaled-E1 ends, and where their terms cancel the
    fallback: out and met, the row's P_BLOCK then 0), and counted (`_tally`). Returns how many are left nan
    (`quadrature` None). The exponentials e^{-kt xh} (the fold of K1 and L1) and those of the rows' E1 and E2
    (`_piece` left their exponents) are taken VECTOR_BLOCK segments a call (`vector_exp`)."""
    rows = np.flatnonzero(pending[:, P_PREC] > 0.0)
    res = np.empty((rows.shape[0], 4))
    i01_series_lanes(pending, rows, P_PREC, max_iter, res)
    ex = np.zeros((3, -(-rows.shape[0] // VECTOR_BLOCK) * VECTOR_BLOCK))  # rows of whole vectors
    for i in range(rows.shape[0]):
        s = rows[i]
        ex[0, i], ex[1, i], ex[2, i] = -kt * xh[s], pending[s, P_E1], pending[s, P_E2]
    for i in range(0, rows.shape[0], VECTOR_BLOCK):
        vector_exp(ex[0], i)
        vector_exp(ex[1], i)
        vector_exp(ex[2], i)
    left = 0
    for i in range(rows.shape[0]):
        s = rows[i]
        H, v1, v2, prec_i = pending[s, P_H], pending[s, P_V1], pending[s, P_V2], pending[s, P_PREC]
        E1, E2 = ex[1, i], ex[2, i]
        pending[s, P_E1], pending[s, P_E2] = E1, E2
        i0, i1, iterations, err = res[i, 0], res[i, 1], res[i, 2], res[i, 3]
        # `_piece`'s a-posteriori guard: estimated rounding error vs the precision; a loop that used all
        # max_iter iterations may not have converged
        if iterations >= max_iter or not (err <= SERIES_SAFETY * prec_i * i0):
            K1, L1, _, ok = _e1_ends(H, v1, v2, E1, E2, prec_i)
            flags = F_REJECTED | F_STABLE if ok else F_REJECTED
        else:
            f = ex[0, i]
            K1, L1, ok, flags = f * i0, f * i1, True, F_SERIES
        if ok:
            pending[s, P_K1], pending[s, P_L1] = K1, L1
        else:
            row = (cone[s, 0], cone[s, 1], cone[s, 2], cone[s, 3], cone[s, 4])
            out[s], met[s] = _fallback(xh[s], h[s], ell[s], kt, ks, 1.0, code, g, row, precision, stats, quadrature)
            pending[s, P_BLOCK] = 0.0
            if quadrature is None and math.isnan(out[s]):
                left += 1
        _tally(stats, quadrature, out[s], iterations, flags)
    return left



@njit
def _pending_recurrences(pending, coeffs, ks, out):
    """out[s] = 2 I / h ks S of the segments whose moment recurrence `checked_airlight` left pending
    (P_BLOCK > 0), S = cosine_moments_forward / 2 of the row's arguments, each block's segments in one
    `cosine_moments_lanes` call (a segment's result does not depend on its batch)."""
    if pending.shape[0] == 0 or pending[:, P_BLOCK].max() <= 0.0:
        return
    nb = int(coeffs[-1])
    starts = np.empty(nb, dtype=np.int64)  # the blocks' starts (the directory of `exact_coeffs`)
    rank_at = np.empty(coeffs.shape[0], dtype=np.int64)  # a block's rank by its start
    for r in range(nb):
        starts[r] = int(coeffs[coeffs.shape[0] - 1 - nb + r])
        rank_at[starts[r]] = r
    rank = np.empty(pending.shape[0], dtype=np.int64)
    first = np.zeros(nb + 1, dtype=np.int64)
    for s in range(pending.shape[0]):
        rank[s] = -1
        if pending[s, P_BLOCK] > 0.0:
            r = rank_at[int(pending[s, P_BLOCK])]
            rank[s] = r
            first[r + 1] += 1
    for r in range(nb):
        first[r + 1] += first[r]
    order = np.empty(first[nb], dtype=np.int64)  # the pending segments, block by block
    fill = first[:nb].copy()
    for s in range(pending.shape[0]):
        if rank[s] >= 0:
            order[fill[rank[s]]] = s
            fill[rank[s]] += 1
    acc = np.empty(order.shape[0])
    for r in range(nb):
        lo, hi = first[r], first[r + 1]
        if hi > lo:
            start = starts[r]
            cosine_moments_lanes(pending, order[lo:hi], coeffs[start + B_C:start + int(coeffs[start - 1])],
                                 acc[lo:hi])
    for i in range(order.shape[0]):
        s = order[i]
        out[s] = pending[s, P_PREF] * (ks * (0.5 * acc[i]))


def evaluate_deferred(xh, h, da, ell, kt, ks, code, g, precision, max_iter, aniso_mode, terms, coeffs, cone, out,
                      met, stats, spots=True, aniso=True, lamberts=True, points=True, recurrences=True):
    """`evaluate_segments` with the quadrature's kernels compiled on first need only: every segment
    without them, then again with them the few left nan (the quadrature fallback, or a nan of the
    closed form, which the second pass reproduces), so the result is that of one pass with them.
    `spots` False: the scene has no light with a cone but emitter points (`light_rows`), `aniso` False:
    its medium is isotropic, `lamberts` False: no emitter point, `points` False: no light without a cone;
    the first pass is then compiled without their code too (such segments, were there any, would be left
    to the second pass). Both passes compile the Taylor mode's code only in that mode. Each pass's moment
    recurrences run here, after it (`_pending_recurrences`, a kernel of its own: the render's process compiles it
    while the compile worker compiles the passes, `compile_recurrences`); `recurrences` False: not at all (the
    worker's air-light, whose values are not used)."""
    taylor_mode = True if aniso_mode == ANISO_TAYLOR else None
    pending = np.empty((len(xh) if aniso else 0, PENDING))
    left = evaluate_segments(xh, h, da, ell, kt, ks, code, g, precision, max_iter, aniso_mode, terms, coeffs, cone,
                             out, met, stats, None, True if spots else None, True if aniso else None,
                             True if lamberts else None, True if points else None, taylor_mode, pending, None)
    if recurrences and aniso and points and aniso_mode == ANISO_EXACT:
        _pending_recurrences(pending, coeffs, ks, out)
    if left:
        todo = np.flatnonzero(np.isnan(out))
        part, part_met = np.empty(len(todo)), np.empty(len(todo), dtype=np.bool_)
        pending = np.empty((len(todo), PENDING))
        evaluate_segments(xh[todo], h[todo], da[todo], ell[todo], kt, ks, code, g, precision, max_iter, aniso_mode,
                          terms, coeffs, cone[todo], part, part_met, stats, True, True, True, taylor_mode=taylor_mode,
                          pending=pending, recurrences=None)
        if recurrences and aniso_mode == ANISO_EXACT:
            _pending_recurrences(pending, coeffs, ks, part)
        out[todo], met[todo] = part, part_met


ANISO_MODES = {"exact": ANISO_EXACT, "taylor": ANISO_TAYLOR}


def light_rows(cone):
    """(spots, lamberts, points) of the rows' cones (`Lights.cone`: cos_end, cos_start, curve): whether any
    row is a spot light's (a cone, `has_cone`, with a curve other than LAMBERT), an emitter point (LAMBERT:
    an area light's, `_lambert_airlight`) or has no cone (`_point_airlight`): the kernels
    `evaluate_deferred` compiles."""
    banded = cone[:, 1] > -1.0  # (`has_cone`, without compiling it for Python)
    lambert = banded & (cone[:, 2] == LAMBERT)
    return bool(np.any(banded & ~lambert)), bool(np.any(lambert)), bool(np.any(~banded))


def working_precision(precision):
    """The precision the kernels work to. Below 1e-7 it is 1000 times finer than requested: a
    float32 image cannot hold relative differences below ~1.2e-7, and two renders accurate to
    only ~1e-9 then round differently in a few pixels in 10,000; working to ~1e-11 makes the
    float32 images of `analytic` and `quadrature` agree to the last bit almost everywhere."""
    return precision if precision >= 1e-7 else 1e-3 * precision


def mode_for(medium, params, lights):
    """The kernels' anisotropic mode: isotropic media always use the exact mode's coefficients (a
    spot's band needs its moment blocks); the paper's Taylor mode takes no rows with a cone (a spot
    light's, an area light's emitter points: `light_rows`), refused."""
    if medium.phase == ISOTROPIC:
        return ANISO_EXACT
    from ..errors import UserError

    spots, lamberts, _ = light_rows(lights.cone)
    if params["anisotropic"] == "taylor" and (spots or lamberts):
        raise UserError("--anisotropic taylor (render.anisotropic): the paper's Taylor series takes no spot or area "
                        "light (their light's cone); use --anisotropic exact")
    return ANISO_MODES[params["anisotropic"]]


def uses_recurrences(medium, lights, params) -> bool:
    """Whether the air-light runs the batched moment recurrences (`_pending_recurrences`): point lights (rows
    without a cone) in an anisotropic medium, in the exact mode."""
    return medium.phase != ISOTROPIC and light_rows(lights.cone)[2] and mode_for(medium, params, lights) == ANISO_EXACT


# `_pending_recurrences`' one signature: `evaluate_deferred`'s batch, `exact_coeffs`, ks, the pass's air-light
RECURRENCES = (types.float64[:, ::1], types.float64[::1], types.float64, types.float64[::1])


def compile_recurrences(medium, lights, params):
    """`Method.compile_here`: the air-light's kernels that the render's process compiles by signature while the
    compile worker compiles the rest on the air-light without them (`Method.worker_airlight`,
    rendering/compile_ahead.py): the moment recurrences, where `uses_recurrences`, in the one signature
    `evaluate_deferred` calls them with."""
    if uses_recurrences(medium, lights, params):
        _pending_recurrences.compile(RECURRENCES)


def _airlight(segs, medium, lights, params, recurrences=True):
    mode = mode_for(medium, params, lights)
    precision = working_precision(params["precision"])
    coeffs = make_coeffs(medium.phase, medium.g, mode, params["terms"], precision)
    stats = new_stats()
    aniso = medium.phase != ISOTROPIC
    spots, lamberts, points = light_rows(lights.cone)
    met = {}  # (kt, ks) -> whether each segment's evaluation met the precision

    def evaluate(xh, h, da, ell, kt, ks, cone):
        out = np.empty_like(xh)
        met[(kt, ks)] = np.empty(len(xh), dtype=np.bool_)
        evaluate_deferred(xh, h, da, ell, kt, ks, medium.phase, medium.g, precision, params["max_iter"], mode,
                          params["terms"], coeffs, cone, out, met[(kt, ks)], stats, spots, aniso, lamberts, points,
                          recurrences)
        return out

    radiance = by_channel(segs, medium, lights, evaluate)
    return radiance, stats, error_bounds.relative_bound(radiance, params["precision"], met, medium,
                                                        lights.cone[segs.light, 0])


METHOD = Method(
    name="analytic",
    summary="Pegoraro & Parker's closed form (eq. 13) with Ei series / scaled E1, to a requested precision",
    params={
        "precision": Param(1e-3, float, "requested relative accuracy of each air-light, e.g. 1e-6", 1e-12, 0.1),
        "max_iter": Param(1000, int, "maximum iterations of the paper's series loop (Fig. 2)", 1),
        "anisotropic": Param("exact", str, "exact (cosine-moment recurrence, beyond the paper) or taylor "
                             "(paper eqs. 14-19)", choices=tuple(ANISO_MODES)),
        "terms": Param(6, int, "Taylor coefficients of the phase function with --anisotropic taylor (paper: 3, 6)",
                       1, 40),
    },
    airlight=_airlight,
    compile_here=compile_recurrences,
    worker_airlight=functools.partial(_airlight, recurrences=False),
    error_law=ErrorLaw({"precision": 1e-6}, "max", 3e-7),  # measured worst 7.2e-8 (isotropic), tests/test_methods.py
    stats_size=STATS_SIZE,
    summarize=summarize_stats,
    supports=Supports(lights=("point", "spot") + AREA_LIGHTS, interiors=Interiors(
        QUAD, closed_forms=True, lights=("directional", ENVIRONMENT), refracted=("directional", ENVIRONMENT),
        limits="no closed form (eq. 7 of the analytic note on single scattering in homogeneous slabs)")),
    tolerance_key="precision",
)
