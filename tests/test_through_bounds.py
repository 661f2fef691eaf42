"""media/convex_chords.py `sphere_chord_error`: the rounding bound of an exact sphere's chord toward a
point light, as `through_pieces` evaluates it (the point o + x w, the unit direction to the light and
the distance in float64), against the chord of the exact point's exact path in mpmath (50 digits), at
random points of random lines and beside the light's tangent cone (the chord's square-root kinks,
where the bound is largest): never exceeded, and below 1e-10 where the chord is longer than 0.1."""
import math

import mpmath
import numpy as np

from raytrace.interiors.paths import piece_errors
from raytrace.media.convex_chords import SPHERE, boundary_kinks, sphere_chord, sphere_chord_error

mpmath.mp.dps = 50
SPHERE_ROW = np.array([0.3, 1.0, -0.2, 1.0])


def exact_chord(o, w, x, light):
    """The chord of the segment from o + x w (exact in mpmath) to the light, inside the sphere."""
    c, r = [mpmath.mpf(v) for v in SPHERE_ROW[:3]], mpmath.mpf(SPHERE_ROW[3])
    p = [mpmath.mpf(o[k]) + mpmath.mpf(x) * mpmath.mpf(w[k]) for k in range(3)]
    rel = [mpmath.mpf(light[k]) - p[k] for k in range(3)]
    d = mpmath.sqrt(sum(v * v for v in rel))
    u = [v / d for v in rel]
    f = [p[k] - c[k] for k in range(3)]
    b = sum(f[k] * u[k] for k in range(3))
    q = b * b - (sum(v * v for v in f) - r * r)
    if q <= 0:
        return mpmath.mpf(0)
    return max(min(-b + mpmath.sqrt(q), d) - max(-b - mpmath.sqrt(q), mpmath.mpf(0)), mpmath.mpf(0))


def kernel_chord(o, w, x, light, moves):
    """(chord, its bound) as through_pieces computes them at x."""
    px, py, pz = o[0] + x * w[0], o[1] + x * w[1], o[2] + x * w[2]
    rx, ry, rz = light[0] - px, light[1] - py, light[2] - pz
    d = max(math.sqrt(rx * rx + ry * ry + rz * rz), 1e-125)
    t = (rx / d, ry / d, rz / d)
    k = sphere_chord(SPHERE_ROW, px, py, pz, *t, d)
    return k, sphere_chord_error(SPHERE_ROW, px, py, pz, *t, k, *moves)


def test_the_sphere_chord_bound_holds():
    rng = np.random.default_rng(5)
    checked = near = 0
    worst, loose = 0.0, []
    for _ in range(40):
        light = rng.uniform(-4.0, 4.0, 3) + SPHERE_ROW[:3]
        if rng.uniform() < 0.25:  # a light inside the sphere: the chord ends at it
            light = SPHERE_ROW[:3] + rng.uniform(-0.5, 0.5, 3)
        w = rng.normal(size=3)
        w /= np.linalg.norm(w)
        away = SPHERE_ROW[:3] - light
        shade = SPHERE_ROW[:3] + away / np.linalg.norm(away) * rng.uniform(1.2, 3.0) + rng.uniform(-0.8, 0.8, 3)
        o = shade - 5.0 * w  # through a point behind the sphere: most lines cross the light's tangent cone
        end = 10.0
        moves, eps, chord_err = np.empty((1, 3)), np.empty((1, 3)), np.zeros((1, 1))
        piece_errors(o[None], w[None], np.array([end]), np.zeros(1, np.int64), light[None],
                     np.array([[-2.0, -2.0, 0.0]]), SPHERE_ROW[None], np.array([0, 1]), np.array([SPHERE]),
                     np.zeros((1, 2)), np.zeros((1, 4)), np.full(3, 0.1), 0, 0.0, eps, moves, chord_err)
        kinks = np.empty(8)
        n = boundary_kinks(SPHERE, SPHERE_ROW[None], 0, 1, o, w, light, end, kinks)
        xs = list(rng.uniform(0.0, end, 20))
        for kink in kinks[:n]:
            xs += [kink + s * h for h in (1e-15, 1e-12, 1e-9, 1e-6, 1e-3) for s in (-1.0, 1.0)]
            near += 1
        for x in xs:
            if not 0.0 <= x <= end:
                continue
            k, bound = kernel_chord(o, w, x, light, moves[0])
            err = abs(k - float(exact_chord(o, w, x, light)))
            assert err <= bound, (o, w, x, light, k, err, bound)
            if k > 0.1:
                loose.append(bound)
            worst = max(worst, err / bound if bound > 0.0 else 0.0)
            checked += 1
    print(f"{checked} chords, {near} kinks: error at most {worst:.2f} of the bound; bound of chords over 0.1: "
          f"median {np.median(loose):.1e}, largest {max(loose):.1e}")
    assert checked > 1000 and near > 40, (checked, near)
    assert max(loose) < 1e-10
