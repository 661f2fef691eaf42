"""What keeps the first render's compile short changes no number.

`analytic` compiles its quadrature fallback only when a segment needs it (`evaluate_deferred`: a
first pass without it leaves those segments nan, a second pass with it does them): on random
segments of point and spot lights, many of which need the fallback (precision 1e-8 in HG 0.9 smoke,
segments short in angle, spot bands whose terms cancel), the values, the met flags and the
statistics are bit for bit those of one pass with the quadrature compiled in. A scene without a
light with a cone compiles the first pass without the spot code too (`evaluate_deferred(...,
spots=False)`), one in an isotropic medium without the anisotropic code (`aniso=False`): the
segments that need them, were there any, go to the second pass bit for bit, and the others agree
with the full kernel's to within 1e-13 relative (the code around them changes, so LLVM may fuse
and reassociate their arithmetic differently: last bits)."""
import math

import numpy as np
import pytest

from raytrace.lights import CURVES, NO_CONE
from raytrace.media.phase import HG, ISOTROPIC
from raytrace.methods import analytic as A
from raytrace.methods.geometry import segment_light_table


def random_segments(n, seed):
    """(xh, h, da, ell, cone rows) of `n` random segments, half of them lit by a random spot light."""
    rng = np.random.default_rng(seed)
    o = rng.normal(size=(n, 3)) * 2.0
    w = rng.normal(size=(n, 3))
    w /= np.linalg.norm(w, axis=1)[:, None]
    lights = rng.normal(size=(2, 3)) * 2.0
    axis = rng.normal(size=(2, 3))
    axis /= np.linalg.norm(axis, axis=1)[:, None]
    cone = np.array([[*NO_CONE, CURVES["smoothstep"]],  # a point light
                     [math.cos(math.radians(35.0)), math.cos(math.radians(20.0)), CURVES["smoothstep"]]])
    light = rng.integers(0, 2, n)
    xh, h, da, rows = segment_light_table(o, w, lights, axis, cone, light, 1.0)
    ell = 10.0 ** rng.uniform(-4, 2, n)
    ell[rng.random(n) < 0.1] = math.inf
    return xh, h, da, ell, rows


def evaluate(fn, segs, kt, ks, precision, coeffs, *extra, phase=(HG, 0.9)):
    xh, h, da, ell, rows = segs
    out, met, stats = np.empty(len(xh)), np.empty(len(xh), dtype=np.bool_), A.new_stats()
    fn(xh, h, da, ell, kt, ks, *phase, precision, 1000, A.ANISO_EXACT, 6, coeffs, rows, out, met, stats, *extra)
    return out, met, stats


def test_the_deferred_fallback_changes_no_bit():
    precision = A.working_precision(1e-8)
    coeffs = A.make_coeffs(HG, 0.9, A.ANISO_EXACT, 6, precision)
    segs = random_segments(400, 37)
    spot = segs[4][:, 2] >= -1.0  # cos_end of a spot's cone
    for kt, ks in ((0.05, 0.04), (2.0, 1.5)):
        first, _, _ = evaluate(A.evaluate_segments, segs, kt, ks, precision, coeffs, None, True, True)
        deferred = np.isnan(first)
        assert 0 < np.sum(deferred & ~spot) and 0 < np.sum(deferred & spot) and np.mean(deferred) < 0.5
        out, met, stats = evaluate(A.evaluate_deferred, segs, kt, ks, precision, coeffs)
        ref_out, ref_met, ref_stats = evaluate(A.evaluate_segments, segs, kt, ks, precision, coeffs, True, True, True)
        assert np.all(np.isfinite(out))
        assert np.array_equal(out, ref_out) and np.array_equal(met, ref_met)
        assert np.array_equal(stats, ref_stats) and stats[A.ST_FALLBACK] > 0


@pytest.mark.parametrize("phase", [(HG, 0.9), (ISOTROPIC, 0.0)])
def test_the_kernels_without_spots_or_anisotropy(phase):
    precision = A.working_precision(1e-8)
    coeffs = A.make_coeffs(*phase, A.ANISO_EXACT, 6, precision)
    segs = random_segments(400, 38)
    spot = segs[4][:, 2] >= -1.0
    for kt, ks in ((0.05, 0.04), (2.0, 1.5)):
        lean = (None, None, None)  # neither spots nor anisotropy: the spot segments, and in HG all, deferred
        first, _, _ = evaluate(A.evaluate_segments, segs, kt, ks, precision, coeffs, *lean, phase=phase)
        assert np.all(np.isnan(first[spot]))
        assert np.mean(np.isnan(first[~spot])) > 0.5 if phase[0] == HG else np.mean(np.isfinite(first[~spot])) > 0.5
        for spots, aniso in ((False, True), (False, False)):
            out, met, stats = evaluate(A.evaluate_deferred, segs, kt, ks, precision, coeffs, spots, aniso, phase=phase)
            ref_out, ref_met, ref_stats = evaluate(A.evaluate_segments, segs, kt, ks, precision, coeffs, True, True,
                                                   True, phase=phase)
            assert np.all(np.isfinite(out)) and np.array_equal(out[spot], ref_out[spot])
            assert np.all(np.abs(out - ref_out) <= 1e-13 * np.abs(ref_out))
            assert np.array_equal(met, ref_met) and np.array_equal(stats, ref_stats)
            assert stats[A.ST_BANDS] + stats[A.ST_PIECE_QUAD] > 0  # spot segments were evaluated
