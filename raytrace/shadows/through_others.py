"""The light of a point, spot or directional light inside a convex index-matched shape, attenuated by
the other index-matched interiors its straight path crosses on the way out.

Inside shape A the single-scattering integrand of media/slab.py `convex_integrand` carries the
outside's extinction kt_out over the light's path outside A. Where that path crosses another
index-matched convex shape B_j (chord c_j, media/convex_chords.py `chord`), the light is attenuated
by B_j's extinction instead over c_j: the integrand times exp(-sum_j (kt_j - kt_out) c_j) (A and the
B_j do not overlap, so c_j is B_j's chord of the whole path from the point to the light). The
chords change slope where the path toward the light passes a vertex of the polygon the plane through
the segment and the light cuts from B_j (`section_kinks`), so `quadrature` starts its adaptive rule
from those points as well as A's own kinks and a spot's cone crossings; `raymarch` and `montecarlo`
evaluate the same integrand with their own rules (media/slab.py `_march_or_sample`).

A directional light (geo's light columns: the unit direction u toward it) takes the path X + s u,
s >= 0, and the integrand ks Phi(w·u) exp(-kt (x + k)) (the outside medium does not attenuate it:
media/slab.py) times exp(-sum_j kt_j c_j) (dk[j] = kt_j: the light crosses B_j instead of nothing).
All its paths lie in the plane through the segment along u, and c_j changes slope where the path
passes a vertex of the polygon that plane cuts from B_j (`section_kinks(..., directional=True)`),
A's own path where it passes one of A's.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..jit import njit
from ..media.convex_chords import PLANES, chord, section_kinks
from ..media.integrand import integrand_of
from ..media.phase import phase_value
from ..media.slab import _N10, _N20, _W10, _W20, MARCH, QUAD, _march_or_sample, convex_integrand, straight_cuts
from ..media.adaptive import piecewise


class AttenuatedConvex(NamedTuple):
    """`convex_integrand` of a point or spot light, or a `directional` one (geo row, the shape's
    planes, one channel) times exp(-sum_j dk[j] chord_j), chord_j through the planes
    others[first[j]:stop[j]]."""
    directional: bool
    geo: np.ndarray
    planes: np.ndarray
    kt: float
    ks: float
    code: int
    g: float
    kt_out: float
    others: np.ndarray
    first: np.ndarray
    stop: np.ndarray
    dk: np.ndarray


@integrand_of(AttenuatedConvex)
@njit
def _attenuated(x, r):
    geo = r.geo
    phase = phase_value(r.code, r.g, geo[3] * geo[6] + geo[4] * geo[7] + geo[5] * geo[8]) if r.directional else 0.0
    v = convex_integrand(x, geo, PLANES, r.planes, r.directional, r.kt, r.ks, r.code, r.g, r.kt_out, phase, -1)
    if v == 0.0:
        return 0.0
    px, py, pz = geo[0] + x * geo[3], geo[1] + x * geo[4], geo[2] + x * geo[5]
    if r.directional:
        ux, uy, uz, dist = geo[6], geo[7], geo[8], math.inf
    else:
        ux, uy, uz = geo[6] - px, geo[7] - py, geo[8] - pz
        dist = math.sqrt(ux * ux + uy * uy + uz * uz)
        if not dist > 0.0:
            return v
        ux, uy, uz = ux / dist, uy / dist, uz / dist
    tau = 0.0
    for j in range(r.first.shape[0]):
        if r.dk[j] != 0.0:
            tau += r.dk[j] * chord(r.others, r.first[j], r.stop[j], px, py, pz, ux, uy, uz, dist)
    return v * math.exp(-tau)


@njit
def attenuated_radiance(directional, geo, planes, ell, kt, ks, code, g, kt_out, others, first, stop, dk, mode, rtol,
                        steps, tau_max, keys, dim0, seed, out, var, stats):
    """out, var (N,) = the attenuated single scattering (`AttenuatedConvex`) of each segment (geo rows,
    unit light, one channel) over [0, ell] and its variance: QUAD adaptive between the kinks of A's
    and every B_j's chords and a spot's cone crossings; MARCH, SAMPLE as media/slab.py's
    `_march_or_sample` (keys, dim0, seed: SAMPLE's random streams)."""
    for s in range(geo.shape[0]):
        out[s], var[s] = 0.0, 0.0
        if ks == 0.0 or not ell[s] > 0.0:
            continue
        rec = AttenuatedConvex(directional, geo[s], planes, kt, ks, code, g, kt_out, others, first, stop, dk)
        if mode == QUAD:
            end = min(ell[s], 745.0 / kt)
            br = np.empty(planes.shape[0] + others.shape[0] + 4 * first.shape[0] + 10)
            br[0] = 0.0
            o, w, light = geo[s, 0:3], geo[s, 3:6], geo[s, 6:9]
            m = 0 if directional else straight_cuts(geo[s], end, br[1:])
            m += section_kinks(planes, 0, planes.shape[0], o, w, light, end, br[1 + m:], directional)
            for j in range(first.shape[0]):
                m += section_kinks(others, first[j], stop[j], o, w, light, end, br[1 + m:], directional)
            br[1:m + 1].sort()
            br[m + 1] = end
            out[s] = piecewise(rec, br, m + 2, rtol, _N10, _W10, _N20, _W20, stats)
        else:
            length = min(ell[s], (tau_max if mode == MARCH else 745.0) / kt)
            out[s], var[s] = _march_or_sample(rec, mode, length, kt, steps, keys[s], dim0, seed)
