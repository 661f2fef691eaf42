"""The rule by which a method integrates the single scattering of media inside shapes (interiors/), a record
that the method supplies (methods/ `Interiors.rule`) and the shared one-dimensional drivers read
(media/slab.py, media/sphere_refraction.py, shadows/through_others.py, interiors/): adaptive quadrature
(QUAD, the reference, bounded where its kernel knows a bound), the midpoint rule (MARCH: ray marching) or
free-path sampling (SAMPLE: Monte Carlo, with the variance of its mean).

One record type serves every rule, its `kind` read inside the drivers: numba compiles each driver once
for all of them (a record type per rule would compile each driver once per rule a process meets). The
method chooses the values; the drivers never ask which method runs.
"""
import math
from typing import NamedTuple

from ..jit import njit
from ..rng import uniform
from .integrand import integrand
from .march import march

QUAD, MARCH, SAMPLE = 0, 1, 2
UNDERFLOW = 745.0  # the optical depth beyond which exp(-tau) underflows to 0 in doubles


class InsideRule(NamedTuple):
    """`kind` (QUAD, MARCH or SAMPLE); `rtol`, the relative accuracy of QUAD (of the other rules: of the
    adaptive quadrature where they have no points of their own, interiors/rows.py `through_airlight`);
    `steps`, MARCH's cells or SAMPLE's samples per segment and channel (QUAD: 1); `tau_max`, the optical
    depth at which a segment is cut (MARCH's parameter; UNDERFLOW for the others)."""
    kind: int
    rtol: float
    steps: int
    tau_max: float


def inside_rule(kind: int, rtol: float, steps: int = 1, tau_max: float = UNDERFLOW) -> InsideRule:
    """The record with the field types every kernel is compiled for (int64, float64, int64, float64)."""
    return InsideRule(int(kind), float(rtol), int(steps), float(tau_max))


@njit
def cut_length(rule, ell, kt):
    """The part [0, length] of a segment of length ell that a MARCH or SAMPLE rule integrates: cut where its
    optical depth kt x reaches the rule's tau_max."""
    return min(ell, rule.tau_max / kt)


@njit
def march_or_sample(rec, rule, length, kt, key, dim0, seed):
    """(value, variance of the mean) of an inside segment [0, length] of the integrand record `rec`: MARCH,
    the midpoint rule with `rule.steps` cells (variance 0); SAMPLE, the mean of `rule.steps` free-path
    samples x = -ln(1 - u (1 - e^{-kt length})) / kt, u from the ray's key at dimensions dim0 + j."""
    steps = rule.steps
    if rule.kind == MARCH:
        return march(rec, 0.0, steps, length / steps, 0.5), 0.0
    mass = -math.expm1(-kt * length) / kt  # ∫ exp(-kt x) dx over the segment
    acc = acc2 = 0.0
    for j in range(steps):
        u = uniform(key, dim0 + j, seed)
        x = -math.log1p(-u * kt * mass) / kt
        f = integrand(x, rec) * mass * math.exp(kt * x)
        acc += f
        acc2 += f * f
    mean = acc / steps
    return mean, max(acc2 / steps - mean * mean, 0.0) / max(steps - 1, 1)
