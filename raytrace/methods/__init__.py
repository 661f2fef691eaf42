"""The registry of air-light methods: name → Method (parameters with defaults, a docstring table).

The renderer, the command line, the tests and the benchmarks all iterate `registry()`, so a new
method module only has to define ``METHOD`` (with its ``Supports``) and be listed in ``_MODULES``.
"""
from __future__ import annotations

import importlib
import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..lights import AREA, EMISSION, ENVIRONMENT
from ..media import Homogeneous
from ..media.phase import HG, ISOTROPIC, NAMES as PHASE_NAMES, RAYLEIGH
from ..media.inside_rule import QUAD, InsideRule, inside_rule

_MODULES = ("analytic", "quadrature", "raymarch", "lecocq", "sun", "montecarlo", "slab_approx")


def _readable(v: float) -> str:
    """A bound as people write it: whole numbers in full (1048576, not 1.04858e+06), others to 6 digits."""
    return str(int(v)) if float(v).is_integer() and abs(v) < 1e15 else f"{v:g}"


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
        lo = "" if self.low is None else (f"> {_readable(self.low)}" if self.open_low else f">= {_readable(self.low)}")
        hi = "" if self.high is None else f"<= {_readable(self.high)}"
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
class Segments:
    """The unit of work of every method (ARCHITECTURE.md): piece [t0, t0 + length] of a camera ray
    lit by one light. `origins` are the segments' own start points o + t0 w (a method integrates
    from there; the renderer applies the medium's transmittance from the camera ray's origin to t0,
    exp(-kt t0) when homogeneous), `length` may be inf, `light` and `ray` index the light and the
    camera ray, `keys` is the camera ray's (pixel, sample) key for counter-based random numbers and
    `stream` numbers the segment among its ray's segments (light + lights x piece), so that every
    segment draws its own random numbers."""
    origins: np.ndarray
    dirs: np.ndarray
    length: np.ndarray
    light: np.ndarray
    ray: np.ndarray
    t0: np.ndarray
    keys: np.ndarray
    stream: np.ndarray
    seed: int = 0
    scale: float = 1.0  # the scene's size (point lights' regularisation, geometry.py)
    per_ray: int = 0  # k when segment r k + j is ray r's j-th and every t0 is 0 (whole rays), else 0
    # rows inside shapes that hold a medium (interiors/crossing.py's crossing; None: every row lies in the camera's
    # medium): the shape whose interior holds each row, the outward normal (S, 3) of the boundary face its
    # camera ray entered by (the slab note's plane), and how light reaches it (crossing.STRAIGHT, ...)
    medium: np.ndarray | None = None
    normals: np.ndarray | None = None
    reach: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.length)

    def take(self, idx) -> "Segments":
        """The segments at `idx` (an index array or slice; the result has no per-ray layout)."""
        pick = lambda a: None if a is None else a[idx]
        return Segments(self.origins[idx], self.dirs[idx], self.length[idx], self.light[idx], self.ray[idx],
                        self.t0[idx], self.keys[idx], self.stream[idx], self.seed, self.scale,
                        medium=pick(self.medium), normals=pick(self.normals), reach=pick(self.reach))


@dataclass(frozen=True)
class ErrorLaw:
    """How close a method comes to the reference on the box-room oracle scenes, for the test over the
    registry (tests/test_methods.py): with `params`, the per-pixel relative error's `statistic`
    ("max" or "median") is at most `tolerance`; "sigma" (stochastic methods): the mean squared
    z-score of the per-pixel errors against their variance estimate is at most `tolerance`."""
    params: dict
    statistic: str
    tolerance: float


LIGHTS = ("point", "spot", "directional", ENVIRONMENT)  # lights.NAMES (the environment's rows are directional)
# quad, disk, sphere lights and emissive shapes: spot rows to the kernels (lights/area.py), for every method
# that takes spot lights
AREA_LIGHTS = AREA + (EMISSION,)
INSIDE_RTOL = 1e-10  # the relative accuracy of the inside quadrature of methods without an `rtol` of their own


def _inside_defaults(params: dict) -> tuple:
    return INSIDE_RTOL, 1, 745.0


@dataclass(frozen=True)
class Interiors:
    """How a method integrates media inside shapes (interiors/crossing.py), the one place it declares it: its
    inside rule, of `kind` QUAD (adaptive quadrature), MARCH (midpoints) or SAMPLE (free paths) with
    `settings(params)`, the rule's (rtol, steps or samples per segment, optical depth at which a segment is
    cut) from the method's own parameters (`rule(params)`: the record media/inside_rule.py's drivers take),
    for the light kinds `lights`, of which `refracted` also through a refractive boundary (ior != 1). The
    light's path inside, one of three: `exact_paths`, the rule along the light's exact paths (straight in
    index-matched shapes, refracted through refractive boundaries); `closed_forms`, closed forms where there
    are some (a directional light's exact path in convex index-matched shapes, media/convex_directional.py;
    its beams through every face of convex refractive ones; eq. 5 through the entry plane of other
    refractive shapes), the rule on the exact paths elsewhere, counted; `entry_plane`, the entry face's
    plane everywhere by the slab note's closed forms (eq. 5; its separable approximation for point
    lights). `camera_inside`: the rule takes rows without an entry face (a camera inside a shape:
    index-matched, convex or an exact sphere; interiors/crossing.py `start_inside`); the entry plane's
    model has none to take. `fixed`: its parameters not implemented inside (they must keep their
    defaults). `limits`: what its refusal of a light says. `through`: how the outside air-light whose
    light crosses index-matched interiors is integrated: "points" (the method's own medium points,
    `Method.points`, each point's light attenuated) or "quadrature" (the traced adaptive quadrature at
    the rule's rtol: quadrature's own rule, a fallback of the others, counted)."""
    kind: int
    lights: tuple = LIGHTS
    refracted: tuple = LIGHTS
    exact_paths: bool = False
    fixed: tuple = ()
    limits: str = ""
    settings: Callable[[dict], tuple] = _inside_defaults
    through: str = "quadrature"
    camera_inside: bool = True
    closed_forms: bool = False
    entry_plane: bool = False

    def __post_init__(self):
        assert self.exact_paths + self.closed_forms + self.entry_plane == 1, "one model of the light's path inside"

    def rule(self, params: dict) -> InsideRule:
        """The inside rule's record for the method's parameters `params`."""
        return inside_rule(self.kind, *self.settings(params))


@dataclass(frozen=True)
class Supports:
    """What a method integrates; the registry refuses the rest in one line, naming the methods that
    take it: light kinds (lights.NAMES), medium kinds (media/ classes), phase functions (media/phase.py
    codes, of the camera's medium and of interiors), media inside shapes (None: refused) and the
    volumetric shadow tests ("intervals": over the exact lit intervals; "samples": a shadow ray per
    medium point, which needs the method's `points`)."""
    lights: tuple = ("point",)
    media: tuple = (Homogeneous,)
    phases: tuple = (ISOTROPIC, RAYLEIGH, HG)
    interiors: Interiors | None = None
    shadow_tests: tuple = ("intervals",)

    def describe(self) -> str:
        """One line of what the method takes (`render.py methods`)."""
        inside = self.interiors
        if inside is None:
            shapes = "no media inside shapes"
        else:
            model = ("exact straight light paths" if inside.exact_paths else
                     "closed forms: exact in convex shapes (refractive: the beam of every face the light meets; an "
                     "exact sphere's refracted paths: adaptive quadrature), the entry face's plane in other "
                     "refractive shapes" if inside.closed_forms else
                     "the slab note's separable approximation")
            through = "" if inside.refracted == inside.lights else \
                f"; through refractive boundaries: {', '.join(inside.refracted)}"
            fallback = "; light through them: adaptive quadrature" if inside.through == "quadrature" and \
                not (inside.kind == QUAD and inside.exact_paths) else ""
            shapes = f"media inside shapes ({', '.join(inside.lights)} lights{through}; {model}{fallback})"
        return (f"takes {', '.join(self.lights)} lights; {', '.join(m.type_name for m in self.media)} media; "
                f"{', '.join(PHASE_NAMES[p] for p in self.phases)} phases; {shapes}")


@dataclass
class Method:
    name: str
    summary: str
    params: dict[str, Param]
    # airlight(segments, medium, lights, params) -> (radiance (S, 3), stats), or (radiance, stats,
    # variance (S, 3)) for a stochastic method: each segment's air-light from its own start point,
    # the light's intensity included, and the variance of each estimate; a deterministic method may
    # return (radiance, stats, bound (S, 3)), a bound on each value's error (else: infinite,
    # error_bounds.py)
    airlight: Callable
    error_law: ErrorLaw
    # compile_here(medium, lights, params): compiles by signature, in the render's process, the air-light's
    # kernels that `worker_airlight` (the air-light as the compile worker runs it) leaves out, so that the two
    # processes share the first compile (rendering/compile_ahead.py); None: the worker compiles `airlight` whole
    compile_here: Callable | None = None
    worker_airlight: Callable | None = None
    stats_size: int = 0
    summarize: Callable[[np.ndarray], dict] = field(default=lambda stats: {})
    check: Callable = field(default=lambda medium, params: None)  # raises UserError if unsupported
    stochastic: bool = False  # results depend on the seed; the renderer keeps per-pixel variance
    # points(segments, medium, lights, params) -> (pos (S, n, k, 3, 3), weight (S, n, k, 3)): the
    # medium points behind the estimate (n iterations of k strategies, per channel), for volumetric
    # shadows: a segment's air-light is the mean over iterations of sum over strategies of V * weight; or
    # (pos, weight, targets (S, n, 3)): where each iteration's shadow rays go, for a method that moves its
    # lights' points per iteration (montecarlo's flat emitters); shadow_rays.shadowed_airlight traces to them
    points: Callable | None = None
    # point_count(segments, medium, params) -> (S,) iterations x strategies `points` would give each
    # segment, so that the renderer can cut the work into chunks of bounded memory
    point_count: Callable | None = None
    supports: Supports = Supports()
    # sphere(medium, params) -> None, or a stochastic method's own estimate of a sphere emitter's unoccluded
    # air-light along camera rays, estimate(ball, radiance (3,), owner, rays, rs) -> (value (P, 3), variance
    # (P, 3)) (rendering/near_emitters.py); None: the emitter's rows
    sphere: Callable | None = None
    # the parameter holding the method's requested relative tolerance, which the renderer's adaptive
    # rules follow (an emitter's order, a penumbra's strata, the rule near a flat emitter); None: none
    tolerance_key: str | None = None

    def __post_init__(self):
        samples = "samples" in self.supports.shadow_tests
        assert samples == (self.points is not None) == ("shadow_test" in self.params), self.name
        assert not samples or self.params["shadow_test"].choices == self.supports.shadow_tests, self.name
        assert self.tolerance_key is None or self.tolerance_key in self.params, self.name

    def tolerance(self, params: dict) -> float | None:
        """The requested relative tolerance (`tolerance_key`), None for a method without one."""
        if self.tolerance_key is None:
            return None
        return float(params.get(self.tolerance_key, self.params[self.tolerance_key].default))

    def samples_shadows(self, params: dict) -> bool:
        """Whether this render tests volumetric shadows with a shadow ray per medium point (the method's
        `shadow_test = "samples"`) rather than over the exact lit intervals."""
        return params.get("shadow_test") == "samples"

    def check_lights(self, lights, source: str):
        """Refuse lights of a kind this method does not integrate, naming the methods that do."""
        from ..errors import UserError

        scene_first = lambda k: (k not in lights.scene_kinds, k)  # an environment before its directional rows
        for kind in sorted(lights.kinds() - set(self.supports.lights), key=scene_first):
            takers = [m.name for m in registry().values() if kind in m.supports.lights]
            what = "emissive shapes (shape.emission)" if kind == EMISSION else f"{kind} lights (light.type = \"{kind}\")"
            raise UserError(f"{source}: --method {self.name}: it does not take {what}; use --method "
                            f"{', '.join(takers)}, or make the lights point lights")

    def check_medium(self, medium, source: str):
        """Refuse a medium type or phase function this method does not integrate, naming the methods
        that do."""
        from ..errors import UserError

        if type(medium) not in self.supports.media:
            kind = medium.type_name
            takers = [m.name for m in registry().values() if type(medium) in m.supports.media]
            raise UserError(f"{source}: --method {self.name}: it does not take {kind} media (medium.type = "
                            f"\"{kind}\"); use --method {', '.join(takers)}, or a homogeneous medium")
        self.check_phase(medium, "medium.phase", source)

    def check_phase(self, medium, key: str, source: str):
        """Refuse the phase function of `medium` (scene key `key`) if this method does not take it."""
        from ..errors import UserError

        if medium.phase not in self.supports.phases:
            name = PHASE_NAMES[medium.phase]
            takers = [m.name for m in registry().values() if medium.phase in m.supports.phases]
            raise UserError(f"{source}: --method {self.name}: it does not take {name} phase functions ({key} = "
                            f"\"{name}\"); use --method {', '.join(takers)}, or an isotropic medium")


def by_kind(table: dict, medium):
    """table[kind of medium]: a method's function for this medium kind; a kind it lacks is an error
    (`Method.check_medium` names the methods that take it), never another kind's code."""
    from ..errors import UserError

    if type(medium) not in table:
        raise UserError(f"medium.type = \"{medium.type_name}\": no integrator for this kind here; use one of "
                        f"{', '.join(k.type_name for k in table)}")
    return table[type(medium)]


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
    """Defaults of `method` updated with `given`, type- and range-checked. A key the method does not
    declare is refused, naming the methods that do take it (nothing is dropped silently): `given` holds
    the keywords and flags given explicitly (api.scene_defaults has left out, with a note, the
    scene's [render] parameters the method does not read)."""
    from ..errors import UserError

    out = {k: p.default for k, p in method.params.items()}
    for k in given:
        if k not in method.params and given[k] is not None:
            takers = [m.name for m in registry().values() if k in m.params]
            fix = (f"it is a parameter of {', '.join(takers)}: choose --method {takers[0]} or remove it" if takers
                   else "no method takes it; see `render.py methods`")
            raise UserError(f"{source}: {k}={given[k]!r} (--{k.replace('_', '-')} on the command line): method "
                            f"{method.name} does not read this parameter; {fix}")
    for k, v in given.items():
        if v is None:
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
