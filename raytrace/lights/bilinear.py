"""An equirectangular environment map interpolated bilinearly in (theta, phi) (environment.py's
`filter`), sampled exactly in proportion to the interpolated luminance.

The map's values are nodes of a grid: columns at the texel centres phi_c = 2 pi ((c + 1/2) / W - 1/2),
periodic in phi; rows at theta_r = pi (r + 1/2) / H with "bilinear" (texel centres; constant in
theta from each pole to the first and last centres), at theta_r = pi r / (H - 1) with "mitsuba"
(Mitsuba 3's envmap.cpp: the first and last rows on the poles). Between nodes L is bilinear in
(theta, phi): cell i spans [Theta_i, Theta_i+1], s = (theta - Theta_i) / Delta_i, and t likewise in phi.

Sampling has density Y(w) / Z per steradian, Y the interpolated luminance and Z its integral over the
sphere, so a grey map gives every direction the same L / pdf = Z. With P_k = (2 pi / W) sum_c Y_kc
(the exact integral over phi of node row k, piecewise linear) the integral of Y over cell row i is
P_i A0_i + P_i+1 A1_i, A1_i = int sin(theta) s dtheta = (sin Theta_i+1 - sin Theta_i) / Delta_i -
cos Theta_i+1 and A0_i = cos Theta_i - cos Theta_i+1 - A1_i. A point u of [0, 1)^2 picks the cell row by
u0 and then theta inside it from its marginal sin(theta)((1 - s) P_i + s P_i+1), whose primitive
G(theta) = P_i (cos Theta_i - cos theta) + (P_i+1 - P_i)((sin theta - sin Theta_i) / Delta_i - s cos theta)
is inverted by bisection; u1 picks the column cell from the row at that theta, g = (1 - s) Y_i + s Y_i+1,
(cell weights (g_c + g_c+1) / 2) and t inside it from the linear density, by its quadratic's root.
"""
from __future__ import annotations

import numpy as np

BISECTIONS = 64  # halvings of s in [0, 1]: to the last bit of a double


def nodes(height: int, filt: str) -> tuple[np.ndarray, np.ndarray]:
    """(theta nodes (K + 1,), the map's row at each node (K + 1,))."""
    if filt == "mitsuba":
        return np.pi * np.arange(height) / (height - 1), np.arange(height)
    return (np.concatenate([[0.0], np.pi * (np.arange(height) + 0.5) / height, [np.pi]]),
            np.concatenate([[0], np.arange(height), [height - 1]]))


def _moments(theta) -> tuple[np.ndarray, np.ndarray]:
    """(A0, A1) (K,): the integrals of sin(theta)(1 - s) and sin(theta) s over each cell row."""
    delta = np.diff(theta)
    a1 = (np.sin(theta[1:]) - np.sin(theta[:-1])) / delta - np.cos(theta[1:])
    return np.cos(theta[:-1]) - np.cos(theta[1:]) - a1, a1


def _rows(image, filt: str):
    """(theta nodes, node rows, P (K + 1, ...): the exact phi-integral of each node row (the trapezoid rule
    of a periodic piecewise linear function), the integral over each cell row (K, ...)) of `image`
    (H, W, ...): RGB or luminance."""
    theta, rows = nodes(image.shape[0], filt)
    p = 2.0 * np.pi / image.shape[1] * image.sum(axis=1)[rows]
    a0, a1 = _moments(theta)
    return theta, rows, p, np.einsum("k,k...->k...", a0, p[:-1]) + np.einsum("k,k...->k...", a1, p[1:])


def integral(image, filt: str) -> np.ndarray:
    """The integral of the interpolated L over the sphere per channel (exact)."""
    return _rows(image, filt)[3].sum(axis=0)


def _value(image, rows, i, s, c, t):
    """The bilinear interpolation (n, 3) in cells (i, c) at (s, t): node rows rows[i], rows[i + 1], columns
    c and c + 1 (periodic)."""
    s, t = s[:, None], t[:, None]
    r0, r1, c1 = rows[i], rows[i + 1], (c + 1) % image.shape[1]
    return ((1.0 - s) * ((1.0 - t) * image[r0, c] + t * image[r0, c1]) +
            s * ((1.0 - t) * image[r1, c] + t * image[r1, c1]))


def sample(image, filt: str, luma_weights, u) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(local directions (n, 3), pdf per steradian (n,), L (n, 3)) of the points u (n, 2) of [0, 1)^2."""
    W = image.shape[1]
    luma = image @ luma_weights
    theta, rows, p, row = _rows(luma, filt)
    cum = np.cumsum(row)
    total = cum[-1]
    i = np.minimum(np.searchsorted(cum, u[:, 0] * total, side="right"), len(row) - 1)
    start = np.concatenate([[0.0], cum])[i]
    target = np.clip(u[:, 0] * total - start, 0.0, row[i])
    t0, delta, p0, dp = theta[i], np.diff(theta)[i], p[i], p[i + 1] - p[i]
    lo, hi = np.zeros(len(i)), np.ones(len(i))
    for _ in range(BISECTIONS):
        s = 0.5 * (lo + hi)
        th = t0 + s * delta
        below = p0 * (np.cos(t0) - np.cos(th)) + dp * ((np.sin(th) - np.sin(t0)) / delta - s * np.cos(th)) < target
        lo, hi = np.where(below, s, lo), np.where(below, hi, s)
    s = 0.5 * (lo + hi)
    g = (1.0 - s)[:, None] * luma[rows[i]] + s[:, None] * luma[rows[i + 1]]  # (n, W): the row at theta
    g = np.concatenate([g, g[:, :1]], axis=1)  # periodic
    cells = np.cumsum(0.5 * (g[:, :-1] + g[:, 1:]), axis=1)
    want = u[:, 1] * cells[:, -1]
    c = np.minimum((cells <= want[:, None]).sum(axis=1), W - 1)  # skips cells of weight 0
    n = np.arange(len(c))
    before = np.where(c > 0, cells[n, c - 1], 0.0)
    g0, g1 = g[n, c], g[n, c + 1]
    f = np.clip((want - before) / np.maximum(0.5 * (g0 + g1), 1e-300), 0.0, 1.0)
    t = f * (g0 + g1) / np.maximum(g0 + np.sqrt((1.0 - f) * g0 * g0 + f * g1 * g1), 1e-300)
    value = _value(image, rows, i, s, c, t)
    return (_direction(t0 + s * delta, 2.0 * np.pi * ((c + 0.5 + t) / W - 0.5)), value @ luma_weights / total,
            value)


def _direction(theta, phi):
    """Directions (n, 3) of the equirectangular mapping: theta from +y, phi from -z toward +x."""
    st = np.sin(theta)
    return np.stack([st * np.sin(phi), np.cos(theta), -st * np.cos(phi)], axis=1)


def radiance(image, filt: str, local) -> np.ndarray:
    """L (n, 3) toward the local directions (n, 3)."""
    W = image.shape[1]
    theta, rows = nodes(image.shape[0], filt)
    x, y, z = np.asarray(local, float).T
    th = np.arctan2(np.hypot(x, z), y)
    i = np.clip(np.searchsorted(theta, th, side="right") - 1, 0, len(theta) - 2)
    s = np.clip((th - theta[i]) / np.diff(theta)[i], 0.0, 1.0)
    q = np.mod((np.arctan2(x, -z) / (2.0 * np.pi) + 0.5) * W - 0.5, W)  # in columns from column 0's centre
    c = np.minimum(q.astype(np.int64), W - 1)
    return _value(image, rows, i, s, c, q - c)


def pdf(image, filt: str, luma_weights, local) -> np.ndarray:
    """The sampling density (n,) per steradian of the local directions (n, 3): Y(w) / Z."""
    return radiance(image, filt, local) @ luma_weights / integral(image @ luma_weights, filt)
