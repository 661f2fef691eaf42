"""What the area lights (quad.py, disk.py, sphere.py) share: a Lambertian emitter of radiance L
(W / (m^2 sr) per channel, the same toward every direction of its emitting side).

An element dA of the emitter at y, of unit normal n, sends toward the direction u the radiant
intensity L dA max(0, n·u): a spot light at y of axis n whose falloff is the cosine itself (spot.py's
LAMBERT curve, a cone of 90 degrees). So an area light is, to the kernels, the rows of a cubature
rule over the emitter's parameter domain: nodes y_i with weights w_i (their sum is the area A), each
a spot row of intensity L w_i, axis n_i; a two-sided emitter has the same nodes once more with
axis -n_i. Every method that takes spot lights integrates each row exactly along the ray as
it integrates a spot light (the air-light's closed form is per point of the light); the cubature
over the emitter is the one approximation (Rows.cubature: no error bound, error_bounds.py), its
order measured in docs/area_lights.md.

Where occluders cut the emitter (penumbrae) the surface term (shading.py) and, with volumetric
shadows, the air-light (shadows/penumbra_airlight.py) sample it instead: each kind maps
(u, v) in [0, 1]^2 onto its emitter (`sample_emitter(light, u, v)`, uniform in area: density 1 / A),
and `Emitter` is what the surface term needs of one emitter (shading.py).
"""
from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..geometry.vectors import perpendicular
from .light import Light, Rows, power
from .spot import CODE as SPOT, LAMBERT

COMMON_KEYS = frozenset({"type", "radiance", "two_sided"})
PROBE_INSET = 1e-6  # how far inside the outline (of the parameter range) the corner probes lie


def gauss_legendre(n: int):
    """Gauss–Legendre nodes and weights on [0, 1] (weights sum to 1; exact for degree 2n - 1), new
    arrays each call (numpy's on [-1, 1] computed once per n: an eigenvalue problem)."""
    x, w = _leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


@functools.lru_cache(maxsize=None)
def _leggauss(n: int):
    return np.polynomial.legendre.leggauss(n)


def frame(normal):
    """Two unit vectors that make (t1, t2, normal) a right-handed orthonormal frame."""
    t1 = -perpendicular(normal)
    return t1, np.cross(normal, t1)


def required(read, key, raw, names):
    """Fail naming the first of `names` missing from the table, with an example."""
    for k, example in names:
        if k not in raw:
            read.fail(f"{key}.{k}", "missing", f"add {key}.{k} = {example}")


def parse_common(read, key, raw, code, position, emitter, axis=None, sides=True) -> Light:
    """The Light of an area kind: its `radiance` (required) and `two_sided` (default false; a
    sphere emits outward only: `sides` false) read here, its geometry in `emitter`."""
    required(read, key, raw, (("radiance", "[10.0, 10.0, 10.0] (W / (m^2 sr))"),))
    radiance = power(read, f"{key}.radiance", read.rgb(f"{key}.radiance", raw["radiance"]))
    return Light(np.asarray(position, float), radiance, code, axis, emitter=emitter,
                 two_sided=sides and two_sided(read, key, raw))


def two_sided(read, key, raw) -> bool:
    """The table's `two_sided` (an area light's or an emissive shape's), default false."""
    two = raw.get("two_sided", False)
    if not isinstance(two, bool):
        read.fail(f"{key}.two_sided", f"expected true or false, got {two!r}",
                  "write two_sided = true to emit on both sides")
    return two


def emitter_rows(light: Light, points, normals, weights) -> Rows:
    """The spot rows (LAMBERT) of a cubature rule: emitter points (n, 3), unit normals (n, 3) and
    area weights (n,); a two-sided light's nodes again facing the other way."""
    if light.two_sided:
        points, normals, weights = (np.concatenate([points, points]), np.concatenate([normals, -normals]),
                                    np.concatenate([weights, weights]))
    n = len(weights)
    return Rows(np.ascontiguousarray(points, dtype=float), weights[:, None] * light.intensity[None, :],
                np.full(n, SPOT, dtype=np.int64), np.ascontiguousarray(normals, dtype=float),
                np.tile([0.0, 1.0, float(LAMBERT)], (n, 1)), cubature=True)


def radiance_text(light: Light) -> str:
    """The end of an area light's `describe`: radiance, sides, power."""
    sides = "two-sided" if light.two_sided else "one-sided"
    return f"radiance {light.intensity.tolist()}, {sides}, power {power_of(light).tolist()} W"


def power_of(light: Light) -> np.ndarray:
    """The emitted power per channel: pi L A one-sided, 2 pi L A two-sided (a Lambertian emitter)."""
    return np.pi * light.intensity * light.emitter["area"] * (2.0 if light.two_sided else 1.0)


@dataclass(frozen=True)
class Emitter:
    """One emitter as the surface term samples it: its `radiance` (3,), `two_sided`, and `sample(u, v)`
    mapping (u, v) (n,) each in [0, 1) to (points (n, 3) on the emitter, unit normals (n, 3) of its
    emitting side, area density (n,) of the map); the samples of a uniform (u, v) are uniform in area.
    `probes`: (points (K, 3), normals (K, 3)) at the emitter's corners, PROBE_INSET inside its outline
    (None: a sphere, which has none): a straight shadow edge that leaves every cubature node on one side leaves
    a corner on the other, so shadow rays to them find the penumbrae the rows miss."""
    radiance: np.ndarray
    two_sided: bool
    sample: Callable
    probes: tuple | None = None
    planar: object = None  # a flat emitter's planar.Planar (the rule about a camera ray's foot point)
    ball: object = None  # a sphere emitter's sphere_rule.Ball (the rule about a camera ray's segment)
    # irradiance(points, normals, shading, sigma_t, tol, missed) -> (E (M, 3), applies (M,)): the
    # unshadowed irradiance at surface points through a homogeneous medium to the relative tolerance tol,
    # where the kind has it in closed form about a centre (None: not; the kind's `surface_irradiance`);
    # missed (1,) += the points where it did not converge (the finest order kept)
    irradiance: Callable | None = None
    # rule(order) -> (points (n, 3), unit normals (n, 3), area weights (n,)): its rows' rule (`unit_rule`), built
    # once per order (the same arrays, read-only, at each call)
    rule: Callable | None = None
    # whether a sample on it can be shadowed by the emitter itself (an emissive shape's triangles: a shadow
    # ray from one leaves through the rest of the shape), so that its penumbrae are not sampled
    self_shadowing: bool = False
    triangles: np.ndarray | None = None  # an emissive shape's triangles (T, 3, 3), the pieces its samples are drawn on


def uniform_density(n: int, area: float) -> np.ndarray:
    """The area density 1 / A of a map that is uniform in area, for n samples."""
    return np.full(n, 1.0 / area)


def emitter(light: Light, sample_emitter, corners=None, planar=None, ball=None, irradiance=None,
            rows=None) -> Emitter:
    """The `Emitter` of an area light whose kind maps (u, v) by `sample_emitter(light, u, v)`, its
    probes at the parameters `corners` ((u, v), each (K,); None: no probes), `planar(light)` its
    `Planar` where the kind is flat, `ball(light)` its `Ball` where it is a sphere (None: not),
    `irradiance(light, ...)` its `Emitter.irradiance` where it has one, `rows(light, order)` its
    kind's rows (`Emitter.rule`: `unit_rule`)."""
    sample = functools.partial(sample_emitter, light)
    probes = None if corners is None else sample(*corners)[:2]
    rule = None if rows is None else functools.lru_cache(maxsize=None)(functools.partial(unit_rule, rows, light))
    return Emitter(light.intensity, light.two_sided, sample, probes, None if planar is None else planar(light),
                   None if ball is None else ball(light),
                   None if irradiance is None else functools.partial(irradiance, light), rule)


def unit_rule(rows, light: Light, order: int):
    """(points (n, 3), unit normals (n, 3), area weights (n,)) of the kind's `rows(light, order)`: the
    rows of the light made one-sided of unit radiance (`emitter_rows`' weights times 1), read-only (an
    `Emitter.rule` keeps them)."""
    r = rows(dataclasses.replace(light, intensity=np.ones(3), two_sided=False), order)
    out = r.position, r.axis, r.intensity[:, 0]
    for a in out:
        a.flags.writeable = False
    return out


def collapsed_variance(g, strata: int) -> np.ndarray:
    """(M, 3) the variance of the mean of g (M, 2 strata^2, 3): two samples in each of strata x strata
    strata, sample j = 2 (a strata + b) + s in stratum (a, b), estimated with the strata collapsed in
    blocks of 2 x 2 (Cochran, Sampling Techniques, 5A.12): 2 sum_B s_B^2 / strata^4, s_B^2 the sample
    variance of block B's 8 values; conservative (it adds the spread of the strata's means within a
    block), and unlike the pairs within one stratum it does not vanish where a shadow edge crosses
    strata whose two samples happen to agree."""
    half = strata // 2
    blocks = g.reshape(-1, half, 2, half, 2, 2, 3).transpose(0, 1, 3, 2, 4, 5, 6).reshape(-1, half * half, 8, 3)
    return 2.0 * blocks.var(axis=2, ddof=1).sum(axis=1) / (strata * strata) ** 2
