"""The air-light kernel alone, per segment, on the segments of a whole render (`analytic`).

    RAYTRACE_ASSETS=../shared/scenes python benchmarks/airlight_kernel.py [--scene conference --spp 1]

Renders the bundled scene once per phase function (its medium's phase function replaced, `analytic`
at its default precision, unshadowed, one thread), keeps the segments that `analytic` was given,
then times `analytic.evaluate_deferred` alone on them: single-thread CPU time, least of `--rounds`
rounds, per segment. Also prints the mean length of the coefficient block the segments used (terms
of the moment recurrence per segment) and the share of segments on each path.
"""
import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import raytrace  # noqa: E402
from raytrace.jit import njit  # noqa: E402
from raytrace.methods import analytic  # noqa: E402
from raytrace.methods.geometry import v_of  # noqa: E402
from raytrace.media.phase import HG, ISOTROPIC, RAYLEIGH  # noqa: E402
from raytrace.rendering.renderer import prepare  # noqa: E402

PHASES = [("isotropic", ISOTROPIC, 0.0), ("rayleigh", RAYLEIGH, 0.0), ("hg g=0.5", HG, 0.5),
          ("hg g=-0.5", HG, -0.5), ("hg g=0.9", HG, 0.9), ("hg g=0.95", HG, 0.95)]


def capture(prep, code, g, spp):
    """The argument tuples of every `evaluate_deferred` call of one render."""
    calls = []
    inner = analytic.evaluate_deferred

    def spy(*args, **kw):
        calls.append((tuple(np.copy(a) if isinstance(a, np.ndarray) else a for a in args), dict(kw)))
        return inner(*args, **kw)

    medium = dataclasses.replace(prep.scene.medium, phase=code, g=g)
    p = dataclasses.replace(prep, scene=dataclasses.replace(prep.scene, medium=medium))
    analytic.evaluate_deferred = spy
    try:
        raytrace.render(prepared=p, method="analytic", threads=1, volumetric_shadows=False, spp=spp)
    finally:
        analytic.evaluate_deferred = inner
    return calls


@njit
def _terms(xh, h, ell, kt, coeffs):
    """Total length of the coefficient blocks (`analytic._block_at`) of these segments."""
    total = 0
    for s in range(xh.shape[0]):
        if not (ell[s] > 0.0) or not (kt * h[s] > 1e-200):
            continue
        vb = v_of(ell[s] - xh[s], h[s]) if ell[s] < np.inf else np.inf
        total += analytic._block_at(coeffs, v_of(-xh[s], h[s]), vb, kt * h[s], analytic.B_HMAX)[1] - analytic.B_C
    return total


def terms(calls):
    """Mean terms of the moment recurrence per segment (the length of its block)."""
    total = sum(_terms(a[0], a[1], a[3], a[4], a[12]) for a, _ in calls)
    return total / sum(len(a[0]) for a, _ in calls)


def run(calls):
    stats = analytic.new_stats()
    for args, kw in calls:
        args = list(args)
        args[14] = np.empty_like(args[14])
        args[15] = np.empty_like(args[15])
        args[16] = stats
        analytic.evaluate_deferred(*args, **kw)
    return stats


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="conference")
    ap.add_argument("--spp", type=int, default=1)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--phases", default=",".join(label for label, _, _ in PHASES),
                    help="comma-separated phase functions of the table (default: all)")
    args = ap.parse_args()
    prep = prepare(raytrace.load(args.scene))
    print("| phase | segments | ns per segment | terms per segment | series | stable | fallback |")
    print("|---|---|---|---|---|---|---|")
    for label, code, g in (p for p in PHASES if p[0] in args.phases.split(",")):
        calls = capture(prep, code, g, args.spp)
        n = sum(len(a[0]) for a, _ in calls)
        stats = run(calls)
        best = np.inf
        for _ in range(args.rounds):
            t0 = time.process_time()
            run(calls)
            best = min(best, time.process_time() - t0)
        s = analytic.summarize_stats(stats)
        print(f"| {label} | {n} | {best / n * 1e9:.0f} | {terms(calls):.1f} | {s['series_fraction']:.3f} | "
              f"{s['stable_fraction']:.3f} | {s['fallback_fraction']:.4f} |", flush=True)


if __name__ == "__main__":
    main()
