"""The particles of "Rendering Particles in a Shaft of Light" (the article below), as an optional
layer on the medium (`[medium.particles]`).

The article ray-marches each camera ray and adds, per step i, a particle term to the air-light
sample Io (its eq. 1, read from the garbled text as)

    I = Io + (1 - (1 - d)^0.4) Is,

with d the particle density of the "unit space" the step lies in, a normal CDF (eq. 2; the text
calls it log-normal, the formula is the normal one)

    d = cdf(x | mu, sigma) = 1 / (sigma sqrt(2 pi)) int_{-inf}^{x} exp(-(t - mu)^2 / (2 sigma^2)) dt,

the neighbour particle at C_i = R_i + D_i direction with D_i = kc (1 - d) (eqs. 3, 4; `direction`
an isotropic random unit vector, kc = 7), and Is the surface radiance of Sun et al. 2005 at that
particle, without its specular term and with the scattering coefficient replaced by
beta = ((1 - d) + c1) c2, c1 = 0.05, c2 = 0.03 (eq. 5, appendix B):

    Is = I0 kd [exp(-T) cos(theta_s) / D_sp^2 + beta^2 G0(T, theta_s) / (2 pi T)],  T = beta D_sp.

The article calls its own model heuristic: it is "roughly based on multiple scattering theories",
"it does not compute scattering effects from every particle", and the (1 - d^0.4) weight replaces
the physically motivated exp(-d) / distance^2 "because this term results in a more obvious result";
c1 and c2 were set "experimentally".

Here Io is the exact air-light of any method (computed elsewhere); this module adds the particle
term. Where the article is not explicit (README, "Particles in a shaft of light"): x is a uniform
random number per cubic cell of edge `cell` (the unit space), keyed by the cell, and d = density *
cdf(x); D_i is kc (1 - d) cells; the particle is a facet whose normal is its `direction` (it faces
the marching point), so cos(theta_s) is direction . (light - C_i) / D_sp; I0 is the light's
emission toward C_i (a spot light's falloff included); each step weighs Is by sigma_s * step and
by the camera's exp(-kt x), like an air-light sample, so the sum does not grow with the step count.
G0 is Sun et al.'s diffuse irradiance integral over the hemisphere about the normal,

    G0(T, theta_s) = int_0^pi K(gamma, theta_s) exp(-T cos gamma) int_{gamma/2}^{pi/2} exp(-T sin(gamma) tan(xi)) dxi dgamma,

with K the azimuthal integral of the clipped cosine (closed form), tabulated once by Gauss-Legendre.
Random numbers come from rng.uniform keyed by (cell, 0, seed) for d and by (ray key, step
dimension, seed) for the step's jitter and direction: images do not depend on the thread count.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from ..jit import njit
from ..lights import light_sample
from ..rng import mix64, uniform

EXPONENT = 0.4  # eq. 1
KC = 7.0  # the article's neighbour distance constant (eq. 3)
C1, C2 = 0.05, 0.03  # eq. 5
_TABLE_T = 64  # G0 table: T through u = T / (1 + T) in [0, 1], theta_s in [0, pi]
_TABLE_THETA = 33


@dataclass(frozen=True)
class Particles:
    """`[medium.particles]`: density scale in [0, 1] of d, the CDF's mu and sigma, the cell edge
    (scene units), kc in cells, the marching step (scene units), beta (None: eq. 5 with c1, c2),
    the particles' reflectance (kd = reflectance / pi) and the random-number seed."""
    density: float = 1.0
    mu: float = 0.5
    sigma: float = 0.5
    cell: float = 0.05
    offset: float = KC
    step: float = 0.05
    beta: float | None = None
    c1: float = C1
    c2: float = C2
    reflectance: float = 1.0
    seed: int = 0


@functools.cache
def g0_table() -> np.ndarray:
    """G0 at u = T / (1 + T) on _TABLE_T points of [0, 1) and theta_s on _TABLE_THETA of [0, pi]."""
    u = np.linspace(0.0, 1.0, _TABLE_T, endpoint=False)
    T = u / (1.0 - u)
    th = np.linspace(0.0, math.pi, _TABLE_THETA)
    xg, wg = np.polynomial.legendre.leggauss(96)
    gam = 0.5 * math.pi * (xg + 1.0)
    wgam = 0.5 * math.pi * wg
    xi_x, xi_w = np.polynomial.legendre.leggauss(48)
    lo = gam / 2.0
    half = (0.5 * math.pi - lo) / 2.0
    xi = lo[:, None] + half[:, None] * (xi_x[None, :] + 1.0)  # (gamma, xi)
    with np.errstate(over="ignore"):
        e = np.exp(-T[:, None, None] * np.sin(gam)[None, :, None] * np.tan(xi)[None, :, :])
    inner = (e * xi_w[None, None, :]).sum(axis=2) * half[None, :]  # (T, gamma)
    outer = inner * np.exp(-T[:, None] * np.cos(gam)[None, :])
    a = np.cos(gam)[:, None] * np.cos(th)[None, :]
    b = np.sin(gam)[:, None] * np.sin(th)[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        phi0 = np.arccos(np.clip(np.where(b > 0.0, -a / b, np.sign(-a) * 2.0), -1.0, 1.0))
    K = 2.0 * (a * phi0 + b * np.sin(phi0))  # int_0^{2pi} max(0, a + b cos(phi)) dphi
    return np.ascontiguousarray((outer * wgam[None, :]) @ K)


@njit
def _g0(table, T, cos_s):
    """Bilinear G0 from the table."""
    u = T / (1.0 + T) * (table.shape[0])
    th = math.acos(min(1.0, max(-1.0, cos_s))) / math.pi * (table.shape[1] - 1)
    i = min(int(u), table.shape[0] - 2)
    j = min(int(th), table.shape[1] - 2)
    fu, ft = min(u - i, 1.0), th - j
    return ((1.0 - fu) * ((1.0 - ft) * table[i, j] + ft * table[i, j + 1])
            + fu * ((1.0 - ft) * table[i + 1, j] + ft * table[i + 1, j + 1]))


_CELL_DIM = np.uint64(0)  # d's dimension under a cell's key; a step's dimensions follow
_OFF = 1 << 31


@njit
def _cell_density(px, py, pz, cell, density, mu, sigma, seed):
    ix = np.uint64(np.int64(math.floor(px / cell)) + _OFF)
    iy = np.uint64(np.int64(math.floor(py / cell)) + _OFF)
    iz = np.uint64(np.int64(math.floor(pz / cell)) + _OFF)
    key = mix64(ix ^ mix64(iy ^ mix64(iz)))
    x = uniform(key, _CELL_DIM, seed)
    return density * 0.5 * math.erfc(-(x - mu) / (sigma * math.sqrt(2.0)))


@njit
def _march(fill, origins, dirs, tmax, keys, p, seed, lk, lpos, lint, laxis, lcone, sigma_s, kt, table,
           counts, starts, ray, pos, light, value):
    """Count (fill = False: counts[i] = particles of ray i) or write (fill = True, at starts[i]) the
    lit particles of each ray: their ray, position, light and radiance contribution (3)."""
    density, mu, sigma, cell, kc, step, beta_user, c1, c2, kd = p
    for i in range(origins.shape[0]):
        n = 0
        k = starts[i]
        steps = int(math.ceil(tmax[i] / step))
        for s in range(steps):
            dim = np.uint64(1 + 3 * s)
            x = (s + uniform(keys[i], dim, seed)) * step
            if x >= tmax[i]:
                break
            rx = origins[i, 0] + x * dirs[i, 0]
            ry = origins[i, 1] + x * dirs[i, 1]
            rz = origins[i, 2] + x * dirs[i, 2]
            d = _cell_density(rx, ry, rz, cell, density, mu, sigma, seed)
            w = 1.0 - (1.0 - d) ** EXPONENT
            if not w > 0.0:
                continue
            z = 1.0 - 2.0 * uniform(keys[i], dim + np.uint64(1), seed)
            ph = 2.0 * math.pi * uniform(keys[i], dim + np.uint64(2), seed)
            r = math.sqrt(max(0.0, 1.0 - z * z))
            ux, uy, uz = r * math.cos(ph), r * math.sin(ph), z
            D = kc * (1.0 - d) * cell
            cx, cy, cz = rx + D * ux, ry + D * uy, rz + D * uz
            beta = beta_user if beta_user > 0.0 else ((1.0 - d) + c1) * c2
            for l in range(lpos.shape[0]):
                tx, ty, tz, dist, f = light_sample(lk, lpos, laxis, lcone, l, cx, cy, cz)
                if f == 0.0:
                    continue
                if fill:
                    cos_s = ux * tx + uy * ty + uz * tz
                    T = beta * dist
                    Is = kd * (math.exp(-T) * max(0.0, cos_s) / (dist * dist)
                               + beta * _g0(table, T, cos_s) / (2.0 * math.pi * dist))
                    ray[k] = i
                    light[k] = l
                    pos[k, 0], pos[k, 1], pos[k, 2] = cx, cy, cz
                    for c in range(3):
                        value[k, c] = step * w * Is * f * lint[l, c] * sigma_s[c] * math.exp(-kt[c] * x)
                    k += 1
                n += 1
        counts[i] = n


@njit
def _scatter(ray, value, keep, out):
    for k in range(ray.shape[0]):
        if keep[k]:
            for c in range(3):
                out[ray[k], c] += value[k, c]


def particle_radiance(particles: Particles, medium, lights, accel, origins, dirs, t, keys, shadowed: bool):
    """The particle term (N, 3) of camera rays with first hits at t (inf: none; those march to
    4 x the scene's extent). `shadowed`: each particle sees a light only through a shadow ray, as the
    shadowed air-light does."""
    p = particles
    params = np.array([p.density, p.mu, p.sigma, p.cell, p.offset, p.step, p.beta or 0.0, p.c1, p.c2,
                       p.reflectance / math.pi])
    tmax = np.minimum(t, 4.0 * accel.scale)
    n = len(origins)
    counts = np.zeros(n, dtype=np.int64)
    args = (origins, dirs, tmax, keys, params, p.seed, lights.kind, lights.position, lights.intensity,
            lights.axis, lights.cone, medium.sigma_s, medium.sigma_t, g0_table())
    _march(False, *args, counts, np.zeros(n, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0, np.int64),
           np.zeros((0, 3)))
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
    m = int(counts.sum())
    ray, pos, light, value = np.empty(m, np.int64), np.empty((m, 3)), np.empty(m, np.int64), np.empty((m, 3))
    _march(True, *args, counts, starts, ray, pos, light, value)
    keep = np.ones(m, dtype=bool)
    if shadowed and m:
        to = lights.position[light] - pos
        dist = np.linalg.norm(to, axis=1)
        keep = ~accel.occluded(pos, to / dist[:, None], dist - accel.epsilon)
    out = np.zeros((n, 3))
    _scatter(ray, value, keep, out)
    return out
