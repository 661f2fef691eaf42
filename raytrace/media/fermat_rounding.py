"""How far a point or spot light's refracted integrand (media/slab.py `refracted_at`, Fermat's path
through one face of a convex refractive shape) may be off at a node: the rounding of its inputs and
of the refraction point, propagated with explicit derivative bounds (docs/error_bounds.md, "Point
and spot light in refractive shapes").

Notation of `refracted_at`: the point X at depth z = z0 + a x below the face's plane, the light at
height hl above it, rho their horizontal distance, r the refraction point's distance from X's foot
(s = rho - r from the light's), k = |(r, z)| and o = |(s, hl)| the legs inside and outside, t1, t2
the angles of incidence and refraction (sin t1 = eta sin t2, eta > 1), u = 2^-53.

Inputs. The face's plane is its mesh face's to dn on each normal component and dc on the offset
(interiors/shapes.py `plane_errors`; the entry face's is the row's own normal through the entry
point, 8u and 16u S): z0 is off by dc + sqrt(3) dn |p| + 8u S, z by that plus
x (sqrt(3) dn + 8u), hl by dc + sqrt(3) dn |L| + 8u S, a by sqrt(3) dn + 4u (S = |p| + the
segment's length + |L| + the largest |c_f|). rho =
sqrt(x^2 (1 - a^2) - 2 x wl + ll) has a radicand off by 16u (x + sqrt(ll))^2 plus the tilt of the
plane (2 sqrt(3) dn (|L - p| + x) on rho), so rho is off by drho = that / (2 rho) + the tilt.

The refraction point. r is the root of f(r) = sin t1 - eta sin t2 (`refraction_point`, bisection to
the resolution of doubles): the computed f is within 8u (1 + eta) of the exact one, and
|f'| >= eta cos^2 t2 / k with cos^2 t2 >= 1 - 1 / eta^2, so the computed root is off by
8u (1 + eta) eta k / (eta^2 - 1) + 4u k. The exact root moves with the inputs: dr/drho in [0, 1]
(rho = s + z tan t2 with s increasing in t2), |dr/dz| <= tan t2 <= 1 / sqrt(eta^2 - 1) and
|dr/dhl| <= tan t1 = s / hl (differentiating rho = hl tan t1 + z tan t2 at fixed rho and z). Then k
is off by dk = dr + dz, o by do = drho + dr + dhl (both are Lipschitz-1 norms of their legs).

The integrand ks Phi(mu) T(cos t1) E F(c) exp(-kt (x + k) - kt_out o), relative, first order:
- the exponent: kt (dk + 4u x) + kt_out do, plus 16u of its size;
- cos t1 = hl / o: (dhl + do) / hl (o >= hl); Fresnel's T: twice that (|d log T / d log cos t1| <= 2
  for eta > 1, checked on a dense grid by tests/test_refracted_point_bounds.py);
- E = T sin t1 / (rho cos t2 Q), Q = hl / cos^2 t1 + z cos t1 / (eta cos^3 t2): sin t1 / rho =
  s / (o rho) with s >= rho hl / (hl + z) (tan t1 >= tan t2), so (drho + dr) (hl + z) / (rho hl) +
  do / hl + drho / rho; cos t2 = z / k: (dz + dk) / (k cos t2); Q >= hl: dhl / hl + 2 (cos t1's) +
  (dz + z (cos t1's) + 3 (dz + dk) / cos t2) / (eta cos^3 t2 hl);
- the scattering cosine mu (t2 moves by (dr cos t2 + dz sin t2) / k): (dr + dz) / k +
  2 (drho + 16u (x + sqrt(ll))) / rho + da, times
  the phase's condition (`phase_condition`);
- a spot's cosine c to its axis: (2 drho + 2 dr + dhl + do + 32u (x + sqrt(ll) + |la|)) / hl +
  2 sqrt(3) dn + 8u, times the falloff's slope (absolute: lights `band_slope` / (cos_start - cos_end));
- 32u for the products and quotients.
The whole is doubled for the second-order terms. Below the light (rho <= 1e-12 (hl + z), where
`refracted_at` takes the limit T(1) / (hl + z / eta)^2): 2 (dhl + dz / eta) / (hl + z / eta) + 1e-11
(the limit's own error, O(rho / hl)) plus the phase's and the spot's as above.

Light leaving the denser side (eta < 1: a light inside a refractive shape, the point outside; media/slab.py
`out_of_faces`). sin t1 = eta sin t2 <= eta: cos t1 >= sqrt(1 - eta^2), t2 -> 90 degrees as the point nears
the critical circle on the plane. Changed from the above:
- the root: |f'| >= hl^2 / o^3, so the computed root is off by 8u (1 + eta) o^3 / hl^2 + 4u k;
- dr/dz = eta r z / k^3 / (hl^2 / o^3 + eta z^2 / k^3) (implicit differentiation of f) is at most r / z
  (dropping hl^2 / o^3) and eta z o^3 / (hl^2 k^2) (dropping the other, r <= k): `leaving_slope` bounds it
  over a piece, a node takes the lesser at its own values;
- Fresnel's T: T(cos t1; eta) = T(cos t2; 1 / eta) (reciprocity), whose log-slope in cos t2 is at most 1.001
  (the grid of tests/test_refracted_point_bounds.py, eta > 1), and d log cos t2 / d log cos t1 = cos1^2 /
  (eta^2 cos2^2); `fresnel`'s own cos t2 = sqrt(1 - sin1^2 / eta^2) is off by (2 / eta^2 + 1/2) u / cos2^2
  relative, and 1 - R by 11u absolute where T >= tau cos2, tau = 4 eta sqrt(1 - eta^2) / (1 + eta)^2 (each
  of 1 - rs^2 = 4 c eta ct / (c + eta ct)^2 and 1 - rp^2 = 4 eta c ct / (eta c + ct)^2 with c <= 1, ct <= 1);
- sin t1 / rho = s / (o rho): (drho + dr) / s + do / hl + drho / rho (s itself: no s >= rho hl / (hl + z));
- Q = A + B (A = hl / cos1^2, B = z cos1 / (eta cos2^3), both positive): at most the sum of their relative
  errors, dh / hl + 2 (cos t1's) and dz / z + (cos t1's) + 3 (cos t2's).
These grow like 1 / cos2^2 near the critical circle while the term vanishes there (E ~ z^2 beyond it): where
the doubled first order exceeds 1/4 (media/slab.py `term_error`), the term's error is at most itself plus
E <= T sin1 cos1^2 / (rho cos2 hl) <= 2 (eta + 1 / eta) / hl^2 (Q >= A; T <= 2 (eta + 1 / eta) cos2 / cos1
from the same factors with their denominators >= c^2, (eta c)^2; sin1 / rho <= 1 / o <= 1 / hl).
"""
from __future__ import annotations

import math

from ..jit import njit

U = 2.0 ** -53
SQ3 = math.sqrt(3.0)


@njit
def refraction_newton(rho, z, hl, eta):
    """media/slab.py `refraction_point` by Newton's method kept inside the bracket (bisection where a
    step leaves it): the root of f(r) = (rho - r) / o - eta r / k, which falls from f(0) >= 0 to
    f(rho) <= 0 with f' = -hl^2 / o^3 - eta z^2 / k^3, to the resolution of doubles (within 4e-16 rho
    of where the computed f changes sign)."""
    if not z > 0.0:  # on the plane: r = 0, or for eta < 1 where the light leaves at the critical angle (sin t1 = eta)
        return max(rho - hl * eta / math.sqrt(1.0 - eta * eta), 0.0) if eta < 1.0 else 0.0
    lo, hi = 0.0, rho
    r = rho * z / (eta * hl + z)  # the paraxial guess, in the bracket
    for _ in range(100):
        o, k = math.sqrt((rho - r) * (rho - r) + hl * hl), math.sqrt(r * r + z * z)
        f = (rho - r) / o - eta * r / k
        if f > 0.0:
            lo = r
        else:
            hi = r
        step = f / (hl * hl / (o * o * o) + eta * z * z / (k * k * k))
        if abs(step) <= 4e-16 * rho:
            return min(max(r + step, 0.0), rho)
        nxt = r + step
        if not lo < nxt < hi:
            nxt = 0.5 * (lo + hi)
            if not lo < nxt < hi:
                return r
        r = nxt
    return r


@njit
def fermat_speed(rho0, rho1, zmin, a, eta):
    """K_R: a bound on the speed |R'(x)| of the refraction point on the face's plane over a piece of a
    segment whose horizontal distances to the light at its ends are rho0, rho1 and whose least depth
    is zmin (shadows/fermat_legs.py's module docstring: sqrt(1 - a^2) + |a| min(1 / sqrt(eta^2 - 1),
    rho_max / z_min))."""
    t = 1.0 / math.sqrt(eta * eta - 1.0) if eta > 1.0 else math.inf
    if zmin > 0.0:
        t = min(t, max(rho0, rho1) / zmin)
    return math.sqrt(max(1.0 - a * a, 0.0)) + abs(a) * t


@njit
def fermat_pace(width, rho0, rho1, z_a, z_b, a, hl, eta):
    """For eta < 1 (the point's side the less dense), a bound on the refraction point's displacement on the
    face's plane over a piece of a segment of length `width` whose horizontal distances to the light at its
    ends are rho0, rho1 and depths z_a, z_b >= 0 (linear in x at rate a; hl > 0 the light's height). As for
    `fermat_speed`, |R'| <= W + |a| B with W = sqrt(1 - a^2) and B = T / (1 + z T'), T = tan t2, T' = dT/ds
    >= 0 (s' = (rho' - a T) / (1 + z T')). In sigma = sin t2 = s / (eta o), c = 1 - sigma^2: T = sigma /
    sqrt(c) <= 1 / sqrt(c), T' = sigma' / c^(3/2) with sigma' = hl^2 / (eta o^3), so B <= T / (z T') <= c C / z
    with C = eta o^3 / hl^2 <= eta (rho_max^2 + hl^2)^(3/2) / hl^2 (o <= |(rho, hl)|), and min(1 / sqrt(c),
    c C / z) <= (C / z)^(1/3); also B <= T = r / z <= rho_max / z. Integrated over the piece (dz = a dx):
    W width + min(1.5 C^(1/3) |z_b^(2/3) - z_a^(2/3)|, rho_max |ln(z_b / z_a)|), finite where a depth is 0
    (there the refraction point tends to where the light leaves at the critical angle). Times 1 + 1e-9."""
    rmax = max(rho0, rho1)
    w = math.sqrt(max(1.0 - a * a, 0.0)) * width
    cube = eta * (rmax * rmax + hl * hl) ** 1.5 / (hl * hl) if hl > 0.0 else math.inf
    turn = 1.5 * cube ** (1.0 / 3.0) * abs(z_b ** (2.0 / 3.0) - z_a ** (2.0 / 3.0)) if z_a != z_b else 0.0
    if z_a > 0.0 and z_b > 0.0:
        turn = min(turn, rmax * abs(math.log(z_b / z_a)))
    return (w + turn) * (1.0 + 1e-9)


@njit
def leg_errors(x, k, s, hl, ll, rho, eta, dn, dc, mags, entry, slope=math.inf):
    """(dz, dh, drho, dr, da): the errors of the depth z, the light's height hl, the horizontal distance
    rho, the refraction point's r and the cosine a at x, where the inside leg is k and s = rho - r
    (module docstring, "Inputs" and "The refraction point"; any k, s at least theirs and rho at
    most its, x at least the node's, bound them). dn, dc: the planes' errors; mags = (|p|, |L|,
    |L - p|, size), size = |p| + the segment's length + |L| + the largest |c_f|; entry: whether this
    is the row's entry face (its plane the entry point's, z0 = 0). For eta < 1 ("Light leaving the
    denser side"), slope: a bound on |dr/dz| there (`leaving_slope`; inf: dr inf)."""
    pn, ln, lp, size = mags
    if entry:
        dn, dz = 8.0 * U, 16.0 * U * size
    else:
        dz = dc + SQ3 * dn * pn + 8.0 * U * size
    dz += x * (SQ3 * dn + 8.0 * U)
    dh = dc + SQ3 * dn * ln + 8.0 * U * size
    lh = math.sqrt(ll)
    drho = 16.0 * U * (x + lh) * (x + lh) / (2.0 * rho) + SQ3 * dn * (lp + x)
    if eta > 1.0:
        dr = (8.0 * U * (1.0 + eta) * eta / (eta * eta - 1.0) + 4.0 * U) * k + drho + dz / math.sqrt(eta * eta - 1.0) \
            + dh * s / hl
    else:
        o = math.sqrt(s * s + hl * hl)
        dr = 8.0 * U * (1.0 + eta) * (o / hl) * (o / hl) * o + 4.0 * U * k + drho + dh * s / hl
        dr += dz * slope if slope < math.inf else math.inf
    return dz, dh, drho, dr, SQ3 * dn + 4.0 * U


@njit
def point_error(x, k, s, hl, ll, rho, eta, dn, dc, mags, entry, slope=math.inf):
    """A bound on the error of the refraction point R on the face's plane (`leg_errors`' arguments):
    dr along the horizontal direction, drho and the plane's tilt on the direction's and the foot's,
    16u of the coordinates."""
    _, _, drho, dr, da = leg_errors(x, k, s, hl, ll, rho, eta, dn, dc, mags, entry, slope)
    return dr + drho + (da - 4.0 * U) * (mags[2] + x) + 16.0 * U * mags[3]


@njit
def cosine_error(x, k, s, hl, ll, rho, eta, dn, dc, mags, entry, slope=math.inf):
    """A bound on the error of a spot's cosine to its axis of the direction the light leaves in
    (`leg_errors`' arguments; module docstring)."""
    _, dh, drho, dr, da = leg_errors(x, k, s, hl, ll, rho, eta, dn, dc, mags, entry, slope)
    do = drho + dr + dh + 4.0 * U * math.sqrt(s * s + hl * hl)
    turn = (2.0 * drho + 2.0 * dr + dh + do + 32.0 * U * (x + math.sqrt(ll) + mags[3])) / hl
    return 2.0 * (turn + 2.0 * da + 8.0 * U)


@njit
def leaving_slope(rmin, rmax, zlo, hl, eta):
    """For eta < 1, a bound on |dr/dz| over a piece where rho lies in [rmin, rmax], the depth is at least
    zlo >= 0 and the light's height is hl > 0 (module docstring, "Light leaving the denser side"): the
    least of tan t2 <= sigma / sqrt(1 - sigma^2), sigma = rmax / (eta sqrt(rmax^2 + hl^2)) (where below
    1), r / z <= rmax / zlo and eta o^3 z / (hl^2 k^2) with o^2 <= rmax^2 + hl^2 and z / k^2 <= min(1 / zlo,
    1 / (2 r_lo)), r_lo = rmin - eta hl / sqrt(1 - eta^2) (k^2 = r^2 + z^2 >= 2 r z; s <= hl tan t_c);
    inf where none applies. Times 1 + 1e-9."""
    best = math.inf
    sig = rmax / (eta * math.sqrt(rmax * rmax + hl * hl))
    if sig < 1.0:
        best = sig / math.sqrt(1.0 - sig * sig)
    near = math.inf
    if zlo > 0.0:
        best = min(best, rmax / zlo)
        near = 1.0 / zlo
    r_lo = rmin - eta * hl / math.sqrt(1.0 - eta * eta)
    if r_lo > 0.0:
        near = min(near, 0.5 / r_lo)
    if near < math.inf:
        o = math.sqrt(rmax * rmax + hl * hl)
        best = min(best, eta * (o / hl) * (o / hl) * o * near)
    return best * (1.0 + 1e-9)


@njit
def term_rounding(x, z0, a, hl, ll, rho, r, eta, kt, kt_out, ph, dn, dc, mags, entry):
    """(eps, dcos): a bound on the relative rounding of `refracted_at`'s value at x without the spot's
    falloff, and the absolute error of the spot's cosine to its axis (module docstring; eta < 1:
    `leaving_rounding`). ph: the phase's condition (media/slab.py `phase_condition`); dn, dc, mags,
    entry: as `leg_errors`'."""
    z = z0 + a * x
    if hl > 0.0 and z > 0.0 and eta < 1.0:
        return leaving_rounding(x, z, hl, ll, rho, r, eta, kt, kt_out, ph, dn, dc, mags, entry)
    if not (hl > 0.0 and z > 0.0 and eta > 1.0):
        return math.inf, math.inf
    lh = math.sqrt(ll)
    if not rho > 1e-12 * (hl + z):
        return _below_light(x, z, hl, ll, eta, kt, kt_out, ph, dn, dc, mags, entry, 1.0)
    k = math.sqrt(r * r + z * z)
    s = rho - r
    o = math.sqrt(s * s + hl * hl)
    dz, dh, drho, dr, da = leg_errors(x, k, s, hl, ll, rho, eta, dn, dc, mags, entry)
    dk = dr + dz + 4.0 * U * k
    do = drho + dr + dh + 4.0 * U * o
    cos2 = z / k
    rc1 = (dh + do) / hl
    eps = kt * (dk + 4.0 * U * x) + kt_out * do + 16.0 * U * (kt * (x + k) + kt_out * o)
    eps += 2.0 * rc1  # Fresnel's T
    eps += (drho + dr) * (hl + z) / (rho * hl) + do / hl + drho / rho  # sin t1 / rho
    eps += (dz + dk) / (k * cos2)  # cos t2
    eps += dh / hl + 2.0 * rc1 + (dz + z * rc1 + 3.0 * (dz + dk) / cos2) / (eta * cos2 ** 3 * hl)  # Q
    eps += ph * ((dr + dz) / k + 2.0 * (drho + 16.0 * U * (x + lh)) / rho + da)  # the phase
    eps += 32.0 * U
    return 2.0 * eps, cosine_error(x, k, s, hl, ll, rho, eta, dn, dc, mags, entry)


@njit
def _below_light(x, z, hl, ll, eta, kt, kt_out, ph, dn, dc, mags, entry, slope):
    """`term_rounding` below the light (rho <= 1e-12 (hl + z): the limit T(1) / (hl + z / eta)^2), dr/dz
    at most slope there."""
    dz, dh, _, _, da = leg_errors(x, z, 0.0, hl, ll, 1.0, eta, dn, dc, mags, entry, slope)
    q = hl + z / eta
    eps = 2.0 * (dh + dz / eta) / q + 1e-11 * (1.0 + ph) + 32.0 * U
    eps += kt * (dz + 8.0 * U * (x + z)) + kt_out * dh + 16.0 * U * (kt * (x + z) + kt_out * hl)
    return 2.0 * eps, 2.0 * (1e-11 + (dh + dz) / hl + da + 8.0 * U)


@njit
def leaving_rounding(x, z, hl, ll, rho, r, eta, kt, kt_out, ph, dn, dc, mags, entry):
    """`term_rounding` for eta < 1 at depth z > 0 (module docstring, "Light leaving the denser side")."""
    if not rho > 1e-12 * (hl + z):
        return _below_light(x, z, hl, ll, eta, kt, kt_out, ph, dn, dc, mags, entry, 1.0)
    lh = math.sqrt(ll)
    k = math.sqrt(r * r + z * z)
    s = rho - r
    o = math.sqrt(s * s + hl * hl)
    if not (s > 0.0 and r > 0.0):
        return math.inf, math.inf
    slope = min(r / z, eta * z * (o / hl) * (o / hl) * o / (k * k))
    dz, dh, drho, dr, da = leg_errors(x, k, s, hl, ll, rho, eta, dn, dc, mags, entry, slope)
    dk = dr + dz + 4.0 * U * k
    do = drho + dr + dh + 4.0 * U * o
    cos1, cos2 = hl / o, z / k
    rc1 = (dh + do) / hl
    rc2 = (dz + dk) / z
    tau = 4.0 * eta * math.sqrt(1.0 - eta * eta) / ((1.0 + eta) * (1.0 + eta))
    eps = kt * (dk + 4.0 * U * x) + kt_out * do + 16.0 * U * (kt * (x + k) + kt_out * o)
    eps += 1.001 * ((cos1 * cos1 * rc1 / (eta * eta) + (2.0 / (eta * eta) + 1.0) * U) / (cos2 * cos2) + U) \
        + 16.0 * U / (tau * cos2)  # Fresnel's T
    eps += (drho + dr) / s + do / hl + drho / rho  # sin t1 / rho = s / (o rho)
    eps += rc2  # cos t2
    eps += dh / hl + 2.0 * rc1 + dz / z + rc1 + 3.0 * rc2  # Q = A + B, A = hl / cos1^2, B = z cos1 / (eta cos2^3)
    eps += ph * ((dr + dz) / k + 2.0 * (drho + 16.0 * U * (x + lh)) / rho + da)  # the phase
    eps += 32.0 * U
    return 2.0 * eps, cosine_error(x, k, s, hl, ll, rho, eta, dn, dc, mags, entry, slope)
