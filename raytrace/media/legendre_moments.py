"""Stable O(L) air-light integral for a phase function given by L+1 Legendre coefficients.

Problem (METHODS.md §3, §6.5): with H = kt*h > 0, 0 <= va < vb <= inf, v = tan(phi/2),
t = 1/(1+v^2), mu = cos(phi) = 2t-1,

    S = int_va^vb e^{-Hv} 2t Phi(mu) dv = int_phia^phib w(phi) Phi(cos phi) dphi,
    w(phi) = e^{-H tan(phi/2)},  Phi(mu) = sum_{l=0}^{L} a_l P_l(mu).

Formulation (derivation in the module report / docstrings below):

1. Basis change Legendre -> cosine (exact, perfectly conditioned, once per phase function):
   P_l(cos phi) = sum_{j=0}^{l} al_j al_{l-j} cos((l-2j) phi), al_j = binom(2j, j)/4^j > 0, so
   Phi(cos phi) = sum_{k=0}^{L} c_k cos(k phi) with all weights positive (`legendre_to_cosine`).
2. Complex Fourier moments E_k = int w e^{ik phi} dphi = int e^{-Hv} 2t z^k dv, with
   z = e^{i phi} = (1+iv)/(1-iv) = (2t-1) + 2ivt (no trig). Then S = sum_k c_k Re E_k.
3. Integration by parts of d/dphi[w (1+cos phi) e^{ik phi}], using (1+cos phi) w' = -H w:

       (k+1) E_{k+1} + 2(k + iH) E_k + (k-1) E_{k-1} = -2i B_k,   k >= 1,
       B_k = [w (1+cos phi) e^{ik phi}] = 2 eb tb zb^k - 2 ea ta za^k   (0 at vb = inf).

   Starting values from the known I0 = K1, I1 = L1 (one IBP step, METHODS §6.5):
       E_0 = 2 K1,  E_1 = 2[e v t] + 2H L1 - 2i (H K1 + [e t]).
4. Stability: the homogeneous solutions behave like (-1)^k exp(+-2 sqrt(2iHk)) for k >> H, i.e.
   |.| ~ exp(+-2 sqrt(Hk)) (dominant / minimal), and for k << H the per-step ratio is ~(2H/k)^2.
   The wanted solution is "neutral" (O(1/k), endpoint contributions). The forward recurrence
   (from E_0, E_1) is therefore used while the dominant growth, weighted by the decay of c_k,
   stays small (`forward_loss`; small H*L); the caller sends larger H to quadrature. (Olver's
   boundary-value algorithm with an asymptotic far-end value is stable there too, and was
   measured accurate to 1e-12, but at 10-40 us per call it is slower than adaptive quadrature,
   1-3 us, so it is not used.)

Scaling contract: S is linear and homogeneous in (K1, L1, ea, eb).  Pass ea = F e^{-H va},
eb = F e^{-H vb} (0 for vb = inf), K1 = F I0(-H, va, vb), L1 = F I1(-H, va, vb) for any common
factor F (e.g. F = e^{H va}, or the renderer's folded e^{-kt xh}) and the result is F*S.
"""
import math

import numpy as np
from ..jit import exact_njit, njit
from .expint import fma
from .phase import INV_4PI


# ----------------------------------------------------------------------------------------------
# coefficient helpers (Python, once per phase function)
# ----------------------------------------------------------------------------------------------
def legendre_to_cosine(a):
    """Cosine coefficients c_k (k = 0..L) with sum_l a_l P_l(cos phi) = sum_k c_k cos(k phi): the
    terms j and l - j of P_l (step 1 above) share cos((l - 2j) phi), so each l is one vector update
    over j <= l/2 (O(L^2) work, but L numpy operations: 0.1 s for L = 4096)."""
    a = np.asarray(a, dtype=float)
    L = a.shape[0] - 1
    al = np.ones(L + 1)
    j = np.arange(1, L + 1)
    al[1:] = np.cumprod((2 * j - 1) / (2 * j))
    c = np.zeros(L + 1)
    for l in np.flatnonzero(a):
        j = np.arange(l // 2 + 1)
        w = a[l] * al[j] * al[l - j]
        w[:(l + 1) // 2] *= 2.0  # j < l - j: both terms; j = l / 2 (even l): one
        c[l - 2 * j] += w
    return c


def hg_legendre(g, L):
    """a_l = (2l+1) g^l / (4 pi), l = 0..L (Henyey-Greenstein, normalised over the sphere)."""
    l = np.arange(L + 1)
    return (2 * l + 1) * float(g) ** l * INV_4PI


def rayleigh_legendre():
    """Rayleigh 3/(16 pi)(1+mu^2) = 1/(4 pi) P_0 + 1/(8 pi) P_2 (mu^2 = (1 + 2 P_2)/3)."""
    return np.array([INV_4PI, 0.0, 1.0 / (8.0 * math.pi)])


# ----------------------------------------------------------------------------------------------
# kernels
# ----------------------------------------------------------------------------------------------
@njit
def _ends(va, vb):
    """t and z = e^{i phi} at both ends (vb = inf -> tb = 0, zb = -1)."""
    ta = 1.0 / (1.0 + va * va)
    za = complex(2.0 * ta - 1.0, 2.0 * va * ta)
    if vb < math.inf:
        tb = 1.0 / (1.0 + vb * vb)
        zb = complex(2.0 * tb - 1.0, 2.0 * vb * tb)
    else:
        tb = 0.0
        zb = complex(-1.0, 0.0)
    return ta, za, tb, zb


@njit
def trig_moments_forward(H, va, vb, K1, L1, ea, eb, c, s):
    """sum_k c_k Re E_k + s_k Im E_k (= int w(phi) [sum_k c_k cos(k phi) + s_k sin(k phi)] dphi) by
    the forward recurrence (stable only for small H*L); `s` may be empty."""
    nc, ns = c.shape[0], s.shape[0]
    n = max(nc, ns)
    ta, za, tb, zb = _ends(va, vb)
    fin = vb < math.inf
    ebt = eb * tb if fin else 0.0
    eat = ea * ta
    E0 = complex(2.0 * K1, 0.0)
    acc = c[0] * E0.real if nc > 0 else 0.0
    if n <= 1:
        return acc
    evt = (ebt * vb if fin else 0.0) - eat * va
    et = ebt - eat
    E1 = complex(2.0 * evt + 2.0 * H * L1, -2.0 * (H * K1 + et))
    if nc > 1:
        acc += c[1] * E1.real
    if ns > 1:
        acc += s[1] * E1.imag
    # real arithmetic: q = ebt zb^k - eat za^k (the boundary term), E_k = (er, ei), E_{k-1} = (mr, mi)
    ar, ai = eat * za.real, eat * za.imag
    br, bi = ebt * zb.real, ebt * zb.imag
    zar, zai, zbr, zbi = za.real, za.imag, zb.real, zb.imag
    mr, mi = E0.real, E0.imag
    er, ei = E1.real, E1.imag
    h2 = 2.0 * H
    for k in range(1, n - 1):
        # (k+1) E_{k+1} = -4i q - 2 (k + iH) E_k - (k-1) E_{k-1}, grouped so that E_k enters last
        # (two fused multiply-adds from E_k to E_{k+1}; the rest is off that dependency chain)
        inv = 1.0 / (k + 1.0)
        tr = (4.0 * (bi - ai) - (k - 1.0) * mr) * inv
        ti = (4.0 * (ar - br) - (k - 1.0) * mi) * inv
        a = -2.0 * k * inv
        b = h2 * inv
        nr = a * er + (b * ei + tr)
        ni = a * ei + (ti - b * er)
        mr, mi, er, ei = er, ei, nr, ni
        if k + 1 < nc:
            acc += c[k + 1] * nr
        if k + 1 < ns:
            acc += s[k + 1] * ni
        ar, ai = ar * zar - ai * zai, ar * zai + ai * zar
        br, bi = br * zbr - bi * zbi, br * zbi + bi * zbr
    return acc


@njit
def cosine_moments_forward(H, va, vb, K1, L1, ea, eb, c):
    """S = sum_k c_k Re E_k by the forward recurrence (stable only for small H*L)."""
    return trig_moments_forward(H, va, vb, K1, L1, ea, eb, c, c[:0])  # no sines; c's type: one compilation


LANES = 64  # segments whose recurrences `cosine_moments_lanes` advances side by side


@exact_njit
def cosine_moments_lanes(args, rows, c, out):
    """out[i] = `cosine_moments_forward` of the arguments args[rows[i], 0:7] (H, va, vb, K1, L1, ea,
    eb), all with the same coefficients c: the recurrences of LANES segments are advanced together,
    two steps k at a time, so that the loop over the segments inside a pass, free of dependencies, runs
    in SIMD registers (HG 0.9's 51 terms: several times faster per segment than one call per
    segment). The recurrence runs on D_k = k E_k (`_step`). No operation mixes two segments, and
    the function is compiled without fastmath (no reassociation, no fused multiply-adds but the explicit
    ones, `expint.fma`: every operation rounds as IEEE arithmetic says, in SIMD registers or not), so a segment's
    result does not depend on the batch it came in or on its place in it."""
    n = c.shape[0]
    state = np.empty((14, LANES))
    acc, mr, mi, er, ei = state[0], state[1], state[2], state[3], state[4]
    ar, ai, br, bi = state[5], state[6], state[7], state[8]
    zar, zai, zbr, zbi, h2 = state[9], state[10], state[11], state[12], state[13]
    for first in range(0, rows.shape[0], LANES):
        w = min(LANES, rows.shape[0] - first)
        for j in range(w):
            r = rows[first + j]
            # the row's entries read one by one: a slice of it would be a view, whose reference numba counts
            H, va, vb, K1, L1 = args[r, 0], args[r, 1], args[r, 2], args[r, 3], args[r, 4]
            ea, eb = args[r, 5], args[r, 6]
            # t and z = e^{i phi} at both ends (`_ends`, here without fastmath too)
            ta = 1.0 / (1.0 + va * va)
            zar[j], zai[j] = 2.0 * ta - 1.0, 2.0 * va * ta
            fin = vb < math.inf
            tb = 1.0 / (1.0 + vb * vb) if fin else 0.0
            zbr[j], zbi[j] = (2.0 * tb - 1.0, 2.0 * vb * tb) if fin else (-1.0, 0.0)
            ebt = eb * tb if fin else 0.0
            eat = ea * ta
            acc[j] = c[0] * (2.0 * K1) if n > 0 else 0.0  # c_0 E_0
            mr[j], mi[j] = 0.0, 0.0  # D_0 = 0 (0 times E_0)
            # D_1 = E_1 (module docstring, step 3)
            er[j] = 2.0 * ((ebt * vb if fin else 0.0) - eat * va) + 2.0 * H * L1
            ei[j] = -2.0 * (H * K1 + (ebt - eat))
            if n > 1:
                acc[j] += c[1] * er[j]
            # the boundary term times 4 (exact: a power of 2), as the recurrence takes it
            ar[j], ai[j], br[j], bi[j] = 4.0 * eat * zar[j], 4.0 * eat * zai[j], 4.0 * ebt * zbr[j], 4.0 * ebt * zbi[j]
            h2[j] = 2.0 * H
        k = 1
        while k + 1 < n - 1:  # two steps a pass over the lanes: each lane's state loaded and stored once
            _lanes_steps(w, k, 2, c, acc, mr, mi, er, ei, ar, ai, br, bi, zar, zai, zbr, zbi, h2)
            k += 2
        if k < n - 1:
            _lanes_steps(w, k, 1, c, acc, mr, mi, er, ei, ar, ai, br, bi, zar, zai, zbr, zbi, h2)
        for j in range(w):
            out[first + j] = acc[j]


@exact_njit(inline="always")
def _lanes_steps(w, k, steps, c, acc, mr, mi, er, ei, ar, ai, br, bi, zar, zai, zbr, zbi, h2):
    """`steps` (1 or 2) steps k -> k + 1 (-> k + 2) of `trig_moments_forward`'s recurrence for lanes 0 .. w - 1
    on D_k = k E_k, c_{k+1} Re E_{k+1} added (`_step`). The loop over the lanes runs in SIMD registers, and
    two steps in one pass load and store each lane's state once where one step a pass did so twice."""
    i1, c1 = 1.0 / k, c[k + 1] / (k + 1.0)
    i2, c2 = (1.0 / (k + 1.0), c[k + 2] / (k + 2.0)) if steps == 2 else (0.0, 0.0)
    for j in range(w):
        za_r, za_i, zb_r, zb_i, h = zar[j], zai[j], zbr[j], zbi[j], h2[j]
        s, e_r, e_i, m_r, m_i = acc[j], er[j], ei[j], mr[j], mi[j]
        a_r, a_i, b_r, b_i = ar[j], ai[j], br[j], bi[j]
        s, e_r, e_i, m_r, m_i, a_r, a_i, b_r, b_i = _step(i1, c1, s, e_r, e_i, m_r, m_i, a_r, a_i, b_r, b_i, za_r,
                                                           za_i, zb_r, zb_i, h)
        if steps == 2:
            s, e_r, e_i, m_r, m_i, a_r, a_i, b_r, b_i = _step(i2, c2, s, e_r, e_i, m_r, m_i, a_r, a_i, b_r, b_i, za_r,
                                                               za_i, zb_r, zb_i, h)
        acc[j], er[j], ei[j], mr[j], mi[j], ar[j], ai[j], br[j], bi[j] = s, e_r, e_i, m_r, m_i, a_r, a_i, b_r, b_i


@exact_njit(inline="always")
def _step(invk, ck, s, e_r, e_i, m_r, m_i, a_r, a_i, b_r, b_i, za_r, za_i, zb_r, zb_i, h2):
    """One lane's step k -> k + 1 on D_k = k E_k (e: D_k, m: D_{k-1}, a, b: the ends' boundary terms times 4,
    exactly, as the recurrence takes them; invk = 1 / k, h2 = 2H): returns s + ck Re D_{k+1} (ck = c_{k+1} /
    (k+1), so that s gains c_{k+1} Re E_{k+1}), D_{k+1}, D_k and the ends' terms times z. Divided by k,
    (k+1) E_{k+1} + 2(k + iH) E_k + (k-1) E_{k-1} = -4i q reads D_{k+1} = -4i q - 2 D_k - (2iH / k) D_k - D_{k-1}
    (D_0 = 0: the term of E_0 vanishes at k = 1): 18 operations with the ends' powers, 9 of them fused
    multiply-adds (`expint.fma`; 2 D_k is exact), where separate products and sums took 27."""
    hk = h2 * invk
    nr = fma(hk, e_i, fma(-2.0, e_r, b_i - a_i)) - m_r
    ni = fma(-hk, e_r, fma(-2.0, e_i, a_r - b_r)) - m_i
    return (fma(ck, nr, s), nr, ni, e_r, e_i, fma(a_r, za_r, -(a_i * za_i)), fma(a_r, za_i, a_i * za_r),
            fma(b_r, zb_r, -(b_i * zb_i)), fma(b_r, zb_i, b_i * zb_r))


@njit
def forward_loss(H, c):
    """Estimated amplification of rounding errors by the forward recurrence,
    max_k |c_k| exp(2 sqrt(H k)) / max_k |c_k|, sampled at <= 9 values of k (the dominant
    homogeneous solution grows like exp(2 sqrt(H k)) relative to the wanted one)."""
    L = c.shape[0] - 1
    cmax = 0.0
    for k in range(L + 1):
        a = abs(c[k])
        if a > cmax:
            cmax = a
    if cmax == 0.0:
        return 1.0
    best = 1.0
    for j in range(9):
        k = (L * (j + 1)) // 9
        if k < 1:
            continue
        v = abs(c[k]) / cmax * math.exp(2.0 * math.sqrt(H * k))
        if v > best:
            best = v
    return best


def start_sensitivity(H, c):
    """|dS/dK1| + |dS/dL1| of S = sum_k c_k Re E_k at each H of the array `H`. S is linear in the start
    values K1, L1 (step 3: E_0 = 2 K1, E_1 = 2 H L1 - 2i H K1 + terms of the ends, which the recurrence
    adds on its own), so its derivatives are the sums over c_k of the homogeneous recurrence's
    solutions (k+1) E_{k+1} + 2(k + iH) E_k + (k-1) E_{k-1} = 0 from E_0 = 2, E_1 = -2iH (K1) and from
    E_0 = 0, E_1 = 2H (L1): functions of H alone, whatever the segment's ends. Each grows like
    exp(2 sqrt(H k)), as the rounding errors `forward_loss` bounds do, but the c_k weigh them down: for
    HG 0.9 the sums stay near 2 c_0 where sum |c_k| forward_loss is 10^2 - 10^4."""
    H = np.asarray(H, dtype=float)
    prev = np.stack([np.full(H.shape, 2.0 + 0.0j), np.zeros(H.shape, dtype=complex)])  # E_0 of K1, of L1
    cur = np.stack([-2.0j * H, 2.0 * H + 0.0j])  # E_1
    acc = c[0] * prev.real + (c[1] * cur.real if c.shape[0] > 1 else 0.0)
    for k in range(1, c.shape[0] - 1):
        prev, cur = cur, (-2.0 * (k + 1.0j * H) * cur - (k - 1.0) * prev) / (k + 1.0)
        acc += c[k + 1] * cur.real
    return np.abs(acc[0]) + np.abs(acc[1])


# measured: forward relative error ~ FORWARD_ERR_PER_LOSS * forward_loss (<= 3e-15 * loss)
FORWARD_ERR_PER_LOSS = 3e-15


@njit
def times_trig(c, a, b, gc, gs):
    """The product of the cosine series sum_k c_k cos(k phi) (k <= L) and the trigonometric
    polynomial sum_m a_m cos(m phi) + b_m sin(m phi) (m <= M), as gc (cosines) and gs (sines) of
    length L + M + 1 (product-to-sum: cos k cos m = (cos(k+m) + cos(k-m)) / 2, cos k sin m =
    (sin(k+m) - sin(k-m)) / 2); returns sum |gc| + sum |gs|."""
    gc[:] = 0.0
    gs[:] = 0.0
    for k in range(c.shape[0]):
        ck = c[k]
        gc[k] += ck * a[0]
        for m in range(1, a.shape[0]):
            ha, hb = 0.5 * ck * a[m], 0.5 * ck * b[m]
            gc[k + m] += ha
            gc[abs(k - m)] += ha
            gs[k + m] += hb
            if m > k:
                gs[m - k] += hb
            elif m < k:
                gs[k - m] -= hb
    return np.sum(np.abs(gc)) + np.sum(np.abs(gs))
