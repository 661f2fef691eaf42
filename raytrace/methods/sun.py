"""`sun`: Sun, Ramamoorthi, Narasimhan & Nayar 2005 (SRNN05) tabulated air-light, as PP09 compared it
(METHODS.md §1, §3, §7; Pegoraro & Parker 2009, Table 1: "Sun's 512x512 precomputed table").

SRNN05's isotropic air-light, with the PP09 mapping (absorption: ks in front, kt in the exponents)
for a unit-intensity light at projection x_h, distance h from the ray, segment [0, ell]:

    Lm = A0 [F(A1, phi_b / 2) - F(A1, phi_a / 2)],   A0 = ks exp(-kt x_h) / (2 pi h),   A1 = H = kt h,
    F(u, v) = int_0^v exp(-u tan xi) dxi,

where phi(x) = atan2(h, x_h - x) is the scattering angle at x (phi_a = gamma, the angle between the
ray and the light seen from the camera; phi_b = pi for ell = inf). h is clamped to >= 1e-300
(sin gamma -> 0); A0 is combined with the table difference in log space, so a light far behind
the camera (exp(-kt x_h) huge) cannot overflow (results beyond SATURATE = 1e300 are saturated and
counted).

The table: F at the CELL CORNERS of a `table_size` x `table_size` grid, u_i = i u_max / (n - 1),
v_j = j (pi/2) / (n - 1), i, j = 0 .. n - 1 (so u = 0, u = u_max, v = 0 and v = pi/2 are exact
nodes), stored as float32 (as a GPU texture would be), looked up bilinearly, arguments beyond the
table clamped to its edge: A1 > u_max reads F(u_max, .), which is larger than the truth (F
decreases with u) -- PP09's "erroneous brightening" -- and the bilinear interpolation misses the
sharp knee of dF/dv = exp(-u tan v) for large u ("white spots"). Defaults 512 x 512, u_max = 10
(the range public shader implementations use; SRNN05's exact range is unverified).

The table is filled once from the closed form (METHODS.md §7, verified there to 7e-15; written
with E1 so nothing overflows):

    F(u, v) = -Im(e^{iu} E1(iu)) + Im(e^{iu} E1(u tan v + iu))   (u > 0; second term 0 at v = pi/2),
    F(0, v) = v,

using scipy.special.exp1 on complex arguments, and cached as .npy under $RAYTRACE_CACHE (default
~/.cache/raytrace), keyed by (table_size, u_max, TABLE_VERSION); writes are atomic (temporary file
+ os.replace) and an unreadable or inconsistent cache file is regenerated. Isotropic media only
(an anisotropic phase would need a table per phase function): `check` raises UserError otherwise.
"""
from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path

import numpy as np

from ..errors import UserError
from ..cache import cache_dir
from ..jit import njit
from . import ErrorLaw, Method, Param, Supports
from .geometry import by_channel
from ..media.phase import ISOTROPIC, NAMES

TABLE_VERSION = 1
HALF_PI = 0.5 * math.pi
SATURATE = 1e300
_LOG_SATURATE = math.log(SATURATE)

# stats slots
EVALS, CLAMPED_U, SATURATED = 0, 1, 2


# ---- the table (Python, one-off) ----

def F_exact(u, v):
    """F(u, v) = int_0^v exp(-u tan xi) dxi from the closed form (float64, vectorised, u >= 0, 0 <= v <= pi/2)."""
    from scipy.special import exp1

    u, v = np.broadcast_arrays(np.asarray(u, float), np.asarray(v, float))
    out = v.astype(float).copy()  # the u = 0 column: F = v
    pos = u > 0.0
    up, vp = u[pos], v[pos]
    rot = np.exp(1j * up)
    whole = -np.imag(rot * exp1(1j * up))  # F(u, pi/2)
    inner = vp < HALF_PI
    tail = np.zeros_like(up)
    tail[inner] = np.imag(rot[inner] * exp1(up[inner] * np.tan(vp[inner]) + 1j * up[inner]))
    out[pos] = whole + tail
    return out


def fill_table(n: int, u_max: float) -> np.ndarray:
    """(n, n) float32 table, [i, j] = F(i u_max / (n-1), j (pi/2) / (n-1)) (cell corners)."""
    u = np.linspace(0.0, u_max, n)
    v = np.linspace(0.0, HALF_PI, n)
    table = F_exact(u[:, None], v[None, :]).astype(np.float32)
    table[:, 0] = 0.0
    return table


def cache_path(n: int, u_max: float) -> Path:
    return cache_dir() / f"sun_F_v{TABLE_VERSION}_{n}x{n}_umax{float(u_max)!r}.npy"


def _plausible(table, n, u_max) -> bool:
    if not (isinstance(table, np.ndarray) and table.dtype == np.float32 and table.shape == (n, n)):
        return False
    if not np.all(np.isfinite(table)) or np.any(table[:, 0] != 0.0):
        return False
    v = np.linspace(0.0, HALF_PI, n).astype(np.float32)
    if not np.array_equal(table[0], v):  # the u = 0 row is F = v exactly
        return False
    probe = F_exact(np.array([u_max, 0.5 * u_max]), np.array([HALF_PI, 0.5]))
    got = [table[-1, -1], lookup(table, u_max, 0.5 * u_max, 0.5)]
    return abs(got[0] - probe[0]) <= 1e-6 and abs(got[1] - probe[1]) <= 1e-3


_MEMO: dict = {}


def load_table(n: int = 512, u_max: float = 10.0) -> np.ndarray:
    """The table for (n, u_max): from memory, else from the disk cache, else filled and cached."""
    key = (int(n), float(u_max))
    if key in _MEMO:
        return _MEMO[key]
    path = cache_path(*key)
    table = None
    try:
        table = np.load(path, allow_pickle=False)
        if not _plausible(table, *key):
            table = None
    except Exception:  # missing, truncated or corrupt: regenerate
        table = None
    if table is None:
        table = fill_table(*key)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=path.name + ".", suffix=".tmp", dir=path.parent)
            try:
                with os.fdopen(fd, "wb") as f:
                    np.save(f, table)
                os.replace(tmp, path)
            except BaseException:
                try:
                    os.unlink(tmp)
                except OSError:
                    pass
                raise
        except OSError:
            pass  # an unwritable cache only costs the refill next time
    _MEMO[key] = table
    return table


# ---- kernels ----

@njit
def _cell(n, x_max, x):
    """Cell index and fraction of x on the n-point grid over [0, x_max], clamped to its edges."""
    f = x / x_max * (n - 1)
    if not f > 0.0:  # also NaN
        f = 0.0
    if f > n - 1:
        f = n - 1.0
    i = min(int(f), n - 2)
    return i, f - i


@njit
def _row(table, i, s, j, t):
    """Bilinear value in cell (i, j) at fractions (s, t)."""
    return ((1.0 - s) * ((1.0 - t) * float(table[i, j]) + t * float(table[i, j + 1]))
            + s * ((1.0 - t) * float(table[i + 1, j]) + t * float(table[i + 1, j + 1])))


@njit
def lookup(table, u_max, u, v):
    """Bilinear F(u, v) from the corner-grid table; u clamped to [0, u_max], v to [0, pi/2]."""
    n = table.shape[0]
    i, s = _cell(n, u_max, u)
    j, t = _cell(n, HALF_PI, v)
    return _row(table, i, s, j, t)


@njit
def lookup_diff(table, u_max, u, va, vb):
    """lookup(u, vb) - lookup(u, va) for va <= vb, without rounding noise: the bilinear interpolant is
    non-decreasing in v (the table is), so within one cell the difference is (t_b - t_a) times the
    cell's slope, and across cells a negative rounding residue is impossible (max with 0)."""
    n = table.shape[0]
    i, s = _cell(n, u_max, u)
    ja, ta = _cell(n, HALF_PI, va)
    jb, tb = _cell(n, HALF_PI, vb)
    if ja == jb:
        slope = ((1.0 - s) * (float(table[i, ja + 1]) - float(table[i, ja]))
                 + s * (float(table[i + 1, ja + 1]) - float(table[i + 1, ja])))
        return (tb - ta) * slope
    return max(_row(table, i, s, jb, tb) - _row(table, i, s, ja, ta), 0.0)


@njit
def airlight_one(xh, h, ell, kt, ks, table, u_max, stats):
    """SRNN05 air-light of the segment [0, ell] (ell may be inf), unit light, one channel (isotropic)."""
    if ks == 0.0 or not ell > 0.0:
        return 0.0
    stats[EVALS] += 1.0
    h = max(h, 1e-300)
    a1 = kt * h
    if a1 > u_max:
        stats[CLAMPED_U] += 1.0
    phi_a = math.atan2(h, xh)
    phi_b = math.pi if ell == math.inf else math.atan2(h, xh - ell)
    diff = lookup_diff(table, u_max, a1, 0.5 * phi_a, 0.5 * phi_b)
    if diff == 0.0:
        return 0.0
    logmag = math.log(ks) - math.log(2.0 * math.pi * h) - kt * xh + math.log(abs(diff))
    if logmag > _LOG_SATURATE:
        stats[SATURATED] += 1.0
        return math.copysign(SATURATE, diff)
    return math.copysign(math.exp(logmag), diff)


@njit
def evaluate_segments(xh, h, ell, kt, ks, table, u_max, out, stats):
    """Unit-intensity air-light of every segment for one channel's coefficients."""
    for s in range(xh.shape[0]):
        out[s] = airlight_one(xh[s], h[s], ell[s], kt, ks, table, u_max, stats)


def _airlight(segs, medium, lights, params):
    stats = np.zeros(3)
    u_max = float(params["u_max"])
    table = load_table(int(params["table_size"]), u_max)

    def evaluate(xh, h, da, ell, kt, ks, cone):
        out = np.empty_like(xh)
        evaluate_segments(xh, h, ell, kt, ks, table, u_max, out, stats)
        return out

    return by_channel(segs, medium, lights, evaluate), stats


def _summarize(stats):
    evals = max(stats[EVALS], 1.0)
    return {"air-light evaluations": int(stats[EVALS]),
            "fraction with A1 beyond the table (clamped)": stats[CLAMPED_U] / evals,
            "saturated estimates": int(stats[SATURATED])}


def _check(medium, params):
    if medium.phase != ISOTROPIC:
        raise UserError(f"method sun: its table F(u, v) is for isotropic media only, but medium.phase is "
                        f"'{NAMES.get(medium.phase, medium.phase)}'; set medium.phase = \"isotropic\" or use "
                        f"--method quadrature")


METHOD = Method(
    name="sun",
    summary="Sun et al. 2005: bilinear lookup in a precomputed F(u, v) table, clamped at its edges (isotropic only)",
    params={
        "table_size": Param(512, int, "table resolution per axis (cell-corner grid), e.g. 512", 2, 8192),
        "u_max": Param(10.0, float, "largest tabulated u = kt h; larger values read the edge, e.g. 10", 0.0, None,
                       True),
    },
    airlight=_airlight,
    error_law=ErrorLaw({}, "median", 3e-4),  # measured worst 1.0e-4 (thick), tests/test_methods.py
    stats_size=3,
    summarize=_summarize,
    check=_check,
    supports=Supports(phases=(ISOTROPIC,)),
)
