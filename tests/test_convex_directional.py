"""Exact single scattering of a directional light inside convex index-matched shapes
(raytrace/media/convex_directional.py) against an independent twin.

The twin (`twin`) integrates eq. (2) with mpmath at 40 digits for the given doubles: the light's
path s(t) by brute force (the minimum over the faces the light crosses), the kinks of s by brute
force too (every crossing of two faces' lines and every zero, kept where those lines are lowest),
Gauss-Legendre between them. Shapes: a box, a triangular prism, a thin tilted cuboid, a random
convex hull (scipy.spatial.ConvexHull's equations); random segments (a quarter starting on a face,
a third running to the exit), random and grazing light (n·u = ±1e-9), kt from 1e-6 to 1e3 per
channel: 1e-12 relative (measured: <= 1e-13 on the box, prism and slab, 8e-13 on the hull), except
where the answer itself is ill-conditioned in doubles (`test_against_the_twin`). Also: the sweep
against the brute-force minimum, a box by hand, the planar model (slab.slab_distant) where it is
exact, the existing convex quadrature (slab.convex_quadrature), the edge cases of the module docstring,
and the error bound interiors/rows.py renders with (`segments_bounded`) against the twin.
"""
import itertools
import math

import mpmath as mp
import numpy as np
import pytest
from scipy.spatial import ConvexHull

from raytrace.media import slab
from raytrace.media.convex_directional import MAX_FACES, envelope, segment_radiance, segments_bounded
from raytrace.media.phase import HG, ISOTROPIC, phase_value

RTOL = 1e-12
FALLS = list(range(11)) + [12, 15, 20, 25, 30, 40, 50, 60]


def unit(v):
    return v / np.linalg.norm(v)


def box(lo, hi):
    n = np.array([[1.0, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]])
    return n, np.array([hi[0], -lo[0], hi[1], -lo[1], hi[2], -lo[2]])


def prism():
    """A triangle (0, 0), (2, 0), (0.5, 1.5) in x, y extruded over z in [-0.5, 1]."""
    tri = np.array([[0.0, 0.0], [2.0, 0.0], [0.5, 1.5]])
    n, c = [[0.0, 0, 1], [0, 0, -1]], [1.0, 0.5]
    for i in range(3):
        a, b = tri[i], tri[(i + 1) % 3]
        e = unit(np.array([b[1] - a[1], a[0] - b[0], 0.0]))  # outward for a counter-clockwise triangle
        n.append(e)
        c.append(e[:2] @ a)
    return np.array(n), np.array(c)


def tilted_slab():
    """A 2 x 2 x 0.02 cuboid, rotated and moved off the origin."""
    q, _ = np.linalg.qr(np.random.default_rng(7).normal(size=(3, 3)))
    half = np.array([1.0, 1.0, 0.01])
    centre = np.array([0.3, -0.2, 0.5])
    n = np.concatenate([q.T, -q.T])
    return n, np.concatenate([half, half]) + n @ centre


def hull(points=24, seed=3):
    h = ConvexHull(np.random.default_rng(seed).normal(size=(points, 3)))
    return h.equations[:, :3].copy(), -h.equations[:, 3].copy()


SHAPES = {"box": box(np.array([-0.5, 0.2, -1.0]), np.array([0.7, 1.3, 0.4])), "prism": prism(),
          "tilted slab": tilted_slab(), "hull": hull()}


def vertices(n, c):
    """The shape's corners: the intersections of three face planes that satisfy every inequality."""
    out = []
    for i, j, k in itertools.combinations(range(len(n)), 3):
        m = n[[i, j, k]]
        if abs(np.linalg.det(m)) < 1e-9:
            continue
        v = np.linalg.solve(m, c[[i, j, k]])
        if np.all(n @ v <= c + 1e-9):
            out.append(v)
    return np.array(out)


def exit_length(n, c, o, w):
    den = n @ w
    return min((c[den > 0] - n[den > 0] @ o) / den[den > 0])


def fdot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def twin(n, c, o, w, length, toward, kt, ks, phase):
    """ks Phi ∫_0^T exp(-kt (t + s(t))) dt per channel, exact for the given doubles: mpmath at 40
    digits, s = max(0, min_f (c_f - n_f·p) / q_f) by brute force, the kinks of s by brute force too (every crossing of two
    faces' lines and every zero, kept where those lines are lowest), mpmath quad between them (in
    the offset from each kink: smooth even where two kinks are a few ulps of t apart). Also returns
    the rounding allowance of doubles, 8 eps kt max (|c_f| + |o| + T) / q_f over the faces lowest
    somewhere (the condition of eq. (2) in its inputs: a face the light grazes, q_f -> 0,
    magnifies the rounding of c_f - n_f·p by 1 / q_f)."""
    with mp.workdps(40):
        N = [[mp.mpf(float(x)) for x in row] for row in n]
        C, O, W, U = ([mp.mpf(float(x)) for x in v] for v in (c, o, w, toward))
        lines = []
        for f in range(len(N)):
            q = fdot(N[f], U)
            if q > 0:
                lines.append(((C[f] - fdot(N[f], O)) / q, -fdot(N[f], W) / q, f))
        ends = {mp.mpf(0), mp.mpf(float(length))}
        for (a1, b1, _), (a2, b2, _) in itertools.combinations_with_replacement(lines, 2):
            if (a1, b1) == (a2, b2):
                t = -a1 / b1 if b1 != 0 else -1
            else:
                t = (a2 - a1) / (b1 - b2) if b1 != b2 else -1
            tol = mp.mpf(10) ** -32 * (abs(a1) + abs(b1) * t + abs(a2) + abs(b2) * t)
            if 0 < t < length and max(a1 + b1 * t, a2 + b2 * t) <= min(a + b * t for a, b, _ in lines) + tol:
                ends.add(t)
        ends = sorted(ends)
        used = {min(lines, key=lambda ln: ln[0] + ln[1] * (lo + hi) / 2)[2] for lo, hi in zip(ends[:-1], ends[1:])}
        out = np.zeros(len(kt))
        for ch in range(len(kt)):
            k = mp.mpf(float(kt[ch]))
            total = 0
            for lo, hi in zip(ends[:-1], ends[1:]):
                def g(x, lo=lo):  # the optical path t + s(t) at t = lo + x
                    return lo + x + max(0, min(a + b * (lo + x) for a, b, _ in lines))
                d = hi - lo
                rate = k * abs(g(d) - g(0)) / d if d > 0 else 0
                # Gauss-Legendre between nodes at falls of 1, 2, ... of optical depth from the brighter end
                # (tanh-sinh misses a sharp decay), up to a fall of e^-60; the rest is left out
                xs = [min(j / rate, d) for j in FALLS] if rate * d > 1 else [0, d]
                xs = sorted(set(xs if g(0) <= g(d) else [d - x for x in xs]))
                total += mp.quad(lambda x: mp.exp(-k * g(x)), xs, method="gauss-legendre")
            out[ch] = float(ks[ch] * phase * total)
    q = n @ toward
    scale = max(((abs(c[f]) + np.linalg.norm(o) + length) / q[f] for f in used), default=0.0)
    return out, 8 * np.finfo(float).eps * kt * scale


def kernel(n, c, o, w, length, toward, kt, ks, phase):
    out, f = np.zeros(len(kt)), len(n)
    assert segment_radiance(n, c, o, w, toward, length, kt, ks, phase, out, np.empty(f), np.empty(f), np.empty(f + 1),
                            np.empty(f, dtype=np.int64))
    return out


def light_directions(rng, n, count):
    """Random directions toward the light, and grazing ones: in a face's plane tipped by ±1e-9."""
    out = [unit(rng.normal(size=3)) for _ in range(count)]
    for _ in range(count):
        f = rng.integers(len(n))
        v = rng.normal(size=3)
        v = unit(v - (v @ n[f]) * n[f])
        out.append(unit(v + rng.choice([-1e-9, 1e-9]) * n[f]))
    return out


def segments(rng, n, c, count):
    """Random segments (o, w, T) inside: o inside or on a face, T to the exit or short of it."""
    corners = vertices(n, c)
    out = []
    for i in range(count):
        if i % 4 == 3:  # on a face
            f = rng.integers(len(n))
            on = corners[np.abs(corners @ n[f] - c[f]) < 1e-9]
            o = rng.dirichlet(np.ones(len(on))) @ on
            w = unit(rng.normal(size=3))
            w = w if w @ n[f] < 0 else -w  # into the shape
        else:
            o = rng.dirichlet(np.ones(len(corners))) @ corners
            w = unit(rng.normal(size=3))
        t_exit = exit_length(n, c, o, w)
        out.append((o, w, t_exit if i % 3 == 0 else t_exit * rng.uniform(0.05, 1.0)))
    return out


@pytest.mark.parametrize("name", sorted(SHAPES))
def test_against_the_twin(name):
    """Random segments, lights (half of them grazing a face) and per-channel coefficients: 1e-12, or
    the twin's rounding allowance where it exceeds 1e-9: a segment that ends (or starts) on a face
    the light grazes at 1e-9 is lit mostly in the last 1e-10 of its length, where s falls from ~0.1
    to 0 and its value rests on c_f - n_f·p / q_f, rounded in doubles to 1e-17 / 1e-9 (the last bit
    of T moves the exact answer by as much: measured 1.5e-5 on the box at kt = 745)."""
    n, c = SHAPES[name]
    rng = np.random.default_rng(sorted(SHAPES).index(name))
    worst, loose, off = 0.0, 0, 0
    count = 8 if name == "hull" else 12  # the hull's twin is the slow one (40-digit minima over its faces)
    lights = light_directions(rng, n, count // 2)
    for o, w, length in segments(rng, n, c, count):
        for toward in lights:
            kt = 10.0 ** rng.uniform(-6, 3, size=3)
            ks = kt * rng.uniform(0.1, 1.0, size=3)
            phase = rng.uniform(0.01, 1.0)
            got = kernel(n, c, o, w, length, toward, kt, ks, phase)
            ref, allow = twin(n, c, o, w, length, toward, kt, ks, phase)
            assert np.all(np.isfinite(got)) and np.all(got >= 0)
            tol = np.where(allow <= 1e-9, RTOL, allow)  # 1e-12 but where doubles cannot tell (docstring)
            assert np.all(np.abs(got - ref) <= tol * ref + 1e-300), (o, w, length, toward, kt, got, ref, allow)
            err = np.abs(got - ref) / np.maximum(ref, 1e-300)
            worst = max(worst, np.max(err, where=allow <= 1e-9, initial=0.0))
            loose += np.count_nonzero(allow > 1e-9)
            off += np.count_nonzero(err > RTOL)
    print(f"{name}: worst relative error {worst:.2e} where the allowance <= 1e-9; {loose} channels beyond, "
          f"{off} of them off by more than 1e-12")


@pytest.mark.parametrize("name", sorted(SHAPES))
def test_the_bound_holds_against_the_twin(name):
    """`segments_bounded` (what interiors/rows.py renders with): the values of `segment_radiance` with the
    phase function at each segment's scattering cosine (to 1e-14: the two kernels are compiled apart
    with fastmath, which may reassociate differently on another CPU), and a bound that the twin's error never
    exceeds (half the lights grazing a face at 1e-9), finite for finite segments, and within
    1e-10 of the value wherever the twin's allowance is below 1e-12."""
    n, c = SHAPES[name]
    rng = np.random.default_rng(40 + sorted(SHAPES).index(name))
    lights = light_directions(rng, n, 3)
    worst, tight, loose, same = 0.0, 0, 0, 0.0
    for o, w, length in segments(rng, n, c, 6 if name == "hull" else 12):
        for toward in lights:
            kt = 10.0 ** rng.uniform(-6, 3, size=3)
            ks = kt * rng.uniform(0.1, 1.0, size=3)
            out, bound = np.zeros((1, 3)), np.zeros((1, 3))
            assert segments_bounded(n, c, o[None, :], w[None, :], np.array([length]), toward, kt, ks, HG, 0.6, out,
                                    bound)
            phase = float(phase_value(HG, 0.6, float(toward @ w)))
            value = kernel(n, c, o, w, length, toward, kt, ks, phase)
            assert np.all(np.abs(out[0] - value) <= 1e-14 * np.abs(value)), (out[0], value)
            same = max(same, float(np.max(np.abs(out[0] - value) / np.where(value > 0, value, 1.0))))
            ref, allow = twin(n, c, o, w, length, toward, kt, ks, phase)
            err = np.abs(out[0] - ref)
            assert np.all(np.isfinite(bound)) and np.all(err <= bound[0]), (o, w, length, toward, kt, err, bound)
            worst = max(worst, float(np.max(err / np.where(bound[0] > 0, bound[0], 1.0))))
            small = allow < 1e-12
            assert np.all(bound[0][small] <= 1e-10 * out[0][small])
            tight += np.count_nonzero(small)
            loose += np.count_nonzero(allow > 1e-9)
    assert tight > 0
    print(f"{name}: largest error / bound {worst:.2e}; {loose} channels where the allowance exceeds 1e-9; "
          f"largest difference from segment_radiance {same:.1e} relative")


def test_the_bound_of_an_infinite_segment_is_infinite():
    """A half-space entered along its boundary plane's normal, T = inf: the value is finite, the
    allowance (|c| + |o| + T) / q is not, so neither is the bound; vacuum channels and no light: 0."""
    out, bound = np.zeros((1, 2)), np.zeros((1, 2))
    assert segments_bounded(np.array([[0.0, 0.0, 1.0]]), np.array([0.0]), np.zeros((1, 3)), np.array([[0.0, 0.0, -1.0]]),
                            np.array([math.inf]), unit(np.array([0.0, 0.3, 1.0])), np.array([1.0, 2.0]),
                            np.array([0.5, 0.0]), ISOTROPIC, 0.0, out, bound)
    assert np.isfinite(out[0, 0]) and out[0, 0] > 0 and bound[0, 0] == math.inf
    assert out[0, 1] == 0.0 and bound[0, 1] == 0.0


def sphere_hull(points=32, seed=4):
    """Qhull's facets of points on the unit sphere (60 for 32 points)."""
    p = np.random.default_rng(seed).normal(size=(points, 3))
    h = ConvexHull(p / np.linalg.norm(p, axis=1)[:, None])
    return h.equations[:, :3].copy(), -h.equations[:, 3].copy()


@pytest.mark.parametrize("name", sorted(SHAPES) + ["sphere hull"])
def test_envelope_is_the_brute_force_minimum(name):
    """The sweep's pieces: s on each piece equals the minimum over the faces at points inside it, and
    the slopes fall from piece to piece (a concave envelope, each face at most once)."""
    n, c = SHAPES[name] if name in SHAPES else sphere_hull()
    assert len(n) <= MAX_FACES
    rng = np.random.default_rng(11)
    f = len(n)
    alpha, beta, cuts, lines = np.empty(f), np.empty(f), np.empty(f + 1), np.empty(f, dtype=np.int64)
    pieces = []
    for o, w, length in segments(rng, n, c, 40):
        toward = unit(rng.normal(size=3))
        m = envelope(n, c, o, w, toward, length, alpha, beta, cuts, lines)
        pieces.append(m)
        assert 1 <= m <= np.count_nonzero(n @ toward > 0) and cuts[0] == 0.0 and cuts[m] == length
        assert np.all(np.diff(cuts[:m + 1]) >= 0) and np.all(np.diff(beta[lines[:m]]) < 0)
        for i in range(m):
            for t in np.linspace(cuts[i], cuts[i + 1], 7)[1:-1]:
                with mp.workdps(40):
                    p = [mp.mpf(o[i]) + mp.mpf(t) * mp.mpf(w[i]) for i in range(3)]
                    brute = float(max(0, min((mp.mpf(cf) - fdot([mp.mpf(x) for x in nf], p)) / fdot(nf, toward)
                                             for nf, cf in zip(n, c) if nf @ toward > 0)))
                assert abs(alpha[lines[i]] + beta[lines[i]] * t - brute) <= 1e-12 * (1.0 + brute)
    assert max(pieces) >= (4 if "hull" in name else 2)  # the light enters through several faces along some


def test_a_box_lit_through_its_side_by_hand():
    """The unit box, a vertical segment from the floor's centre, the light toward (0.6, 0, 0.8): it
    enters through the side x = 1 for t < 1/3 (s = 5/6) and through the top after (s = (1 - t) / 0.8)."""
    n, c = box(np.zeros(3), np.ones(3))
    kt, ks, phase = np.array([1.0, 2.0]), np.array([0.5, 0.25]), 0.3
    got = kernel(n, c, np.array([0.5, 0.5, 0.0]), np.array([0.0, 0.0, 1.0]), 1.0, np.array([0.6, 0.0, 0.8]), kt, ks,
                 phase)
    for k, s_, g in zip(kt, ks, got):
        side = math.exp(-k * 5 / 6) * (1 - math.exp(-k / 3)) / k  # g = t + 5/6
        top = 4 * math.exp(-k * 5 / 4) * (math.exp(k / 4) - math.exp(k / 12)) / k  # g = 5/4 - t/4 on [1/3, 1]
        assert abs(g - s_ * phase * (side + top)) <= 1e-14 * g


def test_the_planar_model_where_it_is_exact():
    """A slab (two planes) entered through its top, the light entering through the top too: eq. 5
    of slab.py (slab_distant, c = a / b) for finite segments, and a half-space for an infinite one."""
    n, c = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]), np.array([0.0, 2.0])
    rng = np.random.default_rng(5)
    for _ in range(50):
        w = unit(rng.normal(size=3) - np.array([0.0, 0.0, 2.0]))
        w = w if w[2] < 0 else w * np.array([1.0, 1.0, -1.0])
        toward = unit(rng.normal(size=3) + np.array([0.0, 0.0, 1.5]))
        toward[2] = abs(toward[2])
        o = np.array([rng.normal(), rng.normal(), 0.0])
        kt = 10.0 ** rng.uniform(-6, 3, size=3)
        ks, phase = 0.7 * kt, 0.2
        a, b = -w[2], toward[2]
        for length, nn, cc in ((exit_length(n, c, o, w), n, c), (math.inf, n[:1], c[:1])):
            got = kernel(nn, cc, o, w, length, toward, kt, ks, phase)
            ref = [slab.slab_distant(k, s_, phase, a / b, length) for k, s_ in zip(kt, ks)]
            assert np.allclose(got, ref, rtol=1e-13, atol=0.0)


@pytest.mark.parametrize("name", ["box", "hull"])
def test_agrees_with_the_existing_convex_quadrature(name):
    """slab.convex_quadrature (what interiors/crossing.py's quadrature integrates in convex shapes today)."""
    n, c = SHAPES[name]
    planes = np.column_stack([n, c])
    rng = np.random.default_rng(2)
    for o, w, length in segments(rng, n, c, 20):
        toward = unit(rng.normal(size=3))
        kt = 10.0 ** rng.uniform(-2, 1.5)
        geo = np.zeros(slab.GEO_COLUMNS)
        geo[:3], geo[3:6], geo[6:9] = o, w, toward
        ref = slab.convex_quadrature(geo, planes, True, length, kt, 0.5 * kt, 0, 0.0, 0.0, 0.3, -1, 1e-12, np.zeros(3))
        got = kernel(n, c, o, w, length, toward, np.array([kt]), np.array([0.5 * kt]), 0.3)[0]
        assert abs(got - ref) <= 1e-10 * ref


def test_edge_cases():
    """T = 0 or negative, kt = 0, huge kt, light parallel to faces, no face toward the light, a segment
    from a face the light enters through, and more than MAX_FACES faces (False, nothing written)."""
    n, c = box(np.zeros(3), np.ones(3))
    o, w = np.array([0.5, 0.5, 1.0]), unit(np.array([0.1, 0.2, -1.0]))
    kt, ks = np.array([0.0, 1e-300, 1.0, 1e8, 1e300]), np.array([0.3, 1e-300, 0.5, 1e8, 1e300])
    for length in (0.0, -1.0, math.nan):
        assert np.all(kernel(n, c, o, w, length, unit(np.array([1.0, 2.0, 3.0])), kt, ks, 0.1) == 0.0)
    for toward in (unit(np.array([0.6, 0.8, 0.0])), np.array([0.0, 0.0, 1.0]), unit(np.array([1e-9, 0.0, 1.0])),
                   unit(np.array([1.0, 2.0, 3.0]))):
        length = exit_length(n, c, o, w)
        got = kernel(n, c, o, w, length, toward, kt, ks, 0.1)
        assert np.all(np.isfinite(got)) and np.all(got >= 0.0)
        assert got[0] == pytest.approx(0.3 * 0.1 * length, rel=1e-15)  # a vacuum: ks Phi T
        assert got[2] <= 0.05 * (1 - math.exp(-length))  # g >= t
        # huge kt: only the first 1 / kt counts; from the top face, where the light enters (s(0) = 0),
        # ks Phi / (kt (1 + beta)), beta = -w_z / u_z; 0 when the light enters through the sides only
        expect = 0.1 / (1.0 + abs(w[2]) / toward[2]) if toward[2] > 0 else 0.0
        assert got[3] == pytest.approx(expect, rel=1e-12, abs=1e-300)
        assert got[4] == pytest.approx(expect, rel=1e-12, abs=1e-300)
    # an infinite slab, the light parallel to it: no face toward the light
    got = kernel(n[4:], c[4:], o, w, 0.5, np.array([1.0, 0.0, 0.0]), kt, ks, 0.1)
    assert np.all(got == np.array([0.3 * 0.1 * 0.5, 0.0, 0.0, 0.0, 0.0]))
    # an infinite segment along a half-space's boundary plane, the light entering from above it
    got = kernel(n[4:5], c[4:5], o, np.array([1.0, 0.0, 0.0]), math.inf, unit(np.array([0.0, 1.0, 1.0])), kt[2:4],
                 ks[2:4], 0.1)
    assert np.allclose(got, 0.1 * ks[2:4] / kt[2:4], rtol=1e-15)
    many_n = np.random.default_rng(1).normal(size=(MAX_FACES + 1, 3))  # a polyhedron about the unit ball
    many_n /= np.linalg.norm(many_n, axis=1)[:, None]
    many_c = np.ones(MAX_FACES + 1)
    out, bound = np.full((1, 2), -7.0), np.full((1, 2), -7.0)
    assert not segments_bounded(many_n, many_c, np.zeros((1, 3)), np.array([[1.0, 0, 0]]), np.array([0.1]),
                                np.array([0.0, 0, 1.0]), np.ones(2), np.ones(2), HG, 0.6, out, bound)
    assert np.all(out == -7.0) and np.all(bound == -7.0)
    f = len(many_n)
    assert not segment_radiance(many_n, many_c, np.zeros(3), np.array([1.0, 0, 0]), np.array([0.0, 0, 1.0]), 0.1,
                                np.ones(2), np.ones(2), 1.0, out[0], np.empty(f), np.empty(f), np.empty(f + 1),
                                np.empty(f, dtype=np.int64))
