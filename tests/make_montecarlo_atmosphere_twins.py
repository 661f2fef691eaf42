"""The noise-free twin of an occluded quad light's air-light in a planet's atmosphere, for Monte Carlo's z-test in
its penumbra (tests/test_montecarlo_fog_penumbra.py), from the geometry and the atmosphere's definition alone (numpy
and scipy, no project code): the scene of tests/make_montecarlo_penumbra_twins.py (its quad, plate, black floor and
wall, its camera's view in 8 x 6 pixels, and its rules over the emitter and along the ray) in the air of a planet of centre c and radius R
(SCENE_FORMAT.md, `type = "atmosphere"`): layer i of density rho_i(x) = e^{-(|x - c| - R) / H_i} times its
coefficients kt_i, ks_i (per channel) and its phase function p_i (isotropic: 1 / (4 pi); Henyey–Greenstein
(1 - g^2) / (4 pi (1 + g^2 - 2 g cos)^{3/2}), cos between the light's direction (x - y) / r and the way to the
camera -w). Channel by channel:

    L(ray) = int_emitter dA(y) int_lit(y) L (2 - x_y) sum_i ks_i rho_i(x) p_i e^{-sum_i kt_i (tau_i(o, x) + tau_i(x, y))}
             / r^3 dt,

the columns tau_i(p, q) = int rho_i along the segment from p to q by a COLUMN-node Gauss–Legendre rule (scipy's
nodes), checked against mpmath's quad at 30 digits (printed and stored). Everything lies above the ground and
below the top sphere. Channels 0 and 2 (the most and least absorbing), each checked on every 4th pixel against
twice the panels over the emitter and along the ray.

    python -m tests.make_montecarlo_atmosphere_twins     # about two CPU minutes; writes tests/data/montecarlo_atmosphere_twins.json
"""
from __future__ import annotations

import functools
import json
from pathlib import Path

import mpmath
import numpy as np
from scipy.special import roots_legendre

from . import make_montecarlo_penumbra_twins as penumbra
from .area_twin import camera_rays

OUT = Path(__file__).parent / "data" / "montecarlo_atmosphere_twins.json"

CENTER, R, TOP = np.array([0.0, -10.0, 0.0]), 10.0, 14.0
LAYERS = [{"sigma_a": 0.05, "sigma_s": [0.3, 0.2, 0.1], "scale_height": 1.0},
          {"sigma_s": 0.05, "phase": {"type": "hg", "g": 0.6}, "scale_height": 0.5}]
MEDIUM = {"type": "atmosphere", "radius": R, "top_radius": TOP, "center": CENTER.tolist(), "layer": LAYERS}
CAMERA = {**penumbra.CAMERA, "width": 8, "height": 6}  # its view in fewer pixels (the twin's cost)
CHANNELS = (0, 2)
PANELS, LINE = 6, 4  # over the emitter and along each lit piece (penumbra's NODES each): ~1e-4 is plenty for the test
COLUMN = 8  # Gauss–Legendre nodes of a column (5.5e-7 from mpmath at worst: the twin's 1e-6 is plenty for the test)
BLOCK = 256  # emitter points at a time (memory)


def _coefficients(layer, key, c):
    value = layer.get(key, 0.0)
    return float(value[c] if isinstance(value, list) else value)


def _phase(layer, cos):
    """4 pi p(cos): 1 for the isotropic phase."""
    if "phase" not in layer:
        return np.ones_like(cos)
    g = layer["phase"]["g"]
    return (1.0 - g * g) / (1.0 + g * g - 2.0 * g * cos) ** 1.5


def column(p, q, H):
    """int_p^q e^{-(|x - c| - R) / H} along the segment (..., 3) -> (...,): COLUMN Gauss–Legendre nodes."""
    x, w = roots_legendre(COLUMN)
    s = 0.5 * (x + 1.0)
    d = q - p
    pts = p[..., None, :] + s[:, None] * d[..., None, :] - CENTER
    alt = np.sqrt(np.einsum("...i,...i->...", pts, pts)) - R
    return np.sqrt(np.einsum("...i,...i->...", d, d)) * (np.exp(-alt / H) @ (0.5 * w))


def exact_column(p, q, H):
    """The same by mpmath's quad at 30 digits (the check of `column`)."""
    with mpmath.workdps(30):
        p, d = [mpmath.mpf(float(v)) for v in p], [mpmath.mpf(float(b - a)) for a, b in zip(p, q)]
        c = [mpmath.mpf(float(v)) for v in CENTER]
        length = mpmath.sqrt(sum(v * v for v in d))
        f = lambda s: mpmath.exp(-(mpmath.sqrt(sum((a + s * b - e) ** 2 for a, b, e in zip(p, d, c))) - R) / H)
        return float(length * mpmath.quad(f, [0, 1]))


def air(o, t, p, y, r, channel):
    """4 pi sum_i ks_i rho_i(x) p_i e^{-sum_i kt_i (tau_i(o, x) + tau_i(x, y))} at x = p of one channel
    (`penumbra._line`'s medium: its 1 / (4 pi) is the isotropic phase), by blocks of emitter points."""
    out = np.empty(p.shape[:-1])
    for b in range(0, len(p), BLOCK):
        x, yb, rb = p[b:b + BLOCK], np.broadcast_to(y[b:b + BLOCK], p[b:b + BLOCK].shape), r[b:b + BLOCK]
        w = x - o
        w /= np.maximum(np.linalg.norm(w, axis=-1, keepdims=True), 1e-300)
        cos = -np.einsum("mki,mki->mk", x - yb, w) / np.maximum(rb, 1e-300)
        alt = np.linalg.norm(x - CENTER, axis=-1) - R
        depth, scatter = 0.0, 0.0
        for layer in LAYERS:
            H = layer["scale_height"]
            ks = _coefficients(layer, "sigma_s", channel)
            kt = ks + _coefficients(layer, "sigma_a", channel)
            depth = depth + kt * (column(np.broadcast_to(o, x.shape), x, H) + column(x, yb, H))
            scatter = scatter + ks * np.exp(-alt / H) * _phase(layer, cos)
        out[b:b + BLOCK] = scatter * np.exp(-depth)
    return out


def rays():
    """(origin (3,), directions (H, W, 3)) of CAMERA's pixel centres."""
    o = np.array(CAMERA["position"], float)
    return o, camera_rays(o, CAMERA["look_at"], [0.0, 1.0, 0.0], CAMERA["fov"], CAMERA["width"], CAMERA["height"])


def pixel(o, w, channel, panels=PANELS, line=LINE):
    return penumbra.pixel(o, w, panels, line, functools.partial(air, channel=channel))


def main():
    rng = np.random.default_rng(1)
    lines = [(rng.uniform([-4, 0, -4], [4, 2, 4]), rng.uniform([-4, 0, -4], [4, 2, 4])) for _ in range(8)]
    lines.append((np.array(CAMERA["position"], float), np.array([5.5, 0.0, -4.0])))  # the longest kind
    worst = max(abs(column(p, q, layer["scale_height"]) / exact_column(p, q, layer["scale_height"]) - 1.0)
                for p, q in lines for layer in LAYERS)
    print(f"columns against mpmath (30 digits): largest relative difference {worst:.2e}")
    o, dirs = rays()
    images, spreads = [], []
    for c in CHANNELS:
        image = np.array([[pixel(o, d, c) for d in row] for row in dirs])
        some = [divmod(k, image.shape[1]) for k in range(0, image.size, 4)]
        spreads.append(max(abs(pixel(o, dirs[q], c, 2 * PANELS, 2 * LINE) / image[q] - 1.0) for q in some))
        print(f"channel {c}: largest relative difference to {2 * PANELS} panels and {2 * LINE} along the ray (every "
              f"4th pixel): {spreads[-1]:.2e}")
        images.append(image.tolist())
    OUT.write_text(json.dumps({"doc": "tests/make_montecarlo_atmosphere_twins.py", "panels": PANELS, "line": LINE,
                               "column": COLUMN, "column_error": worst, "channels": list(CHANNELS),
                               "spread": spreads, "image": images}, indent=1) + "\n")


if __name__ == "__main__":
    main()
