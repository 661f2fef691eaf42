"""The sun's refracted beams in a convex refractive shape of more face planes than the index-matched
kernel's KERNEL_PLANES (the 320-face glass icosphere of tests/test_refracted_mesh_sun.py), attenuated by
another, index-matched interior on their entry points' way to the sun (interiors/rows.py `_face_beams`
with `_other_interiors(..., many=True)`: shadows/through_others.py on each beam's face plane): a dense
absorbing box above part of the ball. Before, these beams were not attenuated and the bound was infinite.

The twin uses the geometry alone, as tests/test_refracted_mesh_sun.py's (each triangle's beam by Snell and
Fresnel by angles, its lit interval by barycentric coordinates, which are affine in x) times
exp(-kt_B c_B), c_B the chord of the path from the entry point Y(x) = p + x w + s(x) u toward the sun
through the dense box by a slab test (as tests/test_beams_through_others.py's); Y is affine in x, so scipy
quad is cut where that path meets an edge of the box (solved from Y's line) and where the faces it
crosses change (bisected).
"""
import math

import numpy as np
from scipy import integrate

from . import oracle
from .test_bounded_media import fresnel_t, slab, snell
from .test_refracted_beams import switches
from .test_refracted_mesh_faces import barycentric
from .test_refracted_mesh_sun import OUTSIDE, SUN, ball, check, twin
from .test_refracted_mesh_faces import triangles
from .test_through_others import edge_crossings

LO_B, HI_B = np.array([-2.0, 1.4, -1.6]), np.array([-0.2, 2.0, -0.3])
DENSE = {"sigma_a": [1.5, 1.0, 0.5], "sigma_s": [0.0, 0.0, 0.0]}
TOWARD_SUN = -np.array(SUN["direction"], float) / np.linalg.norm(SUN["direction"])


def dense_chord(P):
    """(chord, the faces it enters and leaves by) of the path from P toward the sun through the dense box."""
    hit = slab(P, TOWARD_SUN, LO_B, HI_B)
    if hit is None or hit[1] <= 0.0:
        return 0.0, None
    leave = [max((LO_B[a] - P[a]) / TOWARD_SUN[a], (HI_B[a] - P[a]) / TOWARD_SUN[a]) for a in range(3)]
    return hit[1] - max(hit[0], 0.0), (tuple(hit[2]), int(np.argmin(leave)))


def dense_segment(scene, geometry, p, w, ell, dense=True):
    """The sun's single scattering (3,) over the inside segment p + x w, x in [0, ell], each beam times
    exp(-kt_B c_B) of its entry point's path to the sun (module docstring)."""
    tri, normals, offsets = geometry
    inner = scene["shape"][0]["interior"]
    eta, g = inner["ior"], inner["phase"]["g"]
    ks = np.array(inner["sigma_s"], float)
    kt = np.array(inner["sigma_a"], float) + ks
    kt_b = np.array(DENSE["sigma_a"], float) if dense else np.zeros(3)
    s = -TOWARD_SUN
    out = np.zeros(3)
    for f in np.nonzero(normals @ s < 0.0)[0]:
        n, c = normals[f], offsets[f]
        t, ti, tt = snell(s, n, eta)
        e = SUN["irradiance"] * fresnel_t(ti, tt, eta) * math.cos(ti) / math.cos(tt)
        u = -t
        depth = lambda x: (c - n @ (p + x * w)) / (n @ u)  # noqa: E731
        entry = lambda x: p + x * w + depth(x) * u  # noqa: E731
        b0, b1 = barycentric(entry(0.0)[None, :], tri[f])[0], barycentric(entry(ell)[None, :], tri[f])[0]
        lo, hi = 0.0, ell
        for a, b in zip(b0, b1):  # a + (b - a) x / ell >= 0
            if b == a:
                hi = hi if a >= 0.0 else -1.0
            elif b > a:
                lo = max(lo, -a * ell / (b - a))
            else:
                hi = min(hi, -a * ell / (b - a))
        if not hi > lo:
            continue
        ph = oracle.phase("hg", g, float(u @ w))
        P0, line = entry(lo), entry(lo + 1.0) - entry(lo)
        cuts = [lo + x for x in edge_crossings(P0, line, TOWARD_SUN, LO_B, HI_B, hi - lo)]
        cuts += [lo + x for x in switches(P0, line, hi - lo, lambda Y: str(dense_chord(Y)[1]))]
        edges = [lo, *sorted(cuts), hi]
        for a, b in zip(edges, edges[1:]):
            if b > a:
                out += e * ks * ph * integrate.quad_vec(
                    lambda x: np.exp(-kt * (x + depth(x)) - kt_b * dense_chord(entry(x))[0]), a, b, epsabs=0.0,
                    epsrel=1e-12, limit=400)[0]
    return out


def test_a_dense_box_attenuates_the_beams_of_a_320_face_ball():
    """Volumetric shadows: quadrature (rtol 1e-6) within 1e-6 and analytic (the beams through the box by
    QUAD, counted handed) within 1e-6 of the twin with the dense box on every pixel; their bounds finite,
    above the error, median at most 10 rtol of the value; not vacuous: the box darkens some pixel by more
    than 5 % against the twin without it (before, these beams went unattenuated and the bound was
    infinite)."""
    scene = ball(OUTSIDE, SUN)
    scene["shape"].append({"primitive": "box", "min": LO_B.tolist(), "max": HI_B.tolist(), "interior": DENSE})
    geometry = triangles(scene)
    ref = twin(scene, geometry, dense_segment)
    free = twin(scene, geometry, lambda *a: dense_segment(*a, dense=False))
    assert np.max(1.0 - ref[..., 1] / free[..., 1]) > 0.05, np.max(1.0 - ref[..., 1] / free[..., 1])
    for method, params in (("quadrature", {"rtol": 1e-6}), ("analytic", {})):
        res = check(scene, ref, method, params, 1e-6, 1e-5, shadows=True)
        print(method, "largest relative error", np.max(np.abs(res.image - ref) / ref),
              "median bound / value", np.median(res.error_bound / ref))
