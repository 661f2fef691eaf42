"""A spot's cone crossings on a refracted path (media/slab.py `refracted_cuts`, its search `_cone_crossings`,
and `_isolate`'s cone levels for the bound): the leaving cosine c(x) to the spot's axis crosses the cone's
levels where the integrand jumps or kinks. An interval is excluded by the first-order test (c's slope at
most K_R / o_min) or the second-order one (|c''| at most `cone_bend`: ends of one sign clearing M h^2 / 8).

The row below is a face of the 32-segment glass UV ball (512 planes) seen at pixel (16, 1) of 32 x 24 under
a spot at (2, 2, 1), cone 12 degrees, falloff from 6: its cosine crosses cos 12 degrees twice 0.0045 apart,
glancing (slope 2.7e-4 at the first crossing: an ulp of the cosine per 4e-13 of x, about the search's
smallest interval). There the ends of the smallest intervals lie on the level exactly, and a test that
took only strict sign changes lost the first crossing: with the first-order test alone the search ran
into its MAX_ISOLATE evaluations and then found both on larger intervals; with the second-order one it
reached the smallest intervals and lost it.
"""
import functools
import math

import mpmath as mp
import numpy as np

from raytrace.media import slab
from raytrace.media.fermat_rounding import fermat_speed

from .test_refracted_edge_isolation import fermat_point

mp.mp.dps = 30

# z0, a, hl, wl, ll, wa, la, na of `refracted_cosine`, the segment's end, eta, the cone's levels
ROW = (0.3313884054928684, 0.14652635316281434, 1.3793745588139998, -0.689588986508967, 2.479141119763616,
       0.4639154047551582, -0.914887266731274, -0.7788592293071769)
END, ETA, COS_END, COS_START = 1.5912374863779932, 1.5, 0.9781476007338057, 0.9945218953682733


def exact_cosine(x, row=ROW, eta=ETA):
    """The leaving cosine at x (an mpf) of the row's numbers taken as exact: Snell's law on the plane by
    mpmath's root, `_leaving_cosine`'s formula."""
    z0, a, hl, wl, ll, wa, la, na = (mp.mpf(v) for v in row)
    rho = mp.sqrt(x * x * (1 - a * a) - 2 * x * wl + ll)
    z = z0 + a * x
    r = mp.findroot(lambda r: (rho - r) / mp.sqrt((rho - r) ** 2 + hl ** 2) - eta * r / mp.sqrt(r * r + z * z),
                    (mp.mpf(0), rho), solver="anderson")
    return ((rho - r) * (x * wa - la) / rho - hl * na) / mp.sqrt((rho - r) ** 2 + hl ** 2)


def interval_curve(lo, hi, row=ROW, eta=ETA):
    """`_cone_crossings`' M over [lo, hi]: `cone_bend` of `fermat_bend`, `fermat_speed` and o_min."""
    z0, a, hl, wl, ll = row[:5]
    rmin, rmax = slab.rho_range(lo, hi, wl, ll, a)
    zlo, zhi = min(z0 + a * lo, z0 + a * hi), max(z0 + a * lo, z0 + a * hi)
    smin = rmin * hl / (hl + zhi)
    o_min = math.hypot(smin, hl)
    return slab.cone_bend(slab.fermat_bend(rmin, rmax, zlo, zhi, a, hl, eta, 0.0),
                          fermat_speed(rmin, rmax, zlo, a, eta), o_min)


@functools.cache
def exact_crossings(level, n=801):
    """The roots of exact_cosine - level on [0, END]: sign changes on n samples, refined by mpmath."""
    xs = [mp.mpf(END) * i / (n - 1) for i in range(n)]
    v = [exact_cosine(x) - level for x in xs]
    return [float(mp.findroot(lambda t: exact_cosine(t) - level, (xs[i], xs[i + 1]), solver="anderson"))
            for i in range(n - 1) if v[i] * v[i + 1] < 0]


def test_the_cone_bend_bound_holds_on_the_glancing_face():
    """|c''| by mpmath at 5 points of each of the row's intervals (the whole, its quarters, and the
    intervals of 2^-10 and 2^-14 of it about the pair) never exceeds the interval's M, nor |c'| its K."""
    worst = 0.0
    for depth in (0, 2, 10, 14):
        n = 2 ** depth
        for i in range(n):
            lo, hi = END * i / n, END * (i + 1) / n
            if depth > 2 and not (lo < 0.4904 and hi > 0.4857):
                continue
            z0, a, hl, wl, ll = ROW[:5]
            rmin, rmax = slab.rho_range(lo, hi, wl, ll, a)
            smin = rmin * hl / (hl + max(z0 + a * lo, z0 + a * hi))
            k = fermat_speed(rmin, rmax, min(z0 + a * lo, z0 + a * hi), a, ETA) / math.hypot(smin, hl)
            curve = interval_curve(lo, hi)
            for x in np.linspace(lo, hi, 5):
                acc = abs(float(mp.diff(exact_cosine, mp.mpf(float(x)), 2)))
                assert acc <= curve, (lo, hi, x, acc, curve)
                assert abs(float(mp.diff(exact_cosine, mp.mpf(float(x)), 1))) <= k
                worst = max(worst, acc / curve)
    assert worst > 0.03, worst  # not vacuous: within 33x


def test_the_cone_bend_bound_holds():
    """Random segments below the plane z = 0, lights above it (heights 1e-2 to 2, eta 1.33 to 2) and spot
    axes: |c''| of the leaving cosine c = A·(R - L) / |R - L| at 5 points of each of 3 sub-intervals never
    exceeds `cone_bend` of the interval's `fermat_bend`, `fermat_speed` and least outside leg (and is
    within 200x of the largest sampled value somewhere)."""
    rng = np.random.default_rng(5)
    ratios = []
    for case in range(8):
        eta = float(rng.uniform(1.33, 2.0))
        hl = float(10.0 ** rng.uniform(-2.0, 0.3))
        L = [mp.mpf(float(v)) for v in rng.uniform(-1.0, 1.0, 2)] + [mp.mpf(hl)]
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        z0 = float(rng.uniform(0.05, 1.0))
        w = rng.normal(size=3)
        w[2] = -abs(w[2])
        w /= np.linalg.norm(w)
        p = np.array([*rng.uniform(-2.0, 2.0, 2), -z0])
        a = -float(w[2])

        def cosine(t):
            X = [mp.mpf(float(p[j])) + t * mp.mpf(float(w[j])) for j in range(3)]
            R = fermat_point(X, L, eta)
            d = [R[0] - L[0], R[1] - L[1], -L[2]]
            return sum(float(axis[j]) * d[j] for j in range(3)) / mp.sqrt(sum(v * v for v in d))

        ends = np.linspace(0.0, 1.5, 4)
        for lo, hi in zip(ends[:-1], ends[1:]):
            rho = [math.hypot(p[0] + x * w[0] - float(L[0]), p[1] + x * w[1] - float(L[1])) for x in
                   np.linspace(lo, hi, 2001)]
            z = (z0 + a * lo, z0 + a * hi)
            s_min = min(rho) * hl / (hl + max(z))
            bound = slab.cone_bend(slab.fermat_bend(min(rho), max(rho), min(z), max(z), a, hl, eta, 0.0),
                                   fermat_speed(rho[0], rho[-1], min(z), a, eta), math.hypot(s_min, hl))
            acc = [abs(float(mp.diff(cosine, mp.mpf(float(x)), 2))) for x in np.linspace(lo, hi, 5)]
            assert max(acc) <= bound, (case, lo, max(acc), bound)
            ratios.append(bound / max(acc))
    assert min(ratios) < 200.0, min(ratios)


def test_a_glancing_pair_of_crossings_found():
    """`refracted_cuts` finds both crossings of the pair (the SCAN samples bracket neither), at mpmath's
    roots to 1e-12 (the computed cosine's rounding over its slope there: about 4e-13), and none of the
    core's level, which the cosine stays below."""
    out = np.empty(2 * slab.MAX_CUTS)
    m = slab.refracted_cuts(ROW[0], ROW[3], ROW[4], ROW[1], ROW[2], ETA, *ROW[5:], COS_END, COS_START, END, out)
    truth = exact_crossings(COS_END)
    assert len(truth) == 2 and 0.0044 < truth[1] - truth[0] < 0.0046, truth
    assert not exact_crossings(COS_START, 101)
    assert m == 2 and np.all(np.abs(out[:m] - truth) < 1e-12), (out[:m], truth)


class Counted:
    """`_cone_crossings`' Python body with `_cone_psi`'s evaluations counted; `first`: with the first-order
    test alone (`_off_band` refuses)."""

    def __init__(self, monkeypatch, first):
        self.n = 0
        real = slab._cone_psi

        def counting(*args):
            self.n += 1
            return real(*args)
        monkeypatch.setattr(slab, "_cone_psi", counting)
        if first:
            monkeypatch.setattr(slab, "_off_band", lambda *args: False)


def search(level):
    """`_cone_crossings.py_func` over the row for one level: its crossings, sorted."""
    out = np.empty(slab.MAX_CUTS)
    m = slab._cone_crossings.py_func(ROW[0], ROW[3], ROW[4], ROW[1], ROW[2], ETA, *ROW[5:], level, END, out, 0)
    return np.sort(out[:m])


def test_the_second_order_search_ends_below_its_cap(monkeypatch):
    """The first-order search runs into MAX_ISOLATE evaluations on the glancing pair; with the second-order
    test it closes in under half of them, and both find the pair."""
    truth = exact_crossings(COS_END)
    counts = []
    for first in (True, False):
        counter = Counted(monkeypatch, first)
        cuts = search(COS_END)
        counts.append(counter.n)
        monkeypatch.undo()
        assert len(cuts) == 2 and np.all(np.abs(cuts - truth) < 1e-12), (first, cuts, truth)
    assert counts[0] >= slab.MAX_ISOLATE > 2 * counts[1], counts


def test_a_run_of_exact_zeros_is_a_crossing(monkeypatch):
    """A cosine that crosses the level with slope 1e-4 (the row's K and M bound it) equals the level exactly
    over 1.1e-12 of x, more than two of the search's smallest intervals (1e-13 of the segment's scale):
    no smallest interval has a strict sign change, yet the search puts a cut where the run of 0s
    begins (and at most one where it ends), inside the run."""
    x0 = 0.7

    def cosine(x, *args):
        return COS_END + 1e-4 * (x - x0)
    for name in ("_cone_psi", "refracted_cosine"):
        monkeypatch.setattr(slab, name, cosine)
    monkeypatch.setattr(slab, "_bisect_cosine", slab._bisect_cosine.py_func)
    run = [x for x in np.linspace(x0 - 1e-12, x0 + 1e-12, 2001) if cosine(x) == COS_END]
    assert run[-1] - run[0] > 2e-13 * (END + math.sqrt(ROW[4]) + ROW[2] + ROW[0]), (run[0], run[-1])
    cuts = search(COS_END)
    assert 1 <= len(cuts) <= 2 and np.all((cuts >= run[0] - 1e-15) & (cuts <= run[-1] + 1e-15)), (cuts, run[0])
