"""The shadow rays of surface points toward a point light as `Accelerator.shadow_rays` makes them
(accel.py), in a kernel of their own: Embree's wrapper calls it, and so do the surface term's kernels
that make the rays of several lights in one pass (shading.py), which may not import Embree."""
import math

import numpy as np

from ..jit import exact_njit


@exact_njit
def shadow_rays_into(points, normals, idx, first, end, light, eps, unit, o, d, t, o32, d32, t32):
    """`Accelerator.shadow_rays` of the points idx[first:end] into rows first:end of o, d, t and their
    float32 copies in units of `unit` (rows of several lights' rays: shading.py), each
    number rounded as the NumPy expressions it replaced round them: side = sign(n . (light - p))
    (summed as einsum sums three terms), o = p + side eps n, d = (light - o) / |light - o|,
    t = |light - o| - eps."""
    for i in range(first, end):
        k = idx[i]
        dot = (normals[k, 0] * (light[0] - points[k, 0]) + normals[k, 2] * (light[2] - points[k, 2])) \
            + normals[k, 1] * (light[1] - points[k, 1])
        side = (1.0 if dot > 0.0 else -1.0 if dot < 0.0 else 0.0 if dot == 0.0 else dot) * eps  # np.sign
        for a in range(3):
            o[i, a] = points[k, a] + side * normals[k, a]
            d[i, a] = light[a] - o[i, a]
        length = math.sqrt(d[i, 0] * d[i, 0] + d[i, 1] * d[i, 1] + d[i, 2] * d[i, 2])
        over = length if length > 0 else 1.0
        for a in range(3):
            d[i, a] = d[i, a] / over
            o32[i, a] = np.float32(o[i, a] if unit == 1.0 else o[i, a] / unit)
            d32[i, a] = np.float32(d[i, a])
        t[i] = length - eps
        clamped = t[i] if t[i] >= 0.0 or math.isnan(t[i]) else 0.0  # np.maximum(t, 0)
        t32[i] = np.float32(clamped if unit == 1.0 else clamped / unit)
