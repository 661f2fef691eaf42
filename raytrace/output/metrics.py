"""Errors of an image against a reference, and error maps coloured like the paper's fig. 6.

The map shows the absolute error per pixel (mean over channels) as a hue from blue (0) through
cyan, green and yellow to red (the top of the scale); the scale is written on the image.
"""
from __future__ import annotations

import numpy as np

from ..errors import UserError


def errors(test: np.ndarray, ref: np.ndarray) -> dict:
    """Mean absolute, RMS and mean relative error over pixels and channels (relative error uses
    |ref| floored at 1e-3 of the mean |ref| so that black pixels do not dominate), plus the max."""
    if test.shape != ref.shape:
        raise UserError(f"images differ in size: {test.shape[1]}x{test.shape[0]} vs "
                        f"{ref.shape[1]}x{ref.shape[0]}; render both at the same resolution")
    diff = np.abs(test - ref)
    mean_ref = float(np.mean(np.abs(ref)))
    floor = max(1e-3 * mean_ref, 1e-300)
    rel = diff / np.maximum(np.abs(ref), floor)
    return {
        "mean_abs": float(diff.mean()),
        "rms": float(np.sqrt(np.mean(diff ** 2))),
        "mean_rel": float(rel.mean()),
        "max_rel": float(rel.max()),
        "max_abs": float(diff.max()),
        "mean_abs_over_mean_ref": float(diff.mean() / mean_ref) if mean_ref > 0 else float("nan"),
    }


def hue_map(values: np.ndarray, vmax: float) -> np.ndarray:
    """Map values in [0, vmax] to RGB8 along the hue wheel from blue (240°) to red (0°)."""
    x = np.clip(values / vmax if vmax > 0 else np.zeros_like(values), 0.0, 1.0)
    h = (1.0 - x) * 4.0  # 4 = blue, 3 = cyan, 2 = green, 1 = yellow, 0 = red (in 60° units)
    c = np.ones_like(h)
    k = h % 2.0
    xx = 1.0 - np.abs(k - 1.0)
    rgb = np.zeros(values.shape + (3,))
    seg = np.floor(h).astype(int).clip(0, 4)
    table = {0: (c, xx, 0 * c), 1: (xx, c, 0 * c), 2: (0 * c, c, xx), 3: (0 * c, xx, c), 4: (0 * c, 0 * c, c)}
    for s, (r, g, b) in table.items():
        m = seg == s
        rgb[m, 0], rgb[m, 1], rgb[m, 2] = r[m], g[m], b[m]
    return (rgb * 255.0 + 0.5).astype(np.uint8)


def shared_scale(images: list[np.ndarray], ref: np.ndarray, percentile: float = 99.0) -> float:
    """One error-map scale for several images of a scene: the given percentile of the per-pixel
    absolute errors pooled over the images, leaving out images whose mean relative error exceeds 1
    (diverged methods, which then show saturated), so that a few extreme pixels or one broken method
    do not turn every other map blue. Pixels above the scale show red."""
    pooled = [np.abs(img - ref).mean(axis=2).ravel() for img in images if errors(img, ref)["mean_rel"] <= 1.0]
    if not pooled:
        pooled = [np.abs(img - ref).mean(axis=2).ravel() for img in images]
    top = float(np.percentile(np.concatenate(pooled), percentile)) if pooled else 0.0
    return top if top > 0.0 else 1e-300


def error_map(test: np.ndarray, ref: np.ndarray, vmax: float | None = None):
    """(RGB8 image with a legend strip, per-pixel absolute error (H, W), the scale's maximum)."""
    from PIL import Image, ImageDraw

    err = np.abs(test - ref).mean(axis=2)
    if vmax is None:
        vmax = float(err.max())
    body = hue_map(err, vmax)
    h, w = err.shape
    bar_h = max(24, h // 12)
    bar = hue_map(np.tile(np.linspace(0.0, vmax, w), (bar_h // 2, 1)), vmax)
    canvas = Image.new("RGB", (w, h + bar_h), (0, 0, 0))
    canvas.paste(Image.fromarray(body, "RGB"), (0, 0))
    canvas.paste(Image.fromarray(bar, "RGB"), (0, h))
    draw = ImageDraw.Draw(canvas)
    y = h + bar_h // 2
    draw.text((2, y), "0", fill=(255, 255, 255))
    label = f"abs. error {vmax:.3g} (and above)"
    draw.text((max(2, w - 6 * len(label) - 2), y), label, fill=(255, 255, 255))
    return np.asarray(canvas), err, vmax


def bound_check(a: np.ndarray, b: np.ndarray, bound_a: np.ndarray, bound_b: np.ndarray, k: float) -> dict:
    """`render.py diff --bounds k`: the pixel-channels where |a - b| > k (bound_a + bound_b), i.e. where
    the two images' error bounds (or, for Monte Carlo, standard errors; docs/error_bounds.md) cannot
    both hold at k; the largest ratio |a - b| / (bound_a + bound_b) (0 where both are 0 and a = b);
    and the pixels whose combined bound is infinite (the check says nothing there)."""
    if a.shape != b.shape or bound_a.shape != a.shape or bound_b.shape != b.shape:
        raise UserError(f"images or bounds differ in size: {a.shape} vs {b.shape}; render both at the same resolution")
    diff = np.abs(a - b)
    combined = bound_a + bound_b
    finite = np.isfinite(combined)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(diff == 0.0, 0.0, diff / np.where(finite, combined, np.inf))
    return {
        "pixels_over_bounds": int(np.count_nonzero((diff > k * combined).any(axis=-1))),
        "max_diff_over_bounds": float(ratio.max()) if ratio.size else 0.0,
        "pixels_infinite_bound": int(np.count_nonzero((~finite).any(axis=-1))),
    }
