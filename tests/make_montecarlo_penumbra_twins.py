"""The noise-free twin of an occluded quad light's air-light, for Monte Carlo's z-test in its penumbra
(tests/test_montecarlo_penumbra.py), from the geometry alone (numpy, no project code):

    L(ray) = ks / (4 pi) int_emitter dA(y) int_lit(y) L (2 - x_y) e^{-kt (t + r)} / r^3 dt,   x = o + t w, r = |x - y|,

the quad at height 2 facing down (n = -y, so n·(x - y) = 2 - x_y), the ray up to its first hit T (black floor,
wall and plate) and to the emitter's plane. For an emitter point y the plate (height 1) hides x exactly where
x lies below it and the segment from x to y crosses its rectangle: p = x + (1 - x_y) / (2 - x_y) (y - x) there,
and a <= p_x <= b is (2 - x_y) a <= x_x + y_x (1 - x_y) <= (2 - x_y) b (likewise in z), each side linear in t:
the shadow is one interval of t, exact. The lit pieces (at most two) take a composite Gauss–Legendre rule in t (`LINE` panels);
the emitter a composite Gauss–Legendre rule (`PANELS` x `PANELS` cells of NODES^2 nodes: the lit integral is
continuous in y, with kinks where a shadow interval meets a ray's end), checked on every 5th pixel against twice
the panels over the emitter and along the ray (the largest relative difference is printed and stored).

    python -m tests.make_montecarlo_penumbra_twins     # about a CPU minute; writes tests/data/montecarlo_penumbra_twins.json
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from .area_twin import camera_rays

OUT = Path(__file__).parent / "data" / "montecarlo_penumbra_twins.json"

KT, KS, RADIANCE = 0.2, 0.15, 10.0
LIGHT = {"type": "quad", "corners": [[-0.5, 2.0, -0.5], [0.5, 2.0, -0.5], [0.5, 2.0, 0.5], [-0.5, 2.0, 0.5]],
         "radiance": RADIANCE}
PLATE_X, PLATE_Z = (-0.2, 0.6), (-0.4, 0.4)  # at height 1
FLOOR, WALL_Z, WALL_TOP = 6.0, -4.0, 5.0  # the floor |x|, |z| <= 6 at height 0; the wall z = -4, |x| <= 6, 0 <= y <= 5
SHAPES = [{"primitive": "quad", "reflectance": 0.0,
           "corners": [[-FLOOR, 0.0, FLOOR], [FLOOR, 0.0, FLOOR], [FLOOR, 0.0, -FLOOR], [-FLOOR, 0.0, -FLOOR]]},
          {"primitive": "quad", "reflectance": 0.0,
           "corners": [[-FLOOR, 0.0, WALL_Z], [FLOOR, 0.0, WALL_Z], [FLOOR, WALL_TOP, WALL_Z], [-FLOOR, WALL_TOP, WALL_Z]]},
          {"primitive": "quad", "reflectance": 0.0,
           "corners": [[PLATE_X[0], 1.0, PLATE_Z[0]], [PLATE_X[1], 1.0, PLATE_Z[0]], [PLATE_X[1], 1.0, PLATE_Z[1]],
                       [PLATE_X[0], 1.0, PLATE_Z[1]]]}]
MEDIUM = {"sigma_a": KT - KS, "sigma_s": KS}
CAMERA = {"position": [0.0, 1.2, 4.2], "look_at": [0.2, 0.3, 0.0], "fov": 40.0, "width": 16, "height": 12}
NODES, PANELS, LINE = 8, 16, 12  # LINE: panels along each lit piece


def rays():
    """(origin (3,), directions (H, W, 3)) of the pixel centres."""
    o = np.array(CAMERA["position"], float)
    return o, camera_rays(o, CAMERA["look_at"], [0.0, 1.0, 0.0], CAMERA["fov"], CAMERA["width"], CAMERA["height"])


def _first_hit(o, w):
    """The distance to the first of floor, wall and plate (all opaque and black)."""
    best = math.inf
    for axis, level, box in ((1, 0.0, ((0, -FLOOR, FLOOR), (2, -FLOOR, FLOOR))),
                             (2, WALL_Z, ((0, -FLOOR, FLOOR), (1, 0.0, WALL_TOP))),
                             (1, 1.0, ((0, *PLATE_X), (2, *PLATE_Z)))):
        if w[axis] == 0.0:
            continue
        t = (level - o[axis]) / w[axis]
        p = o + t * w
        if 0.0 < t < best and all(lo <= p[a] <= hi for a, lo, hi in box):
            best = t
    assert best < math.inf
    return best


def _composite(panels):
    """(nodes, weights) of `panels` equal panels of NODES Gauss–Legendre nodes on [0, 1]."""
    x, w = np.polynomial.legendre.leggauss(NODES)
    edges = np.linspace(0.0, 1.0, panels + 1)
    h = np.diff(edges)
    return (edges[:-1, None] + 0.5 * h[:, None] * (x[None, :] + 1.0)).ravel(), (0.5 * h[:, None] * w[None, :]).ravel()


def _emitter(panels):
    """(points (M, 3), weights (M,)) of the composite rule over the quad."""
    s, ws = _composite(panels)
    uu, vv = np.meshgrid(s, s, indexing="ij")
    c = np.array(LIGHT["corners"], float)
    y = c[0] + uu.ravel()[:, None] * (c[1] - c[0]) + vv.ravel()[:, None] * (c[3] - c[0])
    return y, np.outer(ws, ws).ravel()  # the quad's area is 1


def _shadow(o, w, y):
    """(lo, hi) (M,): the interval of t where the plate hides y from o + t w (lo >= hi: none)."""
    lo, hi = np.full(len(y), -np.inf), np.full(len(y), np.inf)

    def keep(a, b):  # a + b t >= 0
        with np.errstate(divide="ignore", invalid="ignore"):
            root = -a / b
        pos, neg = b > 0.0, b < 0.0
        np.maximum(lo, np.where(pos, root, -np.inf), out=lo)
        np.minimum(hi, np.where(neg, root, np.inf), out=hi)
        none = (b == 0.0) & (a < 0.0)
        lo[none], hi[none] = np.inf, -np.inf

    keep(np.full(len(y), 1.0 - o[1]), np.full(len(y), -w[1]))  # below the plate: 1 - x_y >= 0
    for k, (a, b) in ((0, PLATE_X), (2, PLATE_Z)):
        # q(t) = x_k + y_k (1 - x_y), with (2 - x_y) a <= q <= (2 - x_y) b
        q0, q1 = o[k] + y[:, k] * (1.0 - o[1]), w[k] - y[:, k] * w[1]
        keep(q0 - a * (2.0 - o[1]), q1 + a * w[1])
        keep(b * (2.0 - o[1]) - q0, -b * w[1] - q1)
    return lo, hi


def homogeneous(o, t, p, y, r):
    """ks e^{-kt (t + r)}: the scattering coefficient at x = p times the transmittance camera -> x -> y."""
    return KS * np.exp(-KT * (t + r))


def _line(o, w, y, lo, hi, line, medium):
    """(M,) the integral in t over [lo, hi] (per emitter point) of L (2 - x_y) medium(o, t, x, y, r) / r^3 (`medium`:
    ks at x times the transmittance from o to x to y, `homogeneous`'s e.g.): `line` equal panels of NODES
    Gauss–Legendre nodes."""
    x, wt = _composite(line)
    span = np.maximum(hi - lo, 0.0)
    t = lo[:, None] + span[:, None] * x[None, :]
    p = o[None, None, :] + t[..., None] * w[None, None, :]
    d = p - y[:, None, :]
    r = np.sqrt(np.einsum("mki,mki->mk", d, d))
    f = RADIANCE * (2.0 - p[..., 1]) * medium(o, t, p, y[:, None, :], r) / r ** 3
    return span * (f @ wt)


def pixel(o, w, panels=PANELS, line=LINE, medium=homogeneous):
    """The air-light of the ray o + t w (the module docstring's L; `medium` as `_line`'s)."""
    end = _first_hit(o, w)
    if w[1] > 0.0:
        end = min(end, (2.0 - o[1]) / w[1])  # the emitter's plane: nothing beyond
    y, wy = _emitter(panels)
    s0, s1 = _shadow(o, w, y)
    s0, s1 = np.clip(s0, 0.0, end), np.clip(s1, 0.0, end)
    empty = s1 <= s0
    s0[empty], s1[empty] = end, end
    total = _line(o, w, y, np.zeros(len(y)), s0, line, medium) + _line(o, w, y, s1, np.full(len(y), end), line, medium)
    return float(total @ wy) / (4.0 * math.pi)


def write(out, medium, doc):
    """The image of `pixel` (H, W) with `medium`, checked on every 5th pixel against twice the panels, to `out`."""
    o, dirs = rays()
    image = np.array([[pixel(o, d, medium=medium) for d in row] for row in dirs])
    some = [divmod(k, image.shape[1]) for k in range(0, image.size, 5)]
    spread = max(abs(pixel(o, dirs[p], 2 * PANELS, 2 * LINE, medium) / image[p] - 1.0) for p in some)
    print(f"largest relative difference to {2 * PANELS} panels and {2 * LINE} along the ray (every 5th pixel): "
          f"{spread:.2e}")
    out.write_text(json.dumps({"doc": doc, "panels": PANELS, "line": LINE, "spread": spread,
                               "image": image.tolist()}, indent=1) + "\n")


def main():
    write(OUT, homogeneous, "tests/make_montecarlo_penumbra_twins.py")


if __name__ == "__main__":
    main()
