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
* Height fog (seed 004): the same rule on ks rho(x) Phi F T_cam(x) T_light(x) / d^2 (the sun: no
  1/d^2, T to infinity toward it), both transmittances the closed-form optical depth
  (geometry.fog_inscatter); rays that hit nothing stop at optical depth tau_max, or where a rising
  ray has all but e^{-tau_max} of its finite column behind it.
* Atmosphere (media/atmosphere.py): the same rule over the part of the segment inside the air,
  per channel, on the layers' summed in-scattering with closed-form (Chapman) transmittances; or,
  with ``transmittance = "marched"``, the naive baseline: the camera's optical depth summed step by
  step along the march and the light's by a march of ``steps`` midpoints toward it (the ground
  still blocks exactly), as shaders without a closed form do.
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from ..rng import uniform
from . import AREA_LIGHTS, INSIDE_RTOL, LIGHTS, ErrorLaw, Interiors, Method, Param, Supports, by_kind
from .geometry import (HO, MU, AtmosphereInX, Eq4, FogInX, atmosphere_channels, atmosphere_row, by_channel, cone_row,
                       eq4_integrand, fog_rows, segment_geometry, spot_factor)
from ..errors import UserError
from ..media import atmosphere as atmo
from ..media import Atmosphere, HeightFog, Homogeneous
from ..media.fog import column, column_distance
from ..media.march import coarse_steps, march, march_error
from ..media.inside_rule import MARCH

MAX_STEPS = 1 << 20
DIM_JITTER = 0x524D  # rng dimension of the per-ray jitter ("RM"), distinct from other methods' dims

# stats slots
EVALS, SAMPLES, CAPPED = 0, 1, 2


@njit
def airlight_one(xh, h, ell, kt, ks, code, g, cone, steps, step, tau_max, xi, stats):
    """Ray-marched air-light of the segment [0, ell] (ell may be inf), one light, one channel.

    steps: sample count when step <= 0; step: step length in scene units (> 0 overrides steps);
    tau_max: optical depth of the cut-off for ell = inf; xi in [0, 1): sample offset in each cell
    (0.5 = midpoint); cone: the segment's cone row (geometry.py).
    """
    if ks == 0.0 or not ell > 0.0:
        return 0.0
    stats[EVALS] += 1.0
    n, delta, capped = _count(ell, kt, steps, step, tau_max)
    stats[CAPPED] += capped
    stats[SAMPLES] += n
    return march(Eq4(xh, h, kt, ks, code, g, cone_row(cone)), 0.0, n, delta, xi)


@njit
def evaluate_segments(xh, h, ell, keys, seed, kt, ks, code, g, cone, steps, step, tau_max, jitter, out, stats):
    """Unit-intensity air-light of every segment for one channel's coefficients."""
    for s in range(xh.shape[0]):
        xi = uniform(keys[s], DIM_JITTER, seed) if jitter else 0.5
        out[s] = airlight_one(xh[s], h[s], ell[s], kt, ks, code, g, cone[s], steps, step, tau_max, xi, stats)


@njit
def estimate_segments(xh, h, ell, keys, seed, kt, ks, code, g, cone, steps, step, tau_max, jitter, fine, est):
    """The error estimate of each segment's march `fine` (`evaluate_segments`) from the march over
    the same cells in media/march.py's `coarse_steps` (`march_error`); a kernel of its own, since a
    second march beside the first in one kernel slows both loops 2x."""
    for s in range(xh.shape[0]):
        est[s] = 0.0
        if ks == 0.0 or not ell[s] > 0.0:
            continue
        xi = uniform(keys[s], DIM_JITTER, seed) if jitter else 0.5
        n, delta, _ = _count(ell[s], kt, steps, step, tau_max)
        m, coarse = coarse_steps(n, delta)
        est[s] = march_error(fine[s], march(Eq4(xh[s], h[s], kt, ks, code, g, cone_row(cone[s])), 0.0, m, coarse, xi), n)


MAX_END = 1e150  # the farthest march: squared distances to its points stay finite


@njit
def _count(ell, kt, steps, step, tau_max):
    """(sample count, step length, 1.0 if the count was capped at MAX_STEPS) of the march of one
    segment and channel. Rays that hit nothing end at tau_max / kt, at most MAX_END (kt = 0 implies
    ks = 0: an empty march)."""
    end = ell
    if end == math.inf:  # MAX_END: tau_max / kt overflowed to inf for kt below ~1e-307 (points at inf: NaN)
        end = min(tau_max / kt, MAX_END) if kt > 0.0 else 0.0
    if not step > 0.0:
        n = max(1, steps)
        return n, end / n, 0.0
    m = math.ceil(end / step)
    if m > MAX_STEPS:
        return MAX_STEPS, end / MAX_STEPS, 1.0
    n = max(1, int(m))
    return n, end / n, 0.0


@njit
def counts(ell, kt, steps, step, tau_max):
    """The largest sample count over the channels of every segment (S,)."""
    out = np.ones(ell.shape[0], dtype=np.int64)
    for s in range(ell.shape[0]):
        for c in range(3):
            out[s] = max(out[s], _count(ell[s], kt[c], steps, step, tau_max)[0])
    return out


@njit
def sample_points(origins, dirs, xh, h, ell, cone, keys, seed, intensity, kt, ks, code, g, steps, step, tau_max,
                  jitter, pos, weight):
    """The march's samples as points for volumetric shadows: pos[s, k, 0, c] is sample k of segment s
    for channel c, weight[s, k, 0, c] = n_max * Delta * I * f(x_k), so that the mean over k of the
    weights is the marched air-light (samples beyond a segment's own count weigh 0)."""
    n_max = pos.shape[1]
    for s in range(origins.shape[0]):
        xi = uniform(keys[s], DIM_JITTER, seed) if jitter else 0.5
        for c in range(3):
            if ks[c] == 0.0 or not ell[s] > 0.0:
                continue
            n, delta, _ = _count(ell[s], kt[c], steps, step, tau_max)
            for k in range(n):
                x = (k + xi) * delta
                for a in range(3):
                    pos[s, k, 0, c, a] = origins[s, a] + x * dirs[s, a]
                weight[s, k, 0, c] = n_max * delta * intensity[s, c] * eq4_integrand(x, xh[s], h[s], kt[c], ks[c],
                                                                                     code, g, cone[s])


def _march(params):
    return int(params["steps"]), float(params["step"]), float(params["tau_max"])


def _point_count(segs, medium, params):
    return counts(segs.length, np.asarray(medium.sigma_t, float), *_march(params))


def _points(segs, medium, lights, params):
    kt = np.asarray(medium.sigma_t, float)
    n = int(_point_count(segs, medium, params).max(initial=1))
    pos = np.zeros((len(segs), n, 1, 3, 3))
    weight = np.zeros((len(segs), n, 1, 3))
    xh, h, _, cone = segment_geometry(segs, lights)
    sample_points(segs.origins, segs.dirs, xh, h, segs.length, cone, np.ascontiguousarray(segs.keys, dtype=np.uint64),
                  int(segs.seed), lights.intensity[segs.light], kt, np.asarray(medium.sigma_s, float), medium.phase,
                  medium.g, *_march(params), bool(params["jitter"]), pos, weight)
    return pos, weight


def _airlight(segs, medium, lights, params):
    return by_kind(_BY_KIND, medium)(segs, medium, lights, params)


def _atmosphere(segs, atm, lights, params):
    stats = np.zeros(3)
    keys = np.ascontiguousarray(segs.keys, dtype=np.uint64)

    def evaluate(rows, directional, xh, h, cone, kt, ks):
        out = np.empty_like(xh)
        atmosphere_segments(rows, directional, xh, h, cone, keys, int(segs.seed), kt, ks, atm.phases, atm.gs,
                            atm.layers, float(atm.radius), float(atm.top), int(params["steps"]), float(params["step"]),
                            params["transmittance"] == "marched", bool(params["jitter"]), out, stats)
        return out

    return atmosphere_channels(segs, atm, lights, evaluate), stats


def _fog(segs, medium, lights, params):
    stats = np.zeros(3)
    keys = np.ascontiguousarray(segs.keys, dtype=np.uint64)
    rows, directional = fog_rows(segs, medium, lights)

    def evaluate(xh, h, da, ell, kt, ks, cone):
        out = np.empty_like(xh)
        fog_segments(rows, directional, xh, h, ell, keys, int(segs.seed), kt, ks, medium.phase, medium.g, cone,
                     medium.scale_height, medium.profile, *_march(params), bool(params["jitter"]), out, stats)
        return out

    return by_channel(segs, medium, lights, evaluate), stats


def _homogeneous(segs, medium, lights, params):
    stats = np.zeros(3)
    keys = np.ascontiguousarray(segs.keys, dtype=np.uint64)

    def evaluate(xh, h, da, ell, kt, ks, cone):
        out, est = np.empty_like(xh), np.empty_like(xh)
        args = (xh, h, ell, keys, int(segs.seed), kt, ks, medium.phase, medium.g, cone, *_march(params),
                bool(params["jitter"]))
        evaluate_segments(*args, out, stats)
        estimate_segments(*args, out, est)
        return out, est

    radiance, est = by_channel(segs, medium, lights, evaluate, estimated=True)
    return radiance, stats, est


def _check(medium, params):
    if params["transmittance"] == "marched" and not isinstance(medium, Atmosphere):
        raise UserError(f"method raymarch: --transmittance marched is the atmosphere's naive baseline; in "
                        f"{medium.type_name} media use --transmittance closed (the default)")


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
        "tau_max": Param(20.0, float, "optical depth at which rays that hit nothing stop, e.g. 20", 0.0, 700.0, True),
        "shadow_test": Param("intervals", str, "with volumetric shadows: integrate the lit intervals (exact between "
                             "shadow boundaries) or samples (a shadow ray per medium sample, the classic)",
                             choices=("intervals", "samples")),
        "transmittance": Param("closed", str, "in an atmosphere: closed-form (Chapman) optical depths, or marched "
                               "(the naive baseline: summed along the march, and a march of `steps` toward the light)",
                               choices=("closed", "marched")),
    },
    airlight=_airlight,
    check=_check,
    # midpoint rule: error O(Delta^2); 4096 steps over the box room's few metres, lights >= 0.1 from rays
    error_law=ErrorLaw({"steps": 4096}, "median", 5e-8),  # measured worst 1.8e-8 (hg_backward_light_behind_camera)
    stats_size=3,
    summarize=_summarize,
    points=_points,
    point_count=_point_count,
    supports=Supports(lights=LIGHTS + AREA_LIGHTS, media=(Homogeneous, HeightFog, Atmosphere),
                      interiors=Interiors(MARCH, exact_paths=True, lights=LIGHTS + AREA_LIGHTS,
                                          refracted=LIGHTS + AREA_LIGHTS, fixed=("step", "jitter"),
                                          settings=lambda params: (INSIDE_RTOL, params["steps"], params["tau_max"]),
                                          through="points"),
                      shadow_tests=("intervals", "samples")),
)
_BY_KIND = {Homogeneous: _homogeneous, HeightFog: _fog, Atmosphere: _atmosphere}


@njit
def _fog_end(row, kt, H, profile, tau_max):
    """Where a ray that hits nothing stops in a height fog: at optical depth tau_max, or, on a rising
    ray whose whole column holds less, where all but e^{-tau_max} of that column lies behind."""
    target = tau_max / kt
    whole = column(row[HO], row[MU], 0.0, math.inf, H, profile)
    if whole < math.inf:
        target = min(target, -whole * math.expm1(-tau_max))
    return column_distance(row[HO], row[MU], 0.0, target, H, profile)


@njit
def fog_segments(rows, directional, xh, h, ell, keys, seed, kt, ks, code, g, cone, H, profile, steps, step, tau_max,
                 jitter, out, stats):
    """Ray-marched unit-intensity air-light of every height-fog segment for one channel: the
    midpoint (or jittered) rule on `fog_inscatter`, whose transmittances are closed form."""
    for s in range(xh.shape[0]):
        out[s] = 0.0
        if ks == 0.0 or not ell[s] > 0.0:
            continue
        xi = uniform(keys[s], DIM_JITTER, seed) if jitter else 0.5
        end = ell[s] if ell[s] < math.inf else _fog_end(rows[s], kt, H, profile, tau_max)
        stats[EVALS] += 1.0
        n, delta, capped = _count(end, kt, steps, step, tau_max)
        stats[CAPPED] += capped
        stats[SAMPLES] += n
        rec = FogInX(rows[s], xh[s], h[s], kt, ks, code, g, cone_row(cone[s]), H, profile, directional[s])
        out[s] = march(rec, 0.0, n, delta, xi)


@njit
def _marched_depth(px, py, pz, lx, ly, lz, d, kt, Hs, R, top, steps):
    """The naive optical depth toward the light: the midpoint rule with `steps` steps from the point
    c + p along l to the light at distance d or, for the sun (d = inf), out of the top sphere."""
    r = math.sqrt(px * px + py * py + pz * pz)
    h, mu = max(r - R, 0.0), min(max((px * lx + py * ly + pz * lz) / r, -1.0), 1.0)
    if atmo.ground_distance(h, mu, R) < d:
        return math.inf
    end = min(d, atmo.shell(h, mu, R, top)[1])
    if not end > 0.0:
        return 0.0
    delta = end / steps
    tau = 0.0
    for k in range(steps):
        t = (k + 0.5) * delta
        qx, qy, qz = px + t * lx, py + t * ly, pz + t * lz
        tau += atmo.density_sum(max(math.sqrt(qx * qx + qy * qy + qz * qz) - R, 0.0), Hs, kt)
    return tau * delta


@njit
def _marched_airlight(row, directional, xh, h, cone, kt, ks, codes, gs, Hs, R, top, steps, a, n, delta, xi):
    """The naive baseline's march over the cells of [A, B]: `atmosphere.scattering` with the camera's
    optical depth summed cell by cell and the light's by `_marched_depth`."""
    acc = 0.0
    tau_cam = 0.0  # the optical depth of the cells before this one
    for k in range(n):
        x = a + (k + xi) * delta
        hx, px, py, pz, lx, ly, lz, d, cos, _ = atmo.light_frame(x, row, directional, R)
        ext = atmo.density_sum(hx, Hs, kt)
        tau_l = _marched_depth(px, py, pz, lx, ly, lz, d, kt, Hs, R, top, steps) if d > 0.0 else math.inf
        f = atmo.scattering(hx, cos, ks, codes, gs, Hs) * math.exp(-tau_l - tau_cam - ext * xi * delta)
        tau_cam += ext * delta
        if not directional:
            dx = x - xh
            d2 = max(h * h + dx * dx, 1e-250)
            f *= spot_factor(dx, math.sqrt(d2), h, cone) / d2
        acc += f
    return acc * delta


@njit
def atmosphere_segments(rows, directional, xh, h, cone, keys, seed, kt, ks, codes, gs, Hs, R, top, steps, step,
                        marched, jitter, out, stats):
    """Ray-marched unit-intensity air-light of every atmosphere segment for one channel's layers,
    over the part [A, B] of the segment inside the air: the midpoint (or jittered) rule on
    `atmosphere.inscatter` (closed-form transmittances), or with `marched` on the same integrand
    with both optical depths summed numerically (`_marched_airlight`)."""
    cols = np.empty(Hs.shape[0])
    for s in range(xh.shape[0]):
        out[s] = 0.0
        a, b = rows[s, atmo.A], rows[s, atmo.B]
        if not b > a:
            continue
        xi = uniform(keys[s], DIM_JITTER, seed) if jitter else 0.5
        stats[EVALS] += 1.0
        n, delta, capped = _count(b - a, 1.0, steps, step, 1.0)
        stats[CAPPED] += capped
        stats[SAMPLES] += n
        if marched:
            out[s] = _marched_airlight(rows[s], directional[s], xh[s], h[s], cone[s], kt, ks, codes, gs, Hs, R, top,
                                       steps, a, n, delta, xi)
        else:
            rec = AtmosphereInX(atmosphere_row(rows[s]), directional[s], xh[s], h[s], cone_row(cone[s]), kt, ks, codes,
                                gs, Hs, R, top, cols)
            out[s] = march(rec, a, n, delta, xi)
