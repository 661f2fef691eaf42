"""The noise-free twin of an occluded quad light's air-light in a height fog, for Monte Carlo's z-test in its
penumbra (tests/test_montecarlo_fog_penumbra.py), from the geometry alone (numpy, no project code): the scene of
tests/make_montecarlo_penumbra_twins.py (its quad, plate, black floor and wall, camera, and its rules over the
emitter and along the ray) in an exponential fog of density rho(h) = e^{-h / H} along y (h0 = 0):

    L(ray) = 1 / (4 pi) int_emitter dA(y) int_lit(y) L (2 - x_y) ks rho(x_y) e^{-kt (tau(o, x) + tau(x, y))} / r^3 dt,

with the closed-form column between two points, tau(p, q) = |q - p| e^{-p_y / H} (1 - e^{-z}) / z,
z = (q_y - p_y) / H (1 at z = 0).

    python -m tests.make_montecarlo_fog_twins     # about six CPU minutes; writes tests/data/montecarlo_fog_twins.json
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from . import make_montecarlo_penumbra_twins as penumbra

OUT = Path(__file__).parent / "data" / "montecarlo_fog_twins.json"

KT, KS, H = 0.5, 0.4, 0.8  # at h0 = 0 (the floor)
MEDIUM = {"type": "height_fog", "sigma_a": KT - KS, "sigma_s": KS, "up": [0.0, 1.0, 0.0], "h0": 0.0,
          "scale_height": H}


def column(p, q):
    """The unit column int rho between the points p and q (..., 3) along the straight line."""
    length = np.linalg.norm(q - p, axis=-1)
    z = (q[..., 1] - p[..., 1]) / H
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(z == 0.0, 1.0, -np.expm1(-z) / z)
    return length * np.exp(-p[..., 1] / H) * ratio


def fog(o, t, p, y, r):
    """ks rho(x) e^{-kt (tau(o, x) + tau(x, y))} at x = p (`penumbra._line`'s medium)."""
    return KS * np.exp(-p[..., 1] / H - KT * (column(np.broadcast_to(o, p.shape), p) + column(p, y)))


if __name__ == "__main__":
    penumbra.write(OUT, fog, "tests/make_montecarlo_fog_twins.py")
