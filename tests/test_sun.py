"""`sun` (METHODS.md §7): the closed-form table fill against mpmath, O(h^2) bilinear error with
resolution, clamping beyond the table (brighter than the truth), in-bounds indexing for any input,
agreement with the `quadrature` reference at 512^2, the on-disk cache, isotropic-only check."""
import math
import os
from types import SimpleNamespace

import mpmath as mp
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from raytrace.errors import UserError
from raytrace.lights import Light, Lights
from raytrace.media import Homogeneous as Medium
from raytrace.media.phase import HG, ISOTROPIC, RAYLEIGH
from raytrace.methods import quadrature as q, sun
from raytrace.methods.geometry import POINT_ROW
from raytrace.segments import unshadowed_airlight

U_MAX = 10.0


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    old = os.environ.get("RAYTRACE_CACHE")
    os.environ["RAYTRACE_CACHE"] = str(tmp_path_factory.mktemp("cache"))
    try:
        yield sun.load_table(512, U_MAX)
    finally:
        if old is None:
            del os.environ["RAYTRACE_CACHE"]
        else:
            os.environ["RAYTRACE_CACHE"] = old


def ref(xh, h, ell, kt, ks):
    return q.airlight_one(xh, h, ell, kt, ks, ISOTROPIC, 0.0, POINT_ROW, 1e-12, q.N10, q.W10, q.N20, q.W20, np.zeros(3))


def lookup_many(tab, u, v, u_max=U_MAX):
    return np.array([sun.lookup(tab, u_max, a, b) for a, b in zip(u, v)])


@pytest.mark.parametrize("u,v", [(0.0, 0.7), (1e-3, 1e-3), (0.01, 0.3), (1e-6, 1.5), (3.0, 1.0), (10.0, 1e-3),
                                 (10.0, 1.5707), (0.5, math.pi / 2), (7.5, 0.2)])
def test_closed_form_fill_matches_mpmath(u, v):
    mp.mp.dps = 30
    want = mp.quad(lambda x: mp.exp(-u * mp.tan(x)), [0, v])
    assert sun.F_exact(u, v) == pytest.approx(float(want), rel=1e-12)


def test_table_is_on_cell_corners(table):
    assert table.shape == (512, 512) and table.dtype == np.float32
    np.testing.assert_array_equal(table[:, 0], 0.0)
    np.testing.assert_array_equal(table[0], np.linspace(0, math.pi / 2, 512).astype(np.float32))
    assert table[-1, -1] == np.float32(sun.F_exact(U_MAX, math.pi / 2))


def test_bilinear_error_falls_as_h_squared():
    rng = np.random.default_rng(3)
    u, v = rng.uniform(1.0, 9.0, 2000), rng.uniform(0.2, 1.3, 2000)  # smooth interior of the range
    exact = sun.F_exact(u, v)
    ns = np.array([17, 33, 65, 129, 257])
    err = np.array([np.abs(lookup_many(sun.fill_table(n, U_MAX), u, v) - exact).max() for n in ns])
    slope = np.polyfit(np.log(1.0 / (ns - 1)), np.log(err), 1)[0]
    assert slope == pytest.approx(2.0, abs=0.2), (slope, err)


def test_512_table_accuracy_inside_its_range(table):
    """Measured (3e5 samples): median 2e-6; max 5e-4 relative for u > 0.05, v > 0.02; near the two
    singular edges it is worse: the knee of dF/dv = exp(-u tan v) at v -> 0 for large u (1.4e-2
    relative there) and the u log u term of F(u, pi/2) at u -> 0 (3e-3 of F(u, pi/2))."""
    rng = np.random.default_rng(4)
    u, v = rng.uniform(0.0, U_MAX, 20000), rng.uniform(0.0, math.pi / 2, 20000)
    exact = sun.F_exact(u, v)
    err = np.abs(lookup_many(table, u, v) - exact)
    inside = (u > 0.05) & (v > 0.02)  # past the first cells along the two singular edges
    assert np.max(err[inside] / exact[inside]) < 1e-3
    assert np.median(err / exact) < 1e-5
    assert np.max(err / sun.F_exact(u, math.pi / 2)) < 5e-3  # relative to the row's scale, everywhere
    assert np.max(err / exact) < 0.02  # worst case, at the knee (u ~ 10, v < 1 cell)


@pytest.mark.parametrize("xh,h,ell,kt", [(2.0, 1.0, 5.0, 0.2), (2.0, 1.0, math.inf, 0.2), (3.0, 1e-4, 6.0, 0.1),
                                         (1.0, 0.3, 10.0, 3.0), (8.0, 2.0, 12.0, 1.5), (0.5, 0.5, 0.1, 0.2),
                                         (50.0, 0.01, 20.0, 0.05)])
def test_airlight_agrees_with_quadrature_inside_the_range(table, xh, h, ell, kt):
    got = sun.airlight_one(xh, h, ell, kt, 0.7 * kt, table, U_MAX, np.zeros(3))
    assert got == pytest.approx(ref(xh, h, ell, kt, 0.7 * kt), rel=1e-3)


def test_beyond_the_table_is_clamped_and_brighter(table):
    v = np.linspace(0.05, math.pi / 2, 7)
    for u in (12.0, 50.0, 1e6, math.inf):
        clamped = lookup_many(table, np.full(7, u), v)
        np.testing.assert_array_equal(clamped, lookup_many(table, np.full(7, U_MAX), v))
        if math.isfinite(u):
            assert np.all(clamped > sun.F_exact(u, v))
    stats = np.zeros(3)
    got = sun.airlight_one(2.0, 20.0, 5.0, 1.0, 1.0, table, U_MAX, stats)  # A1 = H = 20 > u_max
    want = ref(2.0, 20.0, 5.0, 1.0, 1.0)
    assert got > 1000 * want > 0 and stats[sun.CLAMPED_U] == 1


finite = st.floats(allow_nan=True, allow_infinity=True)


@settings(max_examples=300, deadline=None)
@given(u=finite, v=finite, n=st.integers(2, 40), u_max=st.floats(1e-3, 1e3))
def test_indices_stay_inside_the_table(u, v, n, u_max):
    i, s = sun._cell(n, u_max, u)
    j, t = sun._cell(n, math.pi / 2, v)
    assert 0 <= i <= n - 2 and 0 <= j <= n - 2 and 0.0 <= s <= 1.0 and 0.0 <= t <= 1.0


@settings(max_examples=200, deadline=None)
@given(u=finite, v=finite)
def test_lookup_is_bounded_for_any_input(table, u, v):
    val = sun.lookup(table, U_MAX, u, v)
    assert 0.0 <= val <= math.pi / 2 + 1e-6


@settings(max_examples=200, deadline=None)
@given(xh=st.floats(-1e6, 1e6), h=st.floats(0.0, 1e6), ell=st.floats(1e-9, 1e7) | st.just(math.inf),
       kt=st.floats(0.0, 50.0))
def test_airlight_is_finite_and_non_negative(table, xh, h, ell, kt):
    val = sun.airlight_one(xh, h, ell, kt, 0.5 * kt, table, U_MAX, np.zeros(3))
    assert math.isfinite(val) and val >= 0.0


@pytest.mark.parametrize("xh,h,ell,kt", [(3.0, 1e-300, 6.0, 0.1), (3.0, 0.0, 6.0, 0.1), (-1e4, 1.0, math.inf, 0.5),
                                         (-3.0, 0.5, 4.0, 0.3), (2.0, 1.0, 5.0, 0.0), (1e6, 1.0, 10.0, 2.0)])
def test_edge_inputs_are_finite(table, xh, h, ell, kt):
    assert math.isfinite(sun.airlight_one(xh, h, ell, kt, 0.7 * kt, table, U_MAX, np.zeros(3)))


def test_cache_is_written_atomically_and_corrupt_files_are_regenerated(tmp_path, monkeypatch):
    monkeypatch.setenv("RAYTRACE_CACHE", str(tmp_path))
    monkeypatch.setattr(sun, "_MEMO", {})
    path = sun.cache_path(33, 4.0)
    assert path.parent == tmp_path
    fresh = sun.load_table(33, 4.0)
    assert path.exists() and [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary left over
    np.testing.assert_array_equal(np.load(path), fresh)
    for corrupt in (b"not a numpy file", path.read_bytes()[:100]):
        path.write_bytes(corrupt)
        monkeypatch.setattr(sun, "_MEMO", {})
        np.testing.assert_array_equal(sun.load_table(33, 4.0), fresh)
        np.testing.assert_array_equal(np.load(path), fresh)
    np.save(path, np.zeros((33, 33), np.float32))  # valid file, wrong content
    monkeypatch.setattr(sun, "_MEMO", {})
    np.testing.assert_array_equal(sun.load_table(33, 4.0), fresh)
    assert sun.cache_path(33, 4.0) != sun.cache_path(34, 4.0) != sun.cache_path(33, 5.0)


def test_check_accepts_isotropic_only():
    params = {"table_size": 512, "u_max": 10.0}
    sun.METHOD.check(SimpleNamespace(phase=ISOTROPIC, g=0.0), params)
    for code in (RAYLEIGH, HG):
        with pytest.raises(UserError, match="isotropic") as e:
            sun.METHOD.check(SimpleNamespace(phase=code, g=0.5), params)
        assert "\n" not in str(e.value)
    from raytrace.methods import resolve_params
    for bad in ({"table_size": 1}, {"u_max": 0.0}, {"u_max": math.nan}):
        with pytest.raises(UserError):
            resolve_params(sun.METHOD, bad, "t")


def test_driver_sums_lights_and_channels(table, tmp_path, monkeypatch):
    monkeypatch.setenv("RAYTRACE_CACHE", str(tmp_path))
    medium = Medium(np.array([0.1, 0.1, 0.2]), np.array([0.1, 0.1, 0.3]), ISOTROPIC)
    lpos = np.array([[2.0, 1.0, 0.0], [-1.0, 0.0, 2.0]])
    lint = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    lights = Lights.of([Light(p, i) for p, i in zip(lpos, lint)])
    out, stats, _ = unshadowed_airlight(sun.METHOD, medium, lights, {"table_size": 512, "u_max": 10.0}, np.zeros((1, 3)),
                                        np.array([[1.0, 0.0, 0.0]]), np.array([5.0]), np.zeros(1, np.uint64))
    one = lambda xh, h, c: sun.airlight_one(xh, h, 5.0, medium.sigma_t[c], medium.sigma_s[c], table, U_MAX,
                                            np.zeros(3))
    want = [sum(lint[li, c] * one(*xhh, c) for li, xhh in enumerate([(2.0, 1.0), (-1.0, 2.0)])) for c in range(3)]
    np.testing.assert_allclose(out[0], want, rtol=1e-14)
    assert stats[sun.EVALS] == 4
