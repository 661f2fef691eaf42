"""Area lights' emitter points (LAMBERT rows, F = max(c, 0)) take their own air-light path in `analytic`
(`_lambert_airlight`: one break where the ray crosses the emitter's plane, one lit piece), and a scene
compiles only the paths of the rows it has (`light_rows`: spot lights, emitter points, lights without a
cone). Checked: on random emitter points (rays crossing their planes, passing near them, ending short or
running to infinity; thin and thick media; four phase functions; three precisions) the path agrees with
the spot lights' path (`_spot_airlight`, which integrates the same rows as a spot with falloff bands)
to within 1e-14 relative, with the same met flags and statistics; a first pass without the emitter
points' code (or the point lights') leaves theirs nan; and a fresh process that evaluates emitter points
compiles neither the spot lights' path (nor their bands' cubic, `band_trig`) nor the point lights' batch."""
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from raytrace.lights import CURVES, LAMBERT, NO_CONE
from raytrace.media.phase import HG, ISOTROPIC, RAYLEIGH
from raytrace.methods import analytic as A
from raytrace.methods.geometry import segment_light_table

ROOT = Path(__file__).resolve().parents[1]
EMITTER = [0.0, 1.0, float(LAMBERT)]  # an emitter point's cone (lights/area.py)


def emitter_segments(n, seed, cones=(EMITTER, EMITTER)):
    """(xh, h, da, ell, cone rows) of `n` random segments lit by random emitter points (`cones`: theirs)."""
    rng = np.random.default_rng(seed)
    o = rng.normal(size=(n, 3)) * 2.0
    w = rng.normal(size=(n, 3))
    w /= np.linalg.norm(w, axis=1)[:, None]
    lights = rng.normal(size=(len(cones), 3)) * 2.0
    axis = rng.normal(size=(len(cones), 3))
    axis /= np.linalg.norm(axis, axis=1)[:, None]
    light = rng.integers(0, len(cones), n)
    near = rng.random(n) < 0.1  # rays passing within 1e-9 .. 1e-2 of the point (the near-line limit, short pieces)
    o[near] = lights[light[near]] - 3.0 * w[near] + 10.0 ** rng.uniform(-9, -2, (np.count_nonzero(near), 1)) * \
        np.cross(w[near], axis[light[near]])
    xh, h, da, rows = segment_light_table(o, w, lights, axis, np.array(cones, dtype=float), light, 1.0)
    ell = 10.0 ** rng.uniform(-4, 2, n)
    ell[rng.random(n) < 0.1] = math.inf
    return xh, h, da, ell, rows


def spot_path(segs, kt, ks, phase, precision, coeffs):
    """Each segment by `_spot_airlight` (the cone's general cuts and bands), with the quadrature."""
    xh, h, da, ell, rows = segs
    out, met, stats = np.empty(len(xh)), np.empty(len(xh), dtype=np.bool_), A.new_stats()
    for s in range(len(xh)):
        out[s], met[s] = A._spot_airlight(xh[s], h[s], da[s], ell[s], kt, ks, 1.0, *phase, precision, 1000,
                                          A.ANISO_EXACT, 6, coeffs, tuple(rows[s]), stats, True, True)
    return out, met, stats


@pytest.mark.parametrize("phase", [(HG, 0.9), (HG, 0.5), (ISOTROPIC, 0.0), (RAYLEIGH, 0.0)])
@pytest.mark.parametrize("precision", [1e-3, 1e-6, 1e-9])
def test_emitter_points_as_the_spot_path_gives_them(phase, precision):
    wp = A.working_precision(precision)
    coeffs = A.make_coeffs(*phase, A.ANISO_EXACT, 6, wp)
    segs = emitter_segments(600, 41)
    for kt, ks in ((0.05, 0.04), (2.0, 1.5), (1e-3, 1e-3)):
        ref, ref_met, ref_stats = spot_path(segs, kt, ks, phase, wp, coeffs)
        out, met, stats = np.empty(len(ref)), np.empty(len(ref), dtype=np.bool_), A.new_stats()
        A.evaluate_deferred(*segs[:4], kt, ks, *phase, wp, 1000, A.ANISO_EXACT, 6, coeffs, segs[4], out, met, stats,
                            spots=False, aniso=phase[0] != ISOTROPIC, lamberts=True, points=False)
        assert np.all(np.abs(out - ref) <= 1e-14 * np.abs(ref))
        assert np.array_equal(met, ref_met) and np.array_equal(stats, ref_stats)
        assert np.count_nonzero(ref == 0.0) > 100 and np.count_nonzero(ref > 0.0) > 100  # dark and lit segments
        assert stats[A.ST_BANDS] + stats[A.ST_PIECE_QUAD] > 0  # (HG 0.9 at 1e-9: every band by Gauss-Legendre)
        assert stats[A.ST_NEARLINE] > 0 or precision < 1e-6  # (finer: the closed forms)


def test_light_rows_name_the_paths_a_scene_needs():
    spot = [math.cos(0.5), math.cos(0.4), float(CURVES["smoothstep"])]
    point = [*NO_CONE, float(CURVES["smoothstep"])]
    for cones, flags in (([EMITTER, EMITTER], (False, True, False)), ([point], (False, False, True)),
                         ([spot, EMITTER], (True, True, False)), ([point, spot], (True, False, True))):
        assert A.light_rows(np.array(cones)) == flags


def test_a_pass_without_a_rows_path_leaves_its_segments_nan():
    precision = A.working_precision(1e-6)
    coeffs = A.make_coeffs(HG, 0.5, A.ANISO_EXACT, 6, precision)
    point = [*NO_CONE, float(CURVES["smoothstep"])]
    segs = emitter_segments(200, 42, cones=(EMITTER, point))
    lit = segs[4][:, 3] > -1.0  # an emitter point's (`has_cone`)
    assert 50 < np.count_nonzero(lit) < 150
    for lamberts, points in ((None, True), (True, None)):
        out, met = np.empty(200), np.empty(200, dtype=np.bool_)
        A.evaluate_segments(*segs[:4], 0.3, 0.2, HG, 0.5, precision, 1000, A.ANISO_EXACT, 6, coeffs, segs[4], out, met,
                            A.new_stats(), True, True, True, lamberts, points)
        skipped = lit if lamberts is None else ~lit
        assert np.all(np.isnan(out[skipped])) and not np.any(np.isnan(out[~skipped]))
    ref, ref_met = np.empty(200), np.empty(200, dtype=np.bool_)
    A.evaluate_segments(*segs[:4], 0.3, 0.2, HG, 0.5, precision, 1000, A.ANISO_EXACT, 6, coeffs, segs[4], ref,
                        ref_met, A.new_stats(), True, True, True)  # (as `evaluate_deferred`'s second pass)
    out, met = np.empty(200), np.empty(200, dtype=np.bool_)
    A.evaluate_deferred(*segs[:4], 0.3, 0.2, HG, 0.5, precision, 1000, A.ANISO_EXACT, 6, coeffs, segs[4], out, met,
                        A.new_stats(), spots=False, lamberts=False)  # the emitter points left to the second pass
    assert np.array_equal(out[lit], ref[lit]) and np.array_equal(met, ref_met)
    assert np.all(np.abs(out - ref) <= 1e-13 * np.abs(ref))


FRESH = """
import json, sys
import numpy as np
sys.path.insert(0, sys.argv[1])
from test_lambert_airlight import EMITTER, emitter_segments
from raytrace.media.phase import HG
from raytrace.methods import analytic as A
segs = emitter_segments(50, 43)
precision = A.working_precision(1e-3)
coeffs = A.make_coeffs(HG, 0.5, A.ANISO_EXACT, 6, precision)
out, met = np.empty(50), np.empty(50, dtype=np.bool_)
flags = (True if f else None for f in A.light_rows(np.array([EMITTER])))  # spots, lamberts, points
spots, lamberts, points = flags
A.evaluate_segments(*segs[:4], 0.3, 0.2, HG, 0.5, precision, 1000, A.ANISO_EXACT, 6, coeffs, segs[4], out, met,
                    A.new_stats(), None, spots, True, lamberts, points)  # (`evaluate_deferred`'s first pass)
print(json.dumps({name: len(getattr(A, name).signatures) for name in
                  ("_lambert_airlight", "_spot_airlight", "band_trig", "_pending_series", "_pending_recurrences")}))
"""


def test_a_scene_of_emitter_points_compiles_neither_spots_nor_point_lights(tmp_path):
    env = dict(os.environ, RAYTRACE_CACHE=str(tmp_path / "cache"), PYTHONPATH=str(ROOT))
    proc = subprocess.run([sys.executable, "-c", FRESH, str(ROOT / "tests")], env=env, capture_output=True, text=True,
                          check=True)
    compiled = json.loads(proc.stdout.splitlines()[-1])
    assert compiled == {"_lambert_airlight": 1, "_spot_airlight": 0, "band_trig": 0, "_pending_series": 0,
                        "_pending_recurrences": 0}
