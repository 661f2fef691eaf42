"""Cameras (SCENE_FORMAT.md conventions) and the deterministic pixel-sample pattern every method shares.

Image row 0 is the top. Perspective: pixel (i, j) with offset (s, t) looks along
forward + (2(i+s)/W - 1) tan(fov/2) (W/H) right + (1 - 2(j+t)/H) tan(fov/2) up, with
right = normalize(forward x up) and up re-orthogonalised. Environment (equirectangular):
phi = 2 pi ((i+s)/W - 0.5) from forward towards right, theta = pi (j+t)/H from up.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from .jit import exact_njit
from .scene.format import Camera


@functools.lru_cache(maxsize=16)
def sample_offsets(spp: int) -> np.ndarray:
    """(spp, 2) offsets in [0, 1)^2: the pixel centre for spp = 1, a stratified grid of cell centres
    when spp is a square, otherwise the R2 low-discrepancy sequence (deterministic). Computed once
    per spp (every tile asks): read-only."""
    return _read_only(_offsets(spp))


def _read_only(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


def _offsets(spp: int) -> np.ndarray:
    if spp == 1:
        return np.array([[0.5, 0.5]])
    n = math.isqrt(spp)
    if n * n == spp:
        a = (np.arange(n) + 0.5) / n
        s, t = np.meshgrid(a, a, indexing="xy")
        return np.stack([s.ravel(), t.ravel()], axis=1)
    phi = 1.32471795724474602596  # plastic number
    k = np.arange(1, spp + 1)
    return np.stack([(0.5 + k / phi) % 1.0, (0.5 + k / phi**2) % 1.0], axis=1)


def basis(cam: Camera):
    """(forward, right, up) unit vectors of the camera (read-only, computed once per placement)."""
    return _basis(_floats(cam.position), _floats(cam.look_at), _floats(cam.up))


def _floats(v) -> tuple:
    """A vector's entries as a tuple of Python floats (the values float() gives; `tolist`, not a loop
    over NumPy scalars: every tile asks)."""
    return tuple(np.asarray(v, np.float64).tolist())


@functools.lru_cache(maxsize=16)
def _basis(position: tuple, look_at: tuple, cam_up: tuple):
    position, look_at, cam_up = np.array(position), np.array(look_at), np.array(cam_up)
    forward = look_at - position
    forward = forward / np.linalg.norm(forward)
    right = np.cross(forward, cam_up)
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    return tuple(_read_only(v) for v in (forward, right, up))


def generate_rays(cam: Camera, rows: slice | None = None, cols: slice | None = None, samples: slice | None = None):
    """Rays of the pixel block rows x cols (the pixel samples `samples`, default all), every sample
    of a pixel consecutive.

    Returns origins (N, 3), unit directions (N, 3) in float64, with N = rows * cols * samples, in the
    order (row, column, sample)."""
    rows = rows or slice(0, cam.height)
    cols = cols or slice(0, cam.width)
    j = np.arange(rows.start, rows.stop, dtype=np.float64)
    i = np.arange(cols.start, cols.stop, dtype=np.float64)
    return _rays(cam, np.tile(i, len(j)), np.repeat(j, len(i)), sample_offsets(cam.spp)[samples or slice(None)])


def pixel_rays(cam: Camera, ys: np.ndarray, xs: np.ndarray, samples: slice | None = None):
    """Rays of the pixels (ys[k], xs[k]) (the pixel samples `samples`, default all), every sample
    of a pixel consecutive: each ray the same as generate_rays gives it."""
    off = sample_offsets(cam.spp)[samples or slice(None)]
    return _rays(cam, np.ascontiguousarray(xs, np.float64), np.ascontiguousarray(ys, np.float64), off)


def _rays(cam: Camera, xs: np.ndarray, ys: np.ndarray, off: np.ndarray):
    """Origins and unit directions through the image points (xs[p] + off[s, 0], ys[p] + off[s, 1])
    (pixel units; xs, ys (P,), off (S, 2)), in the order (p, s)."""
    forward, right, up = basis(cam)
    o, d = np.empty((len(xs) * len(off), 3)), np.empty((len(xs) * len(off), 3))
    perspective = cam.type == "perspective"
    tan = math.tan(math.radians(cam.fov) / 2.0) if perspective else 0.0
    memo = np.full((0 if perspective else len(off), TRIG_SLOTS + 1, 3), np.nan)
    _ray_kernel(xs, ys, off, float(cam.width), float(cam.height), perspective, tan, cam.width / cam.height, forward,
                right, up, np.asarray(cam.position, np.float64), o, d, memo)
    return o, d


TRIG_SLOTS = 31  # an environment camera's remembered columns per sample (`_ray_kernel`): prime, so that a tile's
# columns (every 128th pixel of the raster order: 4 of 512, 8 of 1024) fall in different slots


@exact_njit
def _ray_kernel(xs, ys, off, W, H, perspective, tan, aspect, forward, right, up, position, o, d, memo):
    """The rays of the module's formulas (`perspective`, else environment) through the points
    (xs[p] + off[s, 0], ys[p] + off[s, 1]), ray p S + s, into o and d, each number rounded as the NumPy
    expressions this kernel replaced round it (the point's two sums among them). An environment ray's
    sines and cosines are those of its phi and theta, computed once per value: memo (S, TRIG_SLOTS + 1,
    3), NaN on entry, keeps per sample the last x of each slot (by column) with cos and sin of its phi,
    and in its last row the last y with sin and cos of its theta (a tile's rays take a few columns,
    row after row)."""
    S = off.shape[0]
    K = memo.shape[1] - 1
    for p in range(xs.shape[0]):
        for s in range(S):
            i = p * S + s
            x, y = xs[p] + off[s, 0], ys[p] + off[s, 1]
            if perspective:
                a = (2.0 * x / W - 1.0) * tan * aspect
                b = (1.0 - 2.0 * y / H) * tan
                for k in range(3):
                    d[i, k] = forward[k] + a * right[k] + b * up[k]
            else:
                slot = math.floor(xs[p]) % K if abs(xs[p]) < 1e15 else 0  # (int() compiles an overload of its own)
                if memo[s, slot, 0] != x:
                    phi = (2.0 * math.pi) * (x / W - 0.5)
                    memo[s, slot, 0], memo[s, slot, 1], memo[s, slot, 2] = x, math.cos(phi), math.sin(phi)
                if memo[s, K, 0] != y:
                    theta = math.pi * y / H
                    memo[s, K, 0], memo[s, K, 1], memo[s, K, 2] = y, math.sin(theta), math.cos(theta)
                cp, sp, st, ct = memo[s, slot, 1], memo[s, slot, 2], memo[s, K, 1], memo[s, K, 2]
                for k in range(3):
                    d[i, k] = st * (cp * forward[k] + sp * right[k]) + ct * up[k]
            length = math.sqrt(d[i, 0] * d[i, 0] + d[i, 1] * d[i, 1] + d[i, 2] * d[i, 2])
            for k in range(3):
                d[i, k] = d[i, k] / length
                o[i, k] = position[k]
