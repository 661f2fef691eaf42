"""What a medium is: its coefficients, its phase function, and the transmittance through it.

`homogeneous` (the paper's model) fills all space with extinction kt = sigma_a + sigma_s per
channel: the transmittance over a length t is exp(-kt t). `height_fog` (seed 004) scales both
coefficients, given at the reference height h0, by one density of the height p·up - h0: the
exponential exp(-(p·up - h0)/H) (eq. 32) or the linear max(0, 1 - (p·up - h0)/H) (eq. 28); the
transmittance along a ray is exp(-kt tau) with tau the closed-form unit optical depth of
height_fog.py (eq. 34 / 30), the same for every channel. `atmosphere` (seed 004, Bruneton's
model) is a planet with exponential layers of their own scale heights and phase functions
(`Atmosphere`, atmosphere.py); `sigma_a`, `sigma_s` are then the layers' sums at the ground.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..jit import njit
from .atmosphere import ray_transmittance
from .height_fog import exponential_distance, exponential_optical_depth, linear_distance, linear_optical_depth
from .particles import Particles
from .phase import ISOTROPIC

HOMOGENEOUS = "homogeneous"
HEIGHT_FOG = "height_fog"
ATMOSPHERE = "atmosphere"
EXPONENTIAL, LINEAR = 0, 1  # height-fog profiles
PROFILES = {"exponential": EXPONENTIAL, "linear": LINEAR}


@dataclass
class Atmosphere:
    """A planet (centre, radius, ground reflectance) and K exponential layers of air up to `top`:
    layer i has scale height scale_heights[i], coefficients sigma_a[i], sigma_s[i] (RGB) at the
    ground and the phase function (phases[i], gs[i]) (phase.py codes)."""
    center: np.ndarray
    radius: float
    top: float
    ground: np.ndarray
    names: tuple
    scale_heights: np.ndarray  # (K,)
    sigma_a: np.ndarray  # (K, 3)
    sigma_s: np.ndarray  # (K, 3)
    phases: np.ndarray  # (K,) int64
    gs: np.ndarray  # (K,)

    @property
    def sigma_t(self) -> np.ndarray:
        return self.sigma_a + self.sigma_s

    def inside(self, points: np.ndarray) -> np.ndarray:
        """True for points strictly inside the planet."""
        return np.linalg.norm(np.asarray(points, float) - self.center, axis=-1) < self.radius


@dataclass
class Medium:
    sigma_a: np.ndarray  # height fog: at the reference height h0
    sigma_s: np.ndarray
    phase: int = ISOTROPIC  # a phase.py code
    g: float = 0.0  # Henyey-Greenstein asymmetry
    particles: Particles | None = None  # seed 003's particle layer (particles.py)
    kind: str = HOMOGENEOUS
    up: np.ndarray | None = None  # height fog: unit up vector, reference height, scale height, profile
    h0: float = 0.0
    scale_height: float = math.inf
    profile: int = EXPONENTIAL
    atmosphere: Atmosphere | None = None

    @property
    def sigma_t(self) -> np.ndarray:
        return self.sigma_a + self.sigma_s

    @property
    def scatters(self) -> bool:
        return bool(np.any(self.sigma_s > 0.0))

    @property
    def fog(self) -> tuple:
        """(up x, up y, up z, h0, H, profile): the height fog's arguments of the kernels below."""
        return (*(float(u) for u in self.up), float(self.h0), float(self.scale_height), int(self.profile))

    def transmittance(self, t: np.ndarray) -> np.ndarray:
        """Homogeneous: exp(-kt t) per channel (N, 3) over lengths t (N,), exactly 1 in vacuum
        channels even for t = inf."""
        kt = self.sigma_t
        with np.errstate(invalid="ignore", over="ignore"):  # kt t = inf (huge kt or t): exp(-inf) = 0
            tr = np.exp(-kt[None, :] * np.asarray(t, float)[:, None])
        return np.where(kt[None, :] == 0.0, 1.0, tr)

    def transmittance_on(self, origins, dirs, a, b) -> np.ndarray:
        """Transmittance (N, 3) over [a, b] of the rays origins + t dirs (a, b arrays (N,) or
        scalars; b may be inf); homogeneous: `transmittance(b - a)`."""
        n = len(origins)
        a = np.broadcast_to(np.asarray(a, float), n)
        b = np.broadcast_to(np.asarray(b, float), n)
        if self.kind == HOMOGENEOUS:
            return self.transmittance(b - a)
        if self.kind == ATMOSPHERE:
            atm = self.atmosphere
            out = np.empty((n, 3))
            ray_transmittance(np.ascontiguousarray(origins, float), np.ascontiguousarray(dirs, float),
                              np.ascontiguousarray(a), np.ascontiguousarray(b), *(float(v) for v in atm.center),
                              float(atm.radius), float(atm.top), atm.scale_heights, atm.sigma_t, out)
            return out
        tau = np.empty(n)
        ray_columns(np.ascontiguousarray(origins, float), np.ascontiguousarray(dirs, float),
                    np.ascontiguousarray(a), np.ascontiguousarray(b), *self.fog, tau)
        kt = self.sigma_t
        with np.errstate(invalid="ignore", over="ignore"):  # kt tau = inf (sigma 1e300, H 1e-300): exp(-inf) = 0
            tr = np.exp(-kt[None, :] * tau[:, None])
        return np.where(kt[None, :] == 0.0, 1.0, tr)


@njit
def attenuated_density(h, tau, H, profile):
    """The fog's density relative to h0 at the height h above h0 (eq. 32 or eq. 28) times e^{-tau},
    without inf * 0 deep below h0 (where the density overflows and tau is inf): the exponential's
    as one exp(-h/H - tau)."""
    if profile == EXPONENTIAL:
        return math.exp(-h / H - tau)
    return max(0.0, 1.0 - h / H) * math.exp(-tau)


@njit
def column(h, mu, t0, t1, H, profile):
    """Unit-density optical depth over [t0, t1] of a ray starting at height h with up-cosine mu."""
    if profile == EXPONENTIAL:
        return exponential_optical_depth(1.0, h, mu, t0, t1, H)
    return linear_optical_depth(1.0, h, mu, t0, t1, H)


@njit
def column_distance(h, mu, t0, tau, H, profile):
    """The t >= t0 where `column` from t0 reaches tau (inf if never): eq. 35 or eq. 31."""
    if profile == EXPONENTIAL:
        return exponential_distance(1.0, h, mu, t0, tau, H)
    return linear_distance(1.0, h, mu, t0, tau, H)


@njit
def ray_columns(origins, dirs, a, b, ux, uy, uz, h0, H, profile, out):
    """out[i] = `column` over [a[i], b[i]] of ray i."""
    for i in range(origins.shape[0]):
        h = origins[i, 0] * ux + origins[i, 1] * uy + origins[i, 2] * uz - h0
        mu = dirs[i, 0] * ux + dirs[i, 1] * uy + dirs[i, 2] * uz
        out[i] = column(h, mu, a[i], b[i], H, profile)
