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
   The wanted solution is "neutral" (O(1/k), endpoint contributions).  Hence
     * forward recurrence (from E_0, E_1) is used while the dominant growth, weighted by the
       decay of c_k, stays small (small H*L);
     * otherwise Olver's algorithm: the tridiagonal boundary-value problem for E_1..E_N (the
       equation k=1 does not involve E_0) with E_{N+1} from a two-term exponentially fitted
       endpoint asymptotic, solved by Gaussian elimination without pivoting (the matrix is
       diagonally dominant: |2(k+iH)| > (k-1)+(k+1)), N chosen so that the dominant solution
       damps the far-end error: exp(-2 sqrt(H)(sqrt(N)-sqrt(L))) * delta <= tol.

Scaling contract: S is linear and homogeneous in (K1, L1, ea, eb).  Pass ea = F e^{-H va},
eb = F e^{-H vb} (0 for vb = inf), K1 = F I0(-H, va, vb), L1 = F I1(-H, va, vb) for any common
factor F (e.g. F = e^{H va}, or the renderer's folded e^{-kt xh}) and the result is F*S.
"""
import math

import numpy as np

from ..jit import njit

_INV_4PI = 1.0 / (4.0 * math.pi)


# ----------------------------------------------------------------------------------------------
# coefficient helpers (Python, once per phase function)
# ----------------------------------------------------------------------------------------------
def legendre_to_cosine(a):
    """Cosine coefficients c_k (k = 0..L) with sum_l a_l P_l(cos phi) = sum_k c_k cos(k phi)."""
    a = np.asarray(a, dtype=float)
    L = a.shape[0] - 1
    al = np.empty(L + 1)
    al[0] = 1.0
    for j in range(1, L + 1):
        al[j] = al[j - 1] * (2 * j - 1) / (2 * j)
    c = np.zeros(L + 1)
    for l in range(L + 1):
        if a[l] == 0.0:
            continue
        for j in range(l + 1):
            c[abs(l - 2 * j)] += a[l] * al[j] * al[l - j]
    return c


def hg_legendre(g, L):
    """a_l = (2l+1) g^l / (4 pi), l = 0..L (Henyey-Greenstein, normalised over the sphere)."""
    l = np.arange(L + 1)
    return (2 * l + 1) * float(g) ** l * _INV_4PI


def rayleigh_legendre():
    """Rayleigh 3/(16 pi)(1+mu^2) = 1/(4 pi) P_0 + 1/(8 pi) P_2 (mu^2 = (1 + 2 P_2)/3)."""
    return np.array([_INV_4PI, 0.0, 1.0 / (8.0 * math.pi)])


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
def cosine_moments_forward(H, va, vb, K1, L1, ea, eb, c):
    """S = sum_k c_k Re E_k by the forward recurrence (stable only for small H*L)."""
    n = c.shape[0]
    ta, za, tb, zb = _ends(va, vb)
    fin = vb < math.inf
    ebt = eb * tb if fin else 0.0
    eat = ea * ta
    E0 = complex(2.0 * K1, 0.0)
    s = c[0] * E0.real
    if n == 1:
        return s
    evt = (ebt * vb if fin else 0.0) - eat * va
    et = ebt - eat
    E1 = complex(2.0 * evt + 2.0 * H * L1, -2.0 * (H * K1 + et))
    s += c[1] * E1.real
    pa = za        # za^k
    pb = zb
    Em = E0
    Ek = E1
    iH = complex(0.0, H)
    for k in range(1, n - 1):
        # -2i B_k = -4i (ebt zb^k - eat za^k)
        rhs = complex(0.0, -4.0) * (ebt * pb - eat * pa)
        En = (rhs - 2.0 * (k + iH) * Ek - (k - 1.0) * Em) / (k + 1.0)
        Em = Ek
        Ek = En
        s += c[k + 1] * En.real
        pa *= za
        pb *= zb
    return s


_ASYM_MAX = 30


@njit
def _endpoint_asym(H, k, v, zk):
    """Endpoint contribution of E_k at phi_v = 2 atan(v), i.e. int_{phi_v}^{pi} w e^{ik phi} dphi
    with w scaled to 1 at phi_v, by the exponentially fitted Watson expansion in phi:
    w(phi_v + s) e^{ik s} = exp(-Lam s + sum_{n>=2} l_n s^n), Lam = H (1+v^2)/2 - ik,
    l_n = -H V_n (V_n: Taylor coefficients of tan((phi_v+s)/2), V' = (1+V^2)/2),
    result zk * sum_n b_n n!/Lam^(n+1), b = exp(sum l_n s^n), optimal truncation."""
    V = np.zeros(_ASYM_MAX + 2)
    b = np.zeros(_ASYM_MAX + 1, dtype=np.complex128)
    V[0] = v
    V[1] = 0.5 * (1.0 + v * v)
    lam = complex(H * V[1], -k)
    il = 1.0 / lam
    b[0] = 1.0
    total = il
    fo = il            # n!/Lam^{n+1}
    best = 1e300
    partial = total
    for n in range(1, _ASYM_MAX + 1):
        # V_{n+1} = (sum_{j=0}^{n} V_j V_{n-j}) / (2(n+1))
        acc = 0.0
        for j in range(n + 1):
            acc += V[j] * V[n - j]
        V[n + 1] = acc / (2.0 * (n + 1))
        # b_n = (1/n) sum_{j=2}^{n} j l_j b_{n-j}, l_j = -H V_j
        bc = 0.0j
        for j in range(2, n + 1):
            bc += (-H * j * V[j]) * b[n - j]
        b[n] = bc / n
        fo = fo * n * il
        if n == 1:
            continue
        term = b[n] * fo
        at = abs(term)
        partial += term
        if at < best:
            # optimal truncation: keep the partial sum ending at the smallest term so far
            best = at
            total = partial
            if at <= 1e-17 * abs(total):
                break
        elif at > 1e4 * best:
            break
    return zk * total, best / abs(total)


@njit
def _far_guess(H, k, va, vb, ea, eb, zak, zbk, fin):
    """(E_k, relative error estimate): endpoint contribution at va minus that at vb (the
    essential-singularity parts at phi = pi cancel for a finite interval; for vb = inf the
    neglected part is ~ exp(H va - 2 sqrt(H k)) relative, included in the estimate)."""
    e, d = _endpoint_asym(H, k, va, zak)
    e = ea * e
    if fin:
        if eb != 0.0:
            eb_, db = _endpoint_asym(H, k, vb, zbk)
            e -= eb * eb_
            if db > d:
                d = db
    else:
        x = H * va - 2.0 * math.sqrt(H * k)
        if x > 0.0:
            x = 0.0
        d += math.exp(x)
    return e, d


@njit
def cosine_moments_olver(H, va, vb, K1, ea, eb, c, N, work):
    """S = sum_k c_k Re E_k by Olver's boundary-value method on k = 1..N (N >= L = len(c)-1),
    E_{N+1} from `_far_guess`; E_0 = 2 K1. `work`: complex128 array of length >= 2N+2."""
    n = c.shape[0]
    s = c[0] * 2.0 * K1
    if n == 1:
        return s
    ta, za, tb, zb = _ends(va, vb)
    fin = vb < math.inf
    ebt = eb * tb if fin else 0.0
    eat = ea * ta
    iH = complex(0.0, H)
    m4i = complex(0.0, -4.0)
    # forward elimination: d_k = 2(k+iH) - m k, m = (k-1)/d_{k-1}; r_k = rhs_k - m r_{k-1}
    pa = za
    pb = zb
    dprev = complex(1.0, 0.0)
    rprev = complex(0.0, 0.0)
    for k in range(1, N + 1):
        rhs = m4i * (ebt * pb - eat * pa)
        m = (k - 1.0) / dprev
        d = 2.0 * (k + iH) - m * k
        r = rhs - m * rprev
        work[2 * k] = d
        work[2 * k + 1] = r
        dprev = d
        rprev = r
        pa *= za
        pb *= zb
    Enext, d = _far_guess(H, N + 1, va, vb, ea, eb, pa, pb, fin)
    for k in range(N, 0, -1):
        Ek = (work[2 * k + 1] - (k + 1.0) * Enext) / work[2 * k]
        if k < n:
            s += c[k] * Ek.real
        Enext = Ek
    return s


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


# measured: forward relative error ~ FORWARD_ERR_PER_LOSS * forward_loss (<= 3e-15 * loss)
FORWARD_ERR_PER_LOSS = 3e-15
OLVER_MAX_N = 20000


@njit
def olver_length(H, L, delta, tol):
    """N with delta * exp(-2 sqrt(H) (sqrt(N) - sqrt(L))) <= tol, N >= L + 8."""
    x = math.log(max(delta, 1e-300) / tol)
    if x < 0.0:
        x = 0.0
    sN = math.sqrt(L) + x / (2.0 * math.sqrt(H))
    if sN * sN > OLVER_MAX_N:
        return OLVER_MAX_N
    N = int(sN * sN) + 8
    if N < L + 8:
        N = L + 8
    return N


@njit
def legendre_integral(H, va, vb, K1, L1, ea, eb, c, tol, work):
    """S = int_va^vb e^{-Hv} 2t sum_k c_k cos(k phi) dv, phi = 2 atan v (module docstring).

    H > 0; 0 <= va < vb <= inf; K1, L1 = F*I0, F*I1 and ea = F e^{-H va}, eb = F e^{-H vb}
    (eb = 0 for vb = inf) for a common factor F; returns F*S.  c: cosine coefficients
    (`legendre_to_cosine(a_l)`, length L+1); tol: target relative accuracy (1e-12 typical),
    selects forward recurrence vs Olver's method and Olver's length; work: complex128 scratch
    of length >= 2N+2 (reallocated if too short; pass np.empty(0, np.complex128) to let the
    kernel allocate)."""
    L = c.shape[0] - 1
    if L <= 1:
        return cosine_moments_forward(H, va, vb, K1, L1, ea, eb, c)
    floss = forward_loss(H, c)
    if FORWARD_ERR_PER_LOSS * floss <= tol:
        return cosine_moments_forward(H, va, vb, K1, L1, ea, eb, c)
    # quality of the far-end asymptotic value at k = L+1, then Olver's length
    fin = vb < math.inf
    ta, za, tb, zb = _ends(va, vb)
    zak = za ** (L + 1)
    zbk = zb ** (L + 1)
    e, delta = _far_guess(H, L + 1, va, vb, 1.0, eb / ea if ea > 0.0 else 0.0, zak, zbk, fin)
    N = olver_length(H, L, delta, tol)
    if N >= OLVER_MAX_N and FORWARD_ERR_PER_LOSS * floss < delta:
        return cosine_moments_forward(H, va, vb, K1, L1, ea, eb, c)
    if work.shape[0] < 2 * N + 2:
        work = np.empty(2 * N + 2, dtype=np.complex128)
    return cosine_moments_olver(H, va, vb, K1, ea, eb, c, N, work)
