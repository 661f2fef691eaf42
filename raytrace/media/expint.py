"""Scaled exponential integrals and the PP09 integrals I0/I1 (METHODS.md §4-5).

* ``g_scaled(w)``   g(w) = e^w E1(w), complex w in the closed right half-plane (bounded, ~1/w).
* ``en_scaled(n, x)`` e^x E_n(x) for real x >= 0 (used by the on-axis limit of analytic.py).
* ``i0i1_stable(H, va, vb)`` I0 = int_va^vb e^{-Hv}/(1+v^2) dv and I1 = int e^{-Hv} v/(1+v^2) dv
  via the scaled-E1 form (no cancellation of O(pi) constants, no overflow), vb may be +inf.
* ``i01_series(a, va, vb, precision, max_iter)`` the paper's Fig. 2 loop (power series of Ei with
  the amplitude indicator, relative control ``indicator <= precision*|I0|``), returning
  (I0, I1, iterations).  Accurate only for small rho = |a| sqrt(1+v^2) (it loses about
  log10(e^rho) digits; see tests/test_expint.py for the documented failure at rho ~ 30).

Written from the formulas of METHODS.md; no external code.
"""
import cmath
import math

import llvmlite.binding as llvm
import llvmlite.ir as llvm_ir
import numba
import numpy as np
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from ..jit import exact_njit, njit

EULER_GAMMA = 0.57721566490153286060651209
_EPS = 2.220446049250313e-16
_FPMIN = 1e-300

# The power series of E1 sums terms up to ~e^|w|/|w| to a result of size ~e^{-Re w}/|w|, so it
# loses a factor ~e^{|w| + Re w} to rounding; it is used while |w| + Re w < G_SERIES_REACH (at most
# ~2 digits lost), where it is cheaper than the continued fraction, which converges slowly near the
# imaginary axis.
G_SERIES_REACH = 5.0


def _series_weights(n):
    """1 / (k k!) for k = 0 .. n - 1 (entry 0 unused, 0), by the float operations the Fig. 2 loop
    did in its own iterations (k! carried as a float, multiplied by k, then the reciprocal of k
    times it), so that the table holds the same doubles; from k = 170 on k k! overflows and the
    weight is 0, as is the table's last entry, which every larger k reads."""
    w = np.zeros(n)
    kfac = 1.0
    for k in range(1, n - 1):
        kfac *= k
        w[k] = 1.0 / (k * kfac)
    return w


SERIES_WEIGHTS = _series_weights(172)


@njit
def g_scaled(w):
    """g(w) = exp(w) E1(w) (principal branch) for complex w with Re w >= 0, w != 0."""
    if abs(w) + w.real < G_SERIES_REACH:
        # E1(w) = -gamma - log w - sum_{k>=1} (-w)^k / (k k!)
        s = 0.0 + 0.0j
        term = 1.0 + 0.0j  # (-w)^k / k!
        for k in range(1, 80):
            term = term * (-w) / k
            inc = term / k
            s += inc
            if abs(inc) < 1e-17 * (abs(s) + 1.0):
                break
        return cmath.exp(w) * (-EULER_GAMMA - cmath.log(w) - s)
    # even continued fraction e^w E1(w) = 1/(w+1- 1/(w+3- 4/(w+5- ...))), modified Lentz
    b = w + 1.0
    c = 1.0 / _FPMIN + 0.0j
    d = 1.0 / b
    h = d
    for i in range(1, 500):
        an = -float(i * i)
        b = b + 2.0
        d = an * d + b
        if d == 0.0:
            d = _FPMIN + 0.0j
        c = b + an / c
        if c == 0.0:
            c = _FPMIN + 0.0j
        d = 1.0 / d
        de = c * d
        h = h * de
        if abs(de.real - 1.0) + abs(de.imag) < 1e-16:
            break
    return h


@njit
def en_scaled(n, x):
    """e^x E_n(x) for integer n >= 1 and real x >= 0 (x = 0 needs n >= 2: 1/(n-1))."""
    if x == 0.0:
        return 1.0 / (n - 1)
    if x < 1.0:
        # E1 by its series, then E_{k+1} = (e^{-x} - x E_k)/k (stable for x < 1)
        s = 0.0
        term = 1.0
        for k in range(1, 60):
            term = term * (-x) / k
            inc = term / k
            s += inc
            if abs(inc) < 1e-17 * (abs(s) + 1.0):
                break
        e = -EULER_GAMMA - math.log(x) - s
        ex = math.exp(-x)
        for k in range(1, n):
            e = (ex - x * e) / k
        return math.exp(x) * e
    b = x + n
    c = 1.0 / _FPMIN
    d = 1.0 / b
    h = d
    for i in range(1, 500):
        an = -float(i * (n - 1 + i))
        b += 2.0
        d = an * d + b
        if d == 0.0:
            d = _FPMIN
        c = b + an / c
        if c == 0.0:
            c = _FPMIN
        d = 1.0 / d
        de = c * d
        h *= de
        if abs(de - 1.0) < 1e-16:
            break
    return h


@njit
def i0i1_stable(H, va, vb):
    """(I0, I1)(a=-H, va, vb) from the scaled E1: I0 = [e^{-Hv} Im g(H(v+i))]_va^vb,
    I1 = -[e^{-Hv} Re g(H(v+i))]_va^vb. H > 0, 0 <= va <= vb <= +inf."""
    ga = g_scaled(complex(H * va, H))
    ea = math.exp(-H * va)
    i0 = -ea * ga.imag
    i1 = ea * ga.real
    if vb < math.inf:
        gb = g_scaled(complex(H * vb, H))
        eb = math.exp(-H * vb)
        i0 += eb * gb.imag
        i1 -= eb * gb.real
    return i0, i1


@njit
def i01_series(a, va, vb, precision, max_iter):
    """The paper's Fig. 2 loop (see `i01_series_est`), returning (I0, I1, iterations)."""
    i0, i1, k, err = i01_series_est(a, va, vb, precision, max_iter)
    return i0, i1, k


@njit
def i01_series_est(a, va, vb, precision, max_iter):
    """The paper's Fig. 2 loop: (I0, I1, iterations, rounding-error estimate) for a < 0, 0 <= va < vb
    (vb may be +inf).

    The k-th increments are rho^k sin(a - k phi) / (k k!) and rho^k cos(a - k phi) / (k k!) at both
    ends (PP-24/25), i.e. the imaginary and real parts of e^{ia} conj(z)^k / (k k!) with
    z = a (v + i) = rho e^{i phi}; the powers are carried by one complex multiplication per end
    and iteration instead of four trigonometric calls. Convergence test (PP09's relative control):
    stop when the amplitude indicator (rho_b^k + rho_a^k)/(k k!) <= precision * |I0|, or after
    max_iter iterations. For vb = +inf the limits i0(a, inf) = pi cos a, i1(a, inf) = -pi sin a
    replace the upper antiderivative (only the lower end is summed).
    """
    i0, i1, pa, za, zb, rva, rvb = _series_start(a, va, vb)
    pb = pa
    big = abs(i0) + abs(i1) + 1.0
    rka = 1.0
    rkb = 1.0
    k = 0
    last = SERIES_WEIGHTS.shape[0] - 1
    for k in range(1, max_iter + 1):
        rka *= rva
        rkb *= rvb
        pa *= za
        pb *= zb
        denom = SERIES_WEIGHTS[min(k, last)]  # 1 / (k k!), tabulated: no division on the loop's path
        i0 += (pb.imag - pa.imag) * denom
        i1 += (pb.real - pa.real) * denom
        indicator = (rkb + rka) * denom
        if indicator > big:
            big = indicator
        if indicator <= precision * abs(i0):
            break
    # rounding: every partial sum carries ~eps * (largest increment); ~sqrt(rho) of them are large
    err = 4.0 * _EPS * big * (1.0 + math.sqrt(rva + rvb))
    return i0, i1, k, err


@njit(inline="always")
def _series_start(a, va, vb):
    """(I0, I1, e^{ia}, z_a, z_b, rho_a, rho_b) before the Fig. 2 loop's first iteration (`i01_series_est`):
    the logarithmic terms of both ends (for vb = +inf the limits at infinity), z = a (v + i), conjugated as the
    loop takes it (z_b = 0, rho_b = 0 at infinity)."""
    rva, rvb, x, y = _series_arguments(a, va, vb)
    phi = math.atan(y) if vb < math.inf else math.atan2(a, a * va)
    return _series_terms(a, va, vb, math.sin(a), math.cos(a), math.log(x), phi, rva, rvb)


@njit(inline="always")
def _series_arguments(a, va, vb):
    """(rho_a, rho_b, x, y) of `_series_start`: the ends' |z| = |a| sqrt(1 + v^2) (rho_b = 0 at vb = +inf) and the
    arguments of its logarithm and arc tangent, rho_b / rho_a and tan(phi_b - phi_a) = (va - vb) / (1 + va vb)
    (1 + va vb > 0); at vb = +inf rho_a and va, arg(a (va + i)) = -pi / 2 - atan(va) for a < 0."""
    rva = abs(a) * math.sqrt(va * va + 1.0)
    if vb < math.inf:
        rvb = abs(a) * math.sqrt(vb * vb + 1.0)
        return rva, rvb, rvb / rva, (va - vb) / (1.0 + va * vb)
    return rva, 0.0, rva, va


@njit(inline="always")
def _series_terms(a, va, vb, sina, cosa, logx, phi, rva, rvb):
    """`_series_start`'s result from sin a, cos a, the logarithm of `_series_arguments`' x and the angle phi: the
    arc tangent of its y (vb finite: phi_b - phi_a), or at vb = +inf arg(a (va + i)) itself."""
    if vb < math.inf:
        i0 = sina * logx - cosa * phi
        i1 = cosa * logx + sina * phi
        zb = complex(a * vb, -a)
    else:
        lg = EULER_GAMMA + logx
        # I = i(inf) - i(va)
        i0 = math.pi * cosa - (sina * lg - cosa * phi)
        i1 = -math.pi * sina - (cosa * lg + sina * phi)
        zb = 0.0j
    return i0, i1, complex(cosa, sina), complex(a * va, -a), zb, rva, rvb


@intrinsic
def fma(typingctx, x, y, z):
    """x * y + z rounded once (IEEE 754 fused multiply-add, LLVM's llvm.fma): one instruction, the same bits in
    SIMD registers or not, where the fastmath flag `contract` lets the compiler choose where to fuse."""
    def codegen(context, builder, signature, args):
        return builder.fma(*args)
    return types.float64(types.float64, types.float64, types.float64), codegen


@intrinsic
def select(typingctx, cond, x, y):
    """x if cond else y as LLVM's select, no branch (numba branches on `x if cond else y`, and a loop with a
    branch in it does not run in SIMD registers)."""
    def codegen(context, builder, signature, args):
        return builder.select(*args)
    return types.float64(types.boolean, types.float64, types.float64), codegen


def _vector_width():
    """How many doubles one call of glibc's vector math library (libmvec: sin, cos, log, atan, exp of a SIMD
    register, each within 4 ulp) takes in this process: 8 with AVX-512, 4 with AVX2; 0 where it cannot be called
    (no libmvec, another CPU, or numba told to compile for a CPU other than this one: `vector_math` then calls the
    scalar libm)."""
    if numba.config.CPU_NAME or numba.config.CPU_FEATURES:
        return 0
    try:
        features = llvm.get_host_cpu_features()
        width = 8 if features.get("avx512f") else 4 if features.get("avx2") else 0
        if width:
            llvm.load_library_permanently("libmvec.so.1")
    except RuntimeError:  # (features unknown, or no libmvec)
        return 0
    return width


VECTOR_WIDTH = _vector_width()
VECTOR_BLOCK = max(VECTOR_WIDTH, 1)  # the entries one `vector_math` call takes
LIBM_ULPS = 4.0  # libmvec's documented accuracy (the scalar libm's is within 1 ulp)


def _vector_math(name, width=VECTOR_WIDTH):
    """An intrinsic f(buf, i): buf[i:i + max(width, 1)] = name(buf[i:i + max(width, 1)]) in place (buf a contiguous
    float64 array, name a libm function of one double): one call of libmvec's variant for a SIMD register of `width`
    doubles (the x86-64 vector function ABI's name), or of the scalar libm where width is 0. Entry by entry: an entry's
    result does not depend on its neighbours (libmvec takes its special cases lane by lane)."""
    symbol = f"_ZGV{'e' if width == 8 else 'd'}N{width}v_{name}" if width else name

    @intrinsic
    def vector_math(typingctx, buf, i):
        def codegen(context, builder, signature, args):
            data = context.make_array(signature.args[0])(context, builder, args[0]).data
            at = builder.gep(data, [context.cast(builder, args[1], signature.args[1], types.intp)])
            vt = llvm_ir.VectorType(llvm_ir.DoubleType(), width) if width else llvm_ir.DoubleType()
            ptr = builder.bitcast(at, vt.as_pointer())
            fn = cgutils.get_or_insert_function(builder.module, llvm_ir.FunctionType(vt, [vt]), symbol)
            builder.store(builder.call(fn, [builder.load(ptr, align=8)]), ptr, align=8)
            return context.get_dummy_value()
        return types.none(buf, i), codegen
    return vector_math


vector_sin, vector_cos, vector_log, vector_atan, vector_exp = (_vector_math(f)
                                                              for f in ("sin", "cos", "log", "atan", "exp"))


SERIES_LANES = 64  # segments whose Fig. 2 loops `i01_series_lanes` advances side by side


@exact_njit
def i01_series_lanes(args, rows, prec_col, max_iter, out):
    """out[i] = (I0, I1, iterations, rounding-error estimate) of `i01_series_est(-H, va, vb, precision, max_iter)`
    for H, va, vb = args[rows[i], 0:3] and precision = args[rows[i], prec_col]: the loops of SERIES_LANES
    segments advanced together, two iterations k a pass over the lanes (in SIMD registers), each lane's sums
    frozen from the iteration its own test stops it, the pass repeated while any lane runs. Compiled without
    fastmath, no operation mixing two segments, so that a segment's result does not depend on its batch;
    the same arithmetic as `i01_series_est` but for the fused multiply-adds (`fma`; the scalar loop lets the
    compiler fuse) and the setup's sin, cos, log and atan, VECTOR_BLOCK lanes a call (`vector_math`: libmvec,
    within LIBM_ULPS ulp, which the estimate adds): its last bits may differ."""
    st = np.ones((22, SERIES_LANES))  # (the transcendentals' rows beyond a last batch's lanes: 1, harmless)
    i0, i1, big, its, prec = st[0], st[1], st[2], st[3], st[4]
    par, pai, pbr, pbi, zar, zai, zbr, zbi = st[5], st[6], st[7], st[8], st[9], st[10], st[11], st[12]
    rka, rkb, rva, rvb, sn, cs, lg, at, lib = st[13], st[14], st[15], st[16], st[17], st[18], st[19], st[20], st[21]
    for first in range(0, rows.shape[0], SERIES_LANES):
        w = min(SERIES_LANES, rows.shape[0] - first)
        for j in range(w):  # `_series_start` with its libm calls made VECTOR_BLOCK lanes at a time
            r = rows[first + j]
            a, va, vb = -args[r, 0], args[r, 1], args[r, 2]
            rva[j], rvb[j], lg[j], at[j] = _series_arguments(a, va, vb)
            sn[j], cs[j] = a, a
        for j in range(0, w, VECTOR_BLOCK):
            vector_sin(sn, j)
            vector_cos(cs, j)
            vector_log(lg, j)
            vector_atan(at, j)
        for j in range(w):
            r = rows[first + j]
            a, va, vb = -args[r, 0], args[r, 1], args[r, 2]
            phi = at[j] if vb < math.inf else -0.5 * math.pi - at[j]
            i0[j], i1[j], p, za, zb, _, _ = _series_terms(a, va, vb, sn[j], cs[j], lg[j], phi, rva[j], rvb[j])
            # libmvec's error in the start terms: sin a, cos a within LIBM_ULPS ulp each times |log x| + |phi|
            # (+ |gamma| + pi at vb = +inf), the logarithm and the angle within LIBM_ULPS ulp
            ends = abs(lg[j]) + abs(phi) + (0.0 if vb < math.inf else EULER_GAMMA + math.pi)
            lib[j] = 2.0 * LIBM_ULPS * _EPS * ends
            big[j] = abs(i0[j]) + abs(i1[j]) + 1.0
            its[j], prec[j] = 0.0, args[r, prec_col]
            par[j], pai[j], pbr[j], pbi[j] = p.real, p.imag, p.real, p.imag
            zar[j], zai[j], zbr[j], zbi[j] = za.real, za.imag, zb.real, zb.imag
            rka[j], rkb[j] = 1.0, 1.0
        k, live = 0, w
        while live > 0 and k < max_iter:  # two iterations a pass (one the last, where max_iter is odd): each lane's
            steps = min(2, max_iter - k)  # state loaded and stored once; one call site, so its code is typed once
            live = _series_pass(w, k + 1, steps, i0, i1, big, its, prec, par, pai, pbr, pbi, zar, zai, zbr, zbi, rka,
                                rkb, rva, rvb)
            k += steps
        for j in range(w):
            out[first + j, 0], out[first + j, 1] = i0[j], i1[j]
            out[first + j, 2] = its[j] if its[j] > 0.0 else float(max_iter)  # (a loop that never stopped)
            out[first + j, 3] = 4.0 * _EPS * big[j] * (1.0 + math.sqrt(rva[j] + rvb[j])) + lib[j]


@exact_njit(inline="always")
def _series_pass(w, k, steps, i0, i1, big, its, prec, par, pai, pbr, pbi, zar, zai, zbr, zbi, rka, rkb, rva, rvb):
    """Iterations k .. k + steps - 1 (steps 1 or 2) of the Fig. 2 loop for lanes 0 .. w - 1 (`i01_series_lanes`,
    `_series_iteration`); returns how many lanes run on."""
    last = SERIES_WEIGHTS.shape[0] - 1
    d1, d2 = SERIES_WEIGHTS[min(k, last)], SERIES_WEIGHTS[min(k + 1, last)]
    k1, k2 = float(k), float(k + 1)
    live = 0
    for j in range(w):
        s0, s1, was, it, a_r, a_i, b_r, b_i = i0[j], i1[j], big[j], its[j], par[j], pai[j], pbr[j], pbi[j]
        ka, kb, p = rka[j], rkb[j], prec[j]
        za_r, za_i, zb_r, zb_i, ra, rb = zar[j], zai[j], zbr[j], zbi[j], rva[j], rvb[j]
        s0, s1, was, it, a_r, a_i, b_r, b_i, ka, kb = _series_iteration(k1, d1, p, za_r, za_i, zb_r, zb_i, ra, rb, s0,
                                                                        s1, was, it, a_r, a_i, b_r, b_i, ka, kb)
        if steps == 2:
            s0, s1, was, it, a_r, a_i, b_r, b_i, ka, kb = _series_iteration(k2, d2, p, za_r, za_i, zb_r, zb_i, ra, rb,
                                                                            s0, s1, was, it, a_r, a_i, b_r, b_i, ka,
                                                                            kb)
        i0[j], i1[j], big[j], its[j], par[j], pai[j], pbr[j], pbi[j] = s0, s1, was, it, a_r, a_i, b_r, b_i
        rka[j], rkb[j] = ka, kb
        live += it == 0.0
    return live


@exact_njit(inline="always")
def _series_iteration(k, denom, prec, za_r, za_i, zb_r, zb_i, ra, rb, s0, s1, was, it, pa_r, pa_i, pb_r, pb_i, ka,
                      kb):
    """One lane's iteration k (denom = 1 / (k k!)) of `i01_series_est`'s loop: the powers advanced whatever the
    lane's state, the sums, the largest indicator and the iteration count `it` (0 while it runs) only while it
    runs (`select`: no branch, so that the loop over the lanes runs in SIMD registers)."""
    ar, ai = fma(pa_r, za_r, -(pa_i * za_i)), fma(pa_r, za_i, pa_i * za_r)
    br, bi = fma(pb_r, zb_r, -(pb_i * zb_i)), fma(pb_r, zb_i, pb_i * zb_r)
    ka, kb = ka * ra, kb * rb
    n0, n1 = fma(bi - ai, denom, s0), fma(br - ar, denom, s1)
    indicator = (kb + ka) * denom
    run = it == 0.0
    stop = indicator <= prec * abs(n0)
    return (select(run, n0, s0), select(run, n1, s1), select(run & (indicator > was), indicator, was),
            select(run & stop, k, it), ar, ai, br, bi, ka, kb)
