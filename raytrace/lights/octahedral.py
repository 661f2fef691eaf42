"""pbrt-v4's equal-area octahedral map of the sphere (Clarberg 2008, "Fast Equal-Area Mapping of the
(Hemi)Sphere using SIMD"; pbrt-v4 util/math.cpp EqualAreaSquareToSphere / EqualAreaSphereToSquare),
the parametrisation of pbrt-v4's environment maps (lights.cpp ImageInfiniteLight).

In pbrt's frame, with p = (2u - 1, 2v - 1) and the signed distance d = 1 - |p_x| - |p_y| from the
square's inscribed diamond, r = 1 - |d|: z = sign(d)(1 - r^2), the azimuth in p's quadrant is
phi = (pi/4)((|p_y| - |p_x|)/r + 1) from the x axis, and the horizontal radius is r sqrt(2 - r^2). So
+z is the square's centre, -z its four corners, and the diamond the upper hemisphere. The map
preserves area: a region of area a of the square covers the solid angle 4 pi a, so every texel of an
N x N map spans 4 pi / N^2. The inverse is exact here (atan2) where pbrt-v4 evaluates atan by a
degree-6 minimax polynomial (a difference of ~1e-6 in u, v: a texel apart only within that of an edge).

The environment light (environment.py) holds an octahedral map in its own frame, whose +y (up) is
the square's centre: pbrt's (x, y, z) = (x, -z, y) of ours (`TO_PBRT`), so u runs toward +x and v
toward -z (the equirectangular map's centre column).
"""
from __future__ import annotations

import numpy as np

TO_PBRT = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # pbrt's frame = TO_PBRT @ ours


def square_to_sphere(u, v) -> np.ndarray:
    """(n, 3) unit directions in pbrt's frame of the points (u, v) of [0, 1]^2 (EqualAreaSquareToSphere)."""
    px, py = 2.0 * np.asarray(u, float) - 1.0, 2.0 * np.asarray(v, float) - 1.0
    ax, ay = np.abs(px), np.abs(py)
    d = 1.0 - (ax + ay)
    r = 1.0 - np.abs(d)
    phi = np.where(r == 0.0, 1.0, (ay - ax) / np.where(r == 0.0, 1.0, r) + 1.0) * (np.pi / 4.0)
    radius = r * np.sqrt(np.maximum(0.0, 2.0 - r * r))
    return np.stack([np.copysign(np.cos(phi), px) * radius, np.copysign(np.sin(phi), py) * radius,
                     np.copysign(1.0 - r * r, d)], axis=-1)


def sphere_to_square(d) -> tuple[np.ndarray, np.ndarray]:
    """(u, v) in [0, 1]^2 of unit directions (n, 3) in pbrt's frame (EqualAreaSphereToSquare, atan exact)."""
    d = np.asarray(d, float)
    x, y, z = np.abs(d[:, 0]), np.abs(d[:, 1]), np.abs(d[:, 2])
    r = np.hypot(x, y) / np.sqrt(1.0 + z)  # sqrt(1 - |z|), without its cancellation near the poles
    phi = np.arctan2(y, x) * (2.0 / np.pi)  # in [0, 1] over the first quadrant
    b = phi * r
    a = r - b
    south = d[:, 2] < 0.0
    a, b = np.where(south, 1.0 - b, a), np.where(south, 1.0 - a, b)  # the lower hemisphere: folded out
    return 0.5 * (np.copysign(a, d[:, 0]) + 1.0), 0.5 * (np.copysign(b, d[:, 1]) + 1.0)


def texels(local, size: int) -> tuple[np.ndarray, np.ndarray]:
    """(row, column) of the texels of an N x N map (row 0 the file's first scanline, at v = 0) that the
    directions (n, 3) in the light's frame fall in (pbrt-v4's LookupNearest; the square's edge, where
    pbrt mirrors across the seam to the texel adjacent there, is clamped)."""
    u, v = sphere_to_square(np.asarray(local, float) @ TO_PBRT.T)
    return (np.minimum((v * size).astype(np.int64), size - 1), np.minimum((u * size).astype(np.int64), size - 1))


def directions(u, v) -> np.ndarray:
    """(n, 3) directions in the light's frame of the points (u, v) of the square."""
    return square_to_sphere(u, v) @ TO_PBRT

