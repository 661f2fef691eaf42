"""Closed-form optical depth of an exponential height fog ("Sampling Analytic Participating Media",
eq. 34) against the numerically integrated one users write (the midpoint rule with n steps), at
equal error; then the atmosphere (scenes/sunrise.toml, its layers table: Rayleigh, Mie, ozone):
raymarch with closed-form against marched transmittances at equal error, and Monte Carlo free-path
sampling by the closed-form inverse against free-path sampling on a ray-marched optical depth at
equal time.

    python benchmarks/height_fog.py            # both parts
    python benchmarks/height_fog.py atmosphere # the atmosphere only

Random segments (heights -2 ... 10 scale heights, all directions, lengths up to 20 scale heights)
of the fog rho = exp(-h/H): the closed form (`fog.column`, verified against mpmath to ~1e-14 in
tests/test_optical_depth.py) is the reference. For each n: the median and maximum relative error
of the midpoint rule and its time per segment; then the n and the time ratio at which the rule
first reaches a maximum error of 1e-3 and 1e-6.
"""
import math
import sys
import time
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from raytrace.media import atmosphere as atmo  # noqa: E402
from raytrace.media.fog import EXPONENTIAL, column, column_distance  # noqa: E402
from raytrace.methods.geometry import HO, MU, fog_inscatter  # noqa: E402
from raytrace.methods.montecarlo import _atm_estimate as _MC_ESTIMATE, _fog_estimate as _FOG_ESTIMATE  # noqa: E402
from raytrace.rng import uniform  # noqa: E402

H = 1.0
N_SEGMENTS = 200_000


@numba.njit(nogil=True)
def closed(h, mu, length, out):
    for i in range(h.shape[0]):
        out[i] = column(h[i], mu[i], 0.0, length[i], H, EXPONENTIAL)


@numba.njit(nogil=True)
def midpoint(h, mu, length, n, out):
    for i in range(h.shape[0]):
        dt = length[i] / n
        acc = 0.0
        for k in range(n):
            acc += math.exp(-(h[i] + mu[i] * (k + 0.5) * dt) / H)
        out[i] = acc * dt


def timed(fn, *args, per=N_SEGMENTS):
    """Seconds per segment of fn(*args) over `per` segments: the best of 3 runs after a compiling one."""
    fn(*args)  # compile
    best = math.inf
    for _ in range(3):
        start = time.perf_counter()
        fn(*args)
        best = min(best, time.perf_counter() - start)
    return best / per


def note_reached(reached, rel, n, ratio):
    """Record in `reached` the first step count n whose max relative error meets 1e-3 and 1e-6."""
    for target in (1e-3, 1e-6):
        if target not in reached and rel.max() <= target:
            reached[target] = (n, ratio)


def main():
    rng = np.random.default_rng(4)
    h = rng.uniform(-2.0, 10.0, N_SEGMENTS) * H
    mu = rng.uniform(-1.0, 1.0, N_SEGMENTS)
    length = rng.uniform(0.0, 20.0, N_SEGMENTS) * H
    ref = np.empty(N_SEGMENTS)
    t_closed = timed(closed, h, mu, length, ref)
    print(f"closed form (eq. 34): {t_closed * 1e9:.0f} ns per segment")
    print("| midpoint steps | median rel. error | max rel. error | ns per segment | x closed form |")
    print("|---|---|---|---|---|")
    reached = {}
    out = np.empty(N_SEGMENTS)
    for n in (1, 4, 16, 64, 256, 1024, 4096):
        t = timed(midpoint, h, mu, length, n, out)
        rel = np.abs(out - ref) / ref
        print(f"| {n} | {np.median(rel):.1e} | {rel.max():.1e} | {t * 1e9:.0f} | {t / t_closed:.0f} |")
        note_reached(reached, rel, n, t / t_closed)
    for target, (n, ratio) in sorted(reached.items(), reverse=True):
        print(f"max error {target:g}: midpoint needs {n} steps, {ratio:.0f} x the closed form's time")


# --- the atmosphere ---------------------------------------------------------------------------------


def _sunrise(width, height):
    from raytrace.scene.format import load_scene

    scene = load_scene(Path(__file__).resolve().parents[1] / "scenes" / "sunrise.toml")
    scene.camera.width, scene.camera.height = width, height
    return scene


def raymarch_at_equal_error():
    """raymarch on the sunrise (64 x 40, one thread): closed-form (Chapman) against marched optical
    depths (the camera's summed along the march, the light's by a march of as many steps), error
    against quadrature (rtol 1e-9); then the time ratio at which each first reaches a max error."""
    from raytrace.options import RenderOptions
    from raytrace.rendering.renderer import prepare, render

    prep = prepare(_sunrise(64, 40))
    one = RenderOptions(threads=1)
    ref = render(prep, "quadrature", {"rtol": 1e-9}, one).image
    print("\nraymarch on scenes/sunrise.toml, 64 x 40, one thread, error against quadrature:")
    print("| steps | transmittance | median rel. error | max rel. error | seconds |")
    print("|---|---|---|---|---|")
    best = {}
    for steps in (4, 16, 64, 256):
        for mode in ("closed", "marched"):
            render(prep, "raymarch", {"steps": steps, "transmittance": mode}, one)  # compile, warm
            runs = [render(prep, "raymarch", {"steps": steps, "transmittance": mode}, one) for _ in range(2)]
            sec = min(r.seconds for r in runs)
            rel = np.abs(runs[0].image - ref) / ref
            print(f"| {steps} | {mode} | {np.median(rel):.1e} | {rel.max():.1e} | {sec:.2f} |")
            for stat, err in (("max", rel.max()), ("median", np.median(rel))):
                for target in (1e-2, 1e-3, 1e-4):
                    if err <= target and (mode, stat, target) not in best:
                        best[(mode, stat, target)] = (steps, sec)
    for stat in ("max", "median"):
        for target in (1e-2, 1e-3, 1e-4):
            c, m = best.get(("closed", stat, target)), best.get(("marched", stat, target))
            if c and m:
                print(f"{stat} error {target:g}: closed {c[0]} steps {c[1]:.2f} s, marched {m[0]} steps {m[1]:.2f} s: "
                      f"{m[1] / c[1]:.1f} x the time")
            elif c:
                print(f"{stat} error {target:g}: closed {c[0]} steps {c[1]:.2f} s; marched not by 256 steps")


@numba.njit(nogil=True)
def _atm_closed(h, mu, t1, R, out):
    for i in range(h.shape[0]):
        out[i] = atmo.atmosphere_column(h[i], mu[i], 0.0, t1[i], R, 8e3)


@numba.njit(nogil=True)
def _atm_midpoint(h, mu, t1, R, n, out):
    for i in range(h.shape[0]):
        dt = t1[i] / n
        r0 = R + h[i]
        acc = 0.0
        for k in range(n):
            t = (k + 0.5) * dt
            acc += math.exp(-(math.sqrt(r0 * r0 + 2.0 * r0 * mu[i] * t + t * t) - R) / 8e3)
        out[i] = acc * dt


def atmosphere_optical_depth_at_equal_error():
    """The Rayleigh layer's column (Earth, H = 8 km) over random segments from 0 ... 60 km up, all
    directions, to the ground or up to 300 km: the Chapman closed form (chapman.atmosphere_column,
    mpmath-verified) against the midpoint rule, at equal maximum error."""
    rng = np.random.default_rng(11)
    n_seg, R = 20_000, 6360e3
    h = rng.uniform(0.0, 60e3, n_seg)
    mu = rng.uniform(-1.0, 1.0, n_seg)
    tg = np.array([atmo.ground_distance(a, b, R) for a, b in zip(h, mu)])
    t1 = np.minimum(rng.uniform(0.0, 300e3, n_seg), tg)
    ref = np.empty(n_seg)
    t_closed = timed(_atm_closed, h, mu, t1, R, ref, per=n_seg)
    print(f"\natmosphere column (Chapman, eq. 40-48): {t_closed * 1e9:.0f} ns per segment")
    print("| midpoint steps | max rel. error | ns per segment | x closed form |")
    print("|---|---|---|---|")
    out = np.empty(n_seg)
    reached = {}
    for n in (4, 16, 64, 256, 1024, 4096, 16384):
        t = timed(_atm_midpoint, h, mu, t1, R, n, out, per=n_seg)
        rel = np.abs(out - ref) / ref
        print(f"| {n} | {rel.max():.1e} | {t * 1e9:.0f} | {t / t_closed:.1f} |")
        note_reached(reached, rel, n, t / t_closed)
    for target, (n, ratio) in sorted(reached.items(), reverse=True):
        print(f"max error {target:g}: midpoint needs {n} steps, {ratio:.1f} x the closed form's time")


@numba.njit(nogil=True)
def _analytic_freepath(rows, kt, ks, codes, gs, layers, R, top, n, seed, out):
    """Per ray: the variance of one free-path estimate (the sun), by the closed-form inverse."""
    cols = np.empty(layers.shape[0])
    cone = np.zeros(4)
    pieces, buf = np.empty((3, 4)), np.empty(2)
    for s in range(rows.shape[0]):
        mean, var = _MC_ESTIMATE(rows[s], True, 0.0, 1.0, cone, kt, ks, codes, gs, layers, R, top, 1, n, np.uint64(s), 0,
                                 seed, cols, pieces, buf)
        out[s, 0], out[s, 1] = mean, var * n


@numba.njit(nogil=True)
def _marched_freepath(rows, kt, ks, codes, gs, layers, R, top, n, steps, seed, out):
    """The same estimator with distances drawn from the optical depth a march of `steps` midpoints
    gives (piecewise-constant extinction, inverted exactly): p(x) = kt_k exp(-tau_M(x)) / N_M, the
    density of what is drawn, so the estimate stays unbiased; f is the exact integrand."""
    cols = np.empty(layers.shape[0])
    cum = np.empty(steps + 1)
    ext = np.empty(steps)
    for s in range(rows.shape[0]):
        a, b = rows[s, atmo.A], rows[s, atmo.B]
        out[s, 0] = out[s, 1] = 0.0
        if not b > a:
            continue
        delta = (b - a) / steps
        cum[0] = 0.0
        for k in range(steps):
            ext[k] = atmo.extinction_at(a + (k + 0.5) * delta, rows[s], kt, layers, R)
            cum[k + 1] = cum[k] + ext[k] * delta
        norm = -math.expm1(-cum[steps])
        acc = acc2 = 0.0
        for j in range(n):
            u = uniform(np.uint64(s), 2 * j + 1, seed)
            target = -math.log1p(-u * norm)
            k = min(max(np.searchsorted(cum, target) - 1, 0), steps - 1)
            x = min(a + k * delta + (target - cum[k]) / ext[k], b)
            p = ext[k] * math.exp(-target) / norm
            est = atmo.inscatter(x, rows[s], True, kt, ks, codes, gs, layers, R, top, cols, -1.0) / p
            acc += est
            acc2 += est * est
        mean = acc / n
        out[s, 0], out[s, 1] = mean, max(acc2 / n - mean * mean, 0.0) * n / (n - 1)


def freepath_variance_at_equal_time(samples=16, steps=(16, 64)):
    """Sunrise rays (48 x 30, sun, blue channel): one free-path estimate's variance per ray, by the
    closed-form inverse and by a ray-marched optical depth, and the time of `samples` estimates per
    ray; the efficiency ratio (var x time) is the variance ratio at equal time."""
    from raytrace.lights import Lights
    from raytrace.shading import planet_hits
    from raytrace.camera import generate_rays

    scene = _sunrise(48, 30)
    atm = scene.medium
    o, d = generate_rays(scene.camera, slice(0, 30), slice(0, 48))
    _, t = planet_hits(scene.medium, o, d, np.full(len(o), np.inf))
    lights = Lights.of(scene.lights)
    rows = np.empty((len(o), atmo.ROW))
    atmo.segment_rows(o, d, t, lights.position, lights.axis, np.zeros(len(o), np.int64), np.ones(len(o), bool),
                      *atm.center, atm.radius, atm.top, rows)
    kt, ks = np.ascontiguousarray(atm.layer_sigma_t[:, 2]), np.ascontiguousarray(atm.layer_sigma_s[:, 2])
    args = (rows, kt, ks, atm.phases, atm.gs, atm.layers, atm.radius, atm.top, samples)
    runs = [("closed-form inverse", _analytic_freepath, ())] + [(f"marched, {m} steps", _marched_freepath, (m,))
                                                                for m in steps]
    outs = _interleaved(runs, args, len(o))
    _print_ratios(f"sunrise rays (48 x 30, the sun, blue), {samples} samples per ray", outs)


@numba.njit(nogil=True)
def _fog_analytic(rows, ell, kt, ks, code, g, H, n, seed, out):
    cone = np.zeros(4)
    for s in range(rows.shape[0]):
        mean, var = _FOG_ESTIMATE(rows[s], True, 0.0, 1.0, ell[s], kt, ks, code, g, cone, H, EXPONENTIAL, 1, n,
                                  np.uint64(s), 0, seed)
        out[s, 0], out[s, 1] = mean, var * n


@numba.njit(nogil=True)
def _fog_marched(rows, ell, kt, ks, code, g, H, n, steps, seed, out):
    """Free-path draws on the fog's ray-marched optical depth (as `_marched_freepath`); rays that
    hit nothing are marched to optical depth 20 (the raymarch default's cut-off)."""
    cum = np.empty(steps + 1)
    ext = np.empty(steps)
    cone = np.zeros(4)
    for s in range(rows.shape[0]):
        row = rows[s]
        out[s, 0] = out[s, 1] = 0.0
        end = ell[s] if ell[s] < math.inf else column_distance(row[HO], row[MU], 0.0, 20.0 / kt, H, EXPONENTIAL)
        if not end < math.inf:
            end = column_distance(row[HO], row[MU], 0.0, 0.999 * column(row[HO], row[MU], 0.0, math.inf, H,
                                                                        EXPONENTIAL), H, EXPONENTIAL)
        delta = end / steps
        cum[0] = 0.0
        for k in range(steps):
            ext[k] = kt * math.exp(-(row[HO] + row[MU] * (k + 0.5) * delta) / H)
            cum[k + 1] = cum[k] + ext[k] * delta
        norm = -math.expm1(-cum[steps])
        acc = acc2 = 0.0
        for j in range(n):
            u = uniform(np.uint64(s), 2 * j + 1, seed)
            target = -math.log1p(-u * norm)
            k = min(max(np.searchsorted(cum, target) - 1, 0), steps - 1)
            x = min(k * delta + (target - cum[k]) / ext[k], end)
            p = ext[k] * math.exp(-target) / norm
            est = fog_inscatter(x, row, 0.0, 1.0, kt, ks, code, g, cone, H, EXPONENTIAL, True) / p
            acc += est
            acc2 += est * est
        mean = acc / n
        out[s, 0], out[s, 1] = mean, max(acc2 / n - mean * mean, 0.0) * n / (n - 1)


def fog_freepath_variance_at_equal_time(samples=16, steps=(16, 64)):
    """The same comparison in scenes/valley_fog.toml (its sun, blue channel, 64 x 36 rays; rays to
    the sky are marched to optical depth 20, or through 99.9 % of a rising ray's finite column, so
    the marched sampler is slightly truncated there)."""
    from raytrace.methods.geometry import fog_rows
    from raytrace.rendering.renderer import prepare
    from raytrace.scene.format import load_scene
    from raytrace.segments import whole_rays
    from raytrace.camera import generate_rays

    scene = load_scene(Path(__file__).resolve().parents[1] / "scenes" / "valley_fog.toml")
    scene.camera.width, scene.camera.height = 64, 36
    prep = prepare(scene)
    o, d = generate_rays(scene.camera, slice(0, 36), slice(0, 64))
    t, _ = prep.accel.first_hit(o, d)
    segs = whole_rays(o, d, t, np.zeros(len(o), np.uint64), 1)
    rows, _ = fog_rows(segs, scene.medium, prep.lights)
    med = scene.medium
    args = (rows, t, float(med.sigma_t[2]), float(med.sigma_s[2]), med.phase, med.g, med.scale_height, samples)
    runs = [("closed-form inverse", _fog_analytic, ())] + [(f"marched, {m} steps", _fog_marched, (m,)) for m in steps]
    outs = _interleaved(runs, args, len(o))
    _print_ratios(f"valley_fog rays (64 x 36, the sun, blue), {samples} samples per ray", outs)


def _interleaved(runs, args, n_rays, rounds=7):
    """{name: (per-ray (mean, variance of one estimate), median seconds)} of the samplers `runs`
    = [(name, kernel, extra args)], timed in interleaved rounds (the machine's load drifts)."""
    outs = {name: np.empty((n_rays, 2)) for name, _, _ in runs}
    for name, fn, extra in runs:
        fn(*args, *extra, np.uint64(1), outs[name])  # compile
    times = {name: [] for name, _, _ in runs}
    for _ in range(rounds):
        for name, fn, extra in runs:
            start = time.perf_counter()
            fn(*args, *extra, np.uint64(1), outs[name])
            times[name].append(time.perf_counter() - start)
    return {name: (outs[name], float(np.median(times[name]))) for name, _, _ in runs}


def _print_ratios(title, outs):
    ref_out, ref_t = outs["closed-form inverse"]
    lit = ref_out[:, 1] > 0.0
    print(f"\nfree-path sampling on {title}, one thread, median of 7 interleaved rounds:")
    print("| sampler | seconds | mean variance of one estimate / closed-form's | variance ratio at equal time |")
    print("|---|---|---|---|")
    for name, (out, sec) in outs.items():
        ratio = np.mean(out[lit, 1] / ref_out[lit, 1])
        print(f"| {name} | {sec:.3f} | {ratio:.3f} | {ratio * sec / ref_t:.2f} |")
    agree = max(abs(np.mean(out[lit, 0]) / np.mean(ref_out[lit, 0]) - 1) for out, _ in outs.values())
    print(f"(pixel means agree to {agree:.1e})")


if __name__ == "__main__":
    if sys.argv[1:] != ["atmosphere"]:
        main()
    atmosphere_optical_depth_at_equal_error()
    raymarch_at_equal_error()
    freepath_variance_at_equal_time()
    fog_freepath_variance_at_equal_time()
