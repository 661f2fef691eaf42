"""The registry of air-light methods: name → Method (parameters with defaults, a docstring table).

The renderer, the command line, the tests and the benchmarks all iterate `registry()`, so a new
method module only has to define ``METHOD`` and be listed in ``_MODULES``.
"""
from __future__ import annotations

import importlib
import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

_MODULES = ("analytic", "quadrature", "raymarch", "lecocq", "sun", "montecarlo")


@dataclass(frozen=True)
class Param:
    """A method parameter: default, type, help text, and the values it accepts: numbers within
    [low, high] (`open_low` excludes low), strings among `choices`."""
    default: object
    type: type
    help: str
    low: float | None = None
    high: float | None = None
    open_low: bool = False
    choices: tuple = ()

    def rule(self) -> str:
        if self.choices:
            return "one of " + ", ".join(self.choices)
        lo = "" if self.low is None else (f"> {self.low:g}" if self.open_low else f">= {self.low:g}")
        hi = "" if self.high is None else f"<= {self.high:g}"
        return " and ".join(x for x in (lo, hi) if x) or "finite"

    def accepts(self, v) -> bool:
        if self.choices:
            return v in self.choices
        if self.type not in (int, float):
            return True
        if not math.isfinite(v):
            return False
        if self.low is not None and (v <= self.low if self.open_low else v < self.low):
            return False
        return self.high is None or v <= self.high


@dataclass
class RayBatch:
    """Camera rays of one tile: origins, unit directions, segment ends (inf on a miss), and the
    (pixel, sample) key of each ray for counter-based random numbers."""
    origins: np.ndarray
    dirs: np.ndarray
    tmax: np.ndarray
    keys: np.ndarray
    seed: int = 0
    scale: float = 1.0  # the scene's size (lights and point lights' regularisation, geometry.py)


@dataclass
class Method:
    name: str
    summary: str
    params: dict[str, Param]
    # airlight(batch, medium, light_pos (L,3), light_intensity (L,3), params) -> (radiance (N,3), stats),
    # or (radiance, stats, variance (N,3)) for a stochastic method: the variance of each ray's estimate
    airlight: Callable
    stats_size: int = 0
    summarize: Callable[[np.ndarray], dict] = field(default=lambda stats: {})
    check: Callable = field(default=lambda medium, params: None)  # raises UserError if unsupported
    stochastic: bool = False  # results depend on the seed; the renderer keeps per-pixel variance
    # points(batch, medium, light_pos, light_int, params) -> (pos (N, L, n, S, 3, 3), weight (N, L, n, S, 3)):
    # the medium points behind the estimate, for volumetric shadows: the air-light of ray r is the
    # mean over iterations j of sum over lights l and strategies s of V * weight[r, l, j, s]
    points: Callable | None = None


def registry() -> dict[str, Method]:
    out = {}
    for name in _MODULES:
        m = importlib.import_module(f"{__name__}.{name}").METHOD
        out[m.name] = m
    return out


def get_method(name: str) -> Method:
    from ..errors import UserError

    methods = registry()
    if name not in methods:
        raise UserError(f"--method {name}: unknown method; choose one of {', '.join(methods)}")
    return methods[name]


def resolve_params(method: Method, given: dict, source: str) -> dict:
    """Defaults of `method` updated with `given` (only the keys it declares), type-checked."""
    from ..errors import UserError

    out = {k: p.default for k, p in method.params.items()}
    for k, v in given.items():
        if k not in method.params or v is None:
            continue
        p = method.params[k]
        if p.type is bool:
            if isinstance(v, str) and v.lower() in ("true", "false", "1", "0", "yes", "no"):
                v = v.lower() in ("true", "1", "yes")
            if not isinstance(v, (bool, int)) or v not in (0, 1):
                raise UserError(f"{source}: --{k.replace('_', '-')} (render.{k}): expected true or false, got {v!r}")
            out[k] = bool(v)
            continue
        flag = "--" + k.replace("_", "-")
        if isinstance(v, bool) or (p.type in (int, float) and isinstance(v, str)):
            raise UserError(f"{source}: {flag} (render.{k}): expected {p.type.__name__}, got {v!r}; {p.help}")
        try:
            v = p.type(v)
        except (TypeError, ValueError):
            raise UserError(f"{source}: {flag} (render.{k}): expected {p.type.__name__}, got {v!r}; {p.help}") from None
        if not p.accepts(v):
            raise UserError(f"{source}: {flag} (render.{k}): must be {p.rule()}, got {v!r}; {p.help}")
        out[k] = v
    return out
