"""`raymarch`: fixed-step ray marching of the air-light, midpoint or jittered (METHODS.md §1, §2, §9.1).

The comparison integrator of Pegoraro & Parker 2009 (PP09, Table 1): the air-light integrand of
eq. 4,

    f(x) = ks exp(-kt (x + d(x))) Phi_c(-(x - x_h) / d(x)) / d(x)^2,      d(x) = sqrt(h^2 + (x - x_h)^2),

(unit light intensity; x + d is the whole optical path light -> x -> camera, so nothing overflows
for lights far behind the camera) is summed at M equally spaced samples of the segment [0, end]:

    Lm ~ Delta * sum_k f((k + xi) Delta),      Delta = end / M.

* ``jitter = false``: midpoint rule, xi = 1/2 (error O(Delta^2) for a smooth integrand; the
  integrand peaks like 1/h^2 at the foot point, so the constant explodes for lights close to the
  ray -- PP09's "visible undersampling near lights").
* ``jitter = true``: one xi ~ U[0, 1) per ray, ``uniform(key, DIM_JITTER, seed)`` from raytrace.rng,
  shared by every light and channel of that ray (PP09 after [ET08]: trades aliasing for noise).
  The estimate is then unbiased for the integral over [0, end].
* ``step > 0`` (scene units) fixes the step length instead of the count: M = ceil(end / step)
  (at least 1), and Delta = end / M <= step, so the last sample cell is never partial.
  M is capped at MAX_STEPS (counted in the stats).
* Rays that hit nothing (ell = inf) march to the optical-depth cut-off end = tau_max / kt of each
  channel (the neglected tail is O(exp(-tau_max))). A channel with kt = 0 has ks = 0 (kt >= ks)
  and returns 0 before that.
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from ..rng import uniform
from . import Method, Param
from .geometry import by_channel, ray_light_table
from .phase import phase_value

MAX_STEPS = 1 << 20
DIM_JITTER = 0x524D  # rng dimension of the per-ray jitter ("RM"), distinct from other methods' dims

# stats slots
EVALS, SAMPLES, CAPPED = 0, 1, 2


@njit
def integrand(x, xh, h, kt, ks, code, g):
    """f(x) of eq. 4 for a unit-intensity light (x_h, h)."""
    dx = x - xh
    d2 = max(h * h + dx * dx, 1e-250)  # h is >= 1e-300: keep 1/d^2 finite when h*h underflows
    d = math.sqrt(d2)
    return ks * math.exp(-kt * (x + d)) * phase_value(code, g, -dx / d) / d2


@njit
def airlight_one(xh, h, ell, kt, ks, code, g, steps, step, tau_max, xi, stats):
    """Ray-marched air-light of the segment [0, ell] (ell may be inf), one light, one channel.

    steps: sample count when step <= 0; step: step length in scene units (> 0 overrides steps);
    tau_max: optical depth of the cut-off for ell = inf; xi in [0, 1): sample offset in each cell
    (0.5 = midpoint).
    """
    if ks == 0.0 or not ell > 0.0:
        return 0.0
    stats[EVALS] += 1.0
    n, delta, capped = _count(ell, kt, steps, step, tau_max)
    stats[CAPPED] += capped
    stats[SAMPLES] += n
    acc = 0.0
    for k in range(n):
        acc += integrand((k + xi) * delta, xh, h, kt, ks, code, g)
    return acc * delta


@njit
def evaluate_rays(xh, h, tmax, keys, seed, kt, ks, code, g, steps, step, tau_max, jitter, out, stats):
    """Unit-intensity air-light of every (ray, light) for one channel's coefficients."""
    for r in range(xh.shape[0]):
        xi = uniform(keys[r], DIM_JITTER, seed) if jitter else 0.5
        for li in range(xh.shape[1]):
            out[r, li] = airlight_one(xh[r, li], h[r, li], tmax[r], kt, ks, code, g, steps, step, tau_max, xi, stats)


@njit
def _count(ell, kt, steps, step, tau_max):
    """(sample count, step length, 1.0 if the count was capped at MAX_STEPS) of the march of one
    segment and channel. Rays that hit nothing end at tau_max / kt (kt = 0 implies ks = 0: an
    empty march)."""
    end = ell
    if end == math.inf:
        end = tau_max / kt if kt > 0.0 else 0.0
    if not step > 0.0:
        n = max(1, steps)
        return n, end / n, 0.0
    m = math.ceil(end / step)
    if m > MAX_STEPS:
        return MAX_STEPS, end / MAX_STEPS, 1.0
    n = max(1, int(m))
    return n, end / n, 0.0


@njit
def max_count(tmax, kt, steps, step, tau_max):
    m = 1
    for r in range(tmax.shape[0]):
        for c in range(3):
            m = max(m, _count(tmax[r], kt[c], steps, step, tau_max)[0])
    return m


@njit
def sample_points(origins, dirs, xh, h, tmax, keys, seed, lint, kt, ks, code, g, steps, step, tau_max, jitter,
                  pos, weight):
    """The march's samples as points for volumetric shadows: pos[r, l, k, 0, c] is sample k of ray r
    for light l and channel c, weight[r, l, k, 0, c] = n_max * Delta * I * f(x_k), so that the mean
    over k of the weights is the marched air-light (samples beyond a ray's own count weigh 0)."""
    n_max = pos.shape[2]
    for r in range(origins.shape[0]):
        xi = uniform(keys[r], DIM_JITTER, seed) if jitter else 0.5
        for li in range(xh.shape[1]):
            for c in range(3):
                if ks[c] == 0.0 or not tmax[r] > 0.0:
                    continue
                n, delta, _ = _count(tmax[r], kt[c], steps, step, tau_max)
                for k in range(n):
                    x = (k + xi) * delta
                    for a in range(3):
                        pos[r, li, k, 0, c, a] = origins[r, a] + x * dirs[r, a]
                    weight[r, li, k, 0, c] = n_max * delta * lint[li, c] * integrand(x, xh[r, li], h[r, li], kt[c],
                                                                                        ks[c], code, g)


def _points(batch, medium, lpos, lint, params):
    kt = np.asarray(medium.sigma_t, float)
    args = (int(params["steps"]), float(params["step"]), float(params["tau_max"]))
    n = max_count(batch.tmax, kt, *args)
    shape = (len(batch.origins), len(lpos), n, 1, 3)
    pos = np.zeros(shape + (3,))
    weight = np.zeros(shape)
    xh, h, _ = ray_light_table(batch.origins, batch.dirs, lpos, batch.scale)
    sample_points(batch.origins, batch.dirs, xh, h, batch.tmax, np.ascontiguousarray(batch.keys, dtype=np.uint64),
                  int(batch.seed), lint, kt, np.asarray(medium.sigma_s, float), medium.phase, medium.g, *args,
                  bool(params["jitter"]), pos, weight)
    return pos, weight


def _airlight(batch, medium, lpos, lint, params):
    stats = np.zeros(3)
    keys = np.ascontiguousarray(batch.keys, dtype=np.uint64)

    def evaluate(xh, h, da, tmax, kt, ks):
        out = np.empty_like(xh)
        evaluate_rays(xh, h, tmax, keys, int(batch.seed), kt, ks, medium.phase, medium.g, int(params["steps"]),
                      float(params["step"]), float(params["tau_max"]), bool(params["jitter"]), out, stats)
        return out

    return by_channel(batch, medium, lpos, lint, evaluate), stats


def _summarize(stats):
    evals = max(stats[EVALS], 1.0)
    return {"air-light evaluations": int(stats[EVALS]), "mean samples per evaluation": stats[SAMPLES] / evals,
            "evaluations with capped step count": int(stats[CAPPED])}


METHOD = Method(
    name="raymarch",
    summary="ray marching with a fixed step count or length, midpoint or one jitter per ray (PP09's comparison)",
    params={
        "steps": Param(64, int, "samples per ray segment when step = 0, e.g. 64", 1, MAX_STEPS),
        "step": Param(0.0, float, "fixed step length in scene units (0 = use steps), e.g. 0.05", 0.0),
        "jitter": Param(False, bool, "one random offset per ray instead of midpoints (unbiased, noisy)"),
        "volumetric_shadows": Param(False, bool, "shadow rays from every sample point to the light (light shafts)"),
        "tau_max": Param(20.0, float, "optical depth at which rays that hit nothing stop, e.g. 20", 0.0, 700.0, True),
    },
    airlight=_airlight,
    stats_size=3,
    summarize=_summarize,
    points=_points,
)
