"""`atmosphere`: a planet's atmosphere (the exponential spherical atmosphere of "Sampling Analytic
Participating Media", Bruneton's layered model) as a participating medium: its geometry and its
closed-form transmittances (docs/atmosphere.md).

The planet is the sphere |p - c| = R, an opaque diffuse ground; the air fills R <= |p - c| <= top
with K layers, layer i of density rho_i(|p - c| - R) times its coefficients (sigma_a, sigma_s per
channel, its own phase function). A layer's profile is a row of the table `layers` (K, 3):
(EXPONENTIAL, H, 0) for exp(-altitude/H), coefficients at the ground, or (TENT, P, W) for
Bruneton's ozone, max(0, 1 - |altitude - P|/W), coefficients at the peak (tent.py). Along a ray
given by the altitude h and zenith cosine mu of its origin, layer i's column over [t0, t1] is
`layer_column` (Chapman's, eq. 40-48 of that article, for the exponential; tent.py's closed form for the
tent) over the part of [t0, t1] inside the top sphere, and the transmittance of channel c is
exp(-sum_i kt[i, c] column_i), or 0 if the ray meets the ground within [t0, t1]. The kernels also
take a 1-D array of scale heights for exponential layers. Everything here is float64: Embree's
float32 cannot place a 6360 km sphere to the metre (ARCHITECTURE.md), so the medium intersects its
own spheres; `ground_distance` is the planet's.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba.extending import overload

from ..jit import njit
from ..lights import distant
from .chapman import atmosphere_column, ground_distance, relative_error
from .medium import Medium, kernel_arrays
from .phase import HG, NAMES as PHASE_NAMES, phase_value
from .tent import tent_breaks, tent_column, tent_density

EXPONENTIAL, TENT = 0, 1  # layer profiles: codes in column 0 of the layers table
PROFILES = {"exponential": EXPONENTIAL, "tent": TENT}
PROFILE_KEYS = {EXPONENTIAL: {"scale_height"}, TENT: {"peak_altitude", "half_width"}}
LAYER_KEYS = {"name", "sigma_a", "sigma_s", "phase", "profile"} | set().union(*PROFILE_KEYS.values())
ULP = 2.0 ** -53
MIN_RADIUS_OVER_H = 3.0  # radius / scale_height below this is outside the Chapman kernels' measured range


@dataclass(kw_only=True)
class Atmosphere(Medium):
    """A planet (centre, radius, ground reflectance) and K layers of air up to `top`: layer i has the
    profile layers[i], coefficients layer_sigma_a[i], layer_sigma_s[i] (RGB) where its density is 1
    and the phase function (phases[i], gs[i]); sigma_a, sigma_s are the layers' sums."""
    center: np.ndarray
    radius: float
    top: float
    ground: np.ndarray
    names: tuple
    layers: np.ndarray  # (K, 3)
    layer_sigma_a: np.ndarray  # (K, 3)
    layer_sigma_s: np.ndarray  # (K, 3)
    phases: np.ndarray  # (K,) int64
    gs: np.ndarray  # (K,)

    type_name = "atmosphere"
    keys = frozenset({"type", "center", "radius", "top_radius", "reflectance", "layer"})
    has_ground = True

    @property
    def layer_sigma_t(self) -> np.ndarray:
        return self.layer_sigma_a + self.layer_sigma_s

    @classmethod
    def parse(cls, read, raw):
        """Planet `center`, `radius`, the ground's `reflectance`, air up to `top_radius`, and
        [[medium.layer]] tables, each with its coefficients, profile and `phase`."""
        for k, example in (("center", "[0.0, -6360000.0, 0.0]"), ("radius", "6360000.0"), ("top_radius", "6420000.0")):
            if k not in raw:
                read.fail(f"medium.{k}", "missing", f"add medium.{k} = {example}")
        center = read.vec3("medium.center", raw["center"])
        radius = float(read.number("medium.radius", raw["radius"], positive=True))
        top = float(read.number("medium.top_radius", raw["top_radius"]))
        if not top > radius:
            read.fail("medium.top_radius", f"must exceed medium.radius = {radius:g}, got {top!r}",
                      "give the radius of the top of the atmosphere, e.g. radius + 60000.0")
        layers = raw.get("layer")
        if not isinstance(layers, list) or not layers:
            read.fail("medium.layer", "an atmosphere needs at least one layer", "add [[medium.layer]] tables (sigma_s, "
                      "sigma_a, scale_height, phase), e.g. Rayleigh and Mie")
        names, rows, sa, ss, phases, gs = [], [], [], [], [], []
        for i, layer in enumerate(layers):
            key = f"medium.layer[{i}]"
            layer = read.table(key, layer)
            read.unknown(key, layer, LAYER_KEYS)
            name = layer.get("name", f"layer {i}")
            if not isinstance(name, str):
                read.fail(f"{key}.name", f"expected a string, got {name!r}", 'write name = "rayleigh"')
            names.append(name)
            rows.append(_layer_profile(read, key, layer, radius))
            sa.append(read.rgb(f"{key}.sigma_a", layer.get("sigma_a", 0.0)))
            ss.append(read.rgb(f"{key}.sigma_s", layer.get("sigma_s", 0.0)))
            code, g = read.phase(layer.get("phase", "isotropic"), f"{key}.phase")
            phases.append(code)
            gs.append(g)
        sa, ss = np.array(sa), np.array(ss)
        return cls(sa.sum(axis=0), ss.sum(axis=0), center=center, radius=radius, top=top,
                   ground=read.rgb("medium.reflectance", raw.get("reflectance", 0.0)), names=tuple(names),
                   layers=np.array(rows, dtype=np.float64), layer_sigma_a=sa, layer_sigma_s=ss,
                   phases=np.array(phases, dtype=np.int64), gs=np.array(gs))

    def check_scene(self, read, camera, lights):
        """Neither the camera nor a light may sit inside the planet (it is opaque)."""
        if self.inside(camera.position):
            read.fail("camera.position", f"{camera.position.tolist()} is inside the planet (medium.center "
                      f"{self.center.tolist()}, radius {self.radius:g})", "move the camera onto or above the ground")
        for i, light in enumerate(lights):
            if not distant(light) and self.inside(light.position):
                read.fail(f"light[{i}].position", f"{light.position.tolist()} is inside the planet (medium.center "
                          f"{self.center.tolist()}, radius {self.radius:g})", "move the light above the ground")

    def describe(self):
        out = [f"medium: atmosphere, planet centre {self.center.tolist()}, radius {self.radius:g}, top radius "
               f"{self.top:g}, ground reflectance {self.ground.tolist()}"]
        for i, name in enumerate(self.names):
            phase = PHASE_NAMES[int(self.phases[i])] + (f" g={self.gs[i]}" if self.phases[i] == HG else "")
            out.append(f"  layer[{i}] {name}: sigma_a {self.layer_sigma_a[i].tolist()}, sigma_s "
                       f"{self.layer_sigma_s[i].tolist()} {_profile_text(self.layers[i])}, phase {phase}")
        return out

    def inside(self, points: np.ndarray) -> np.ndarray:
        """True for points strictly inside the planet."""
        return np.linalg.norm(np.asarray(points, float) - self.center, axis=-1) < self.radius

    def transmittance_on(self, origins, dirs, a, b):
        n = len(origins)
        out = np.empty((n, 3))
        ray_transmittance(*kernel_arrays(n, origins, dirs, a, b), *(float(v) for v in self.center), float(self.radius),
                          float(self.top), self.layers, np.ascontiguousarray(self.layer_sigma_t.T), out)
        return out

    def ground_hits(self, origins, dirs) -> np.ndarray:
        """The distance (N,) to the ground along each ray (inf if it misses), in float64."""
        tg = np.empty(len(origins))
        planet_hits(np.ascontiguousarray(origins, float), np.ascontiguousarray(dirs, float),
                    *(float(c) for c in self.center), float(self.radius), tg)
        return tg

    def ground_surface(self, points):
        """(normals, reflectances) (N, 3) of the ground at `points` on it."""
        up = points - self.center
        return up / np.linalg.norm(up, axis=1)[:, None], np.broadcast_to(self.ground, points.shape)


def _layer_profile(read, key, layer, radius):
    """The row of the layers table of one [[medium.layer]]."""
    name = read.string(f"{key}.profile", layer.get("profile", "exponential"), tuple(PROFILES))
    code = PROFILES[name]
    for other in sorted(set().union(*PROFILE_KEYS.values()) - PROFILE_KEYS[code]):
        if other in layer:
            owner = next(n for n, c in PROFILES.items() if other in PROFILE_KEYS[c])
            read.fail(f"{key}.{other}", f"only a{'n' if owner[0] in 'aeiou' else ''} {owner} layer has it, this "
                      f"layer is {name}", f'remove it or write profile = "{owner}"')
    if code == TENT:
        return _tent_profile(read, key, layer, radius)
    if "scale_height" not in layer:
        read.fail(f"{key}.scale_height", "missing", "add scale_height = 8000.0 (the height over which the density "
                  "falls by e)")
    H = float(read.number(f"{key}.scale_height", layer["scale_height"]))
    if not H > 0.0:
        read.fail(f"{key}.scale_height", f"must be positive, got {H!r}", "use a height greater than 0, e.g. 8000.0")
    if radius / H < MIN_RADIUS_OVER_H:
        read.fail(f"{key}.scale_height", f"{H:g} exceeds medium.radius / {MIN_RADIUS_OVER_H:g}",
                  "use a scale height well below the planet's radius (the closed form is verified for "
                  f"radius / scale_height >= {MIN_RADIUS_OVER_H:g})")
    return (EXPONENTIAL, H, 0.0)


def _tent_profile(read, key, layer, radius):
    """(TENT, peak altitude, half-width) of a tent layer: the peak on or above the ground, the
    half-width positive and below the planet's radius (the tent's spheres have positive radii)."""
    for k, example in (("peak_altitude", "25000.0"), ("half_width", "15000.0")):
        if k not in layer:
            read.fail(f"{key}.{k}", "missing", f"add {k} = {example} (Bruneton's ozone)")
    peak = float(read.number(f"{key}.peak_altitude", layer["peak_altitude"]))
    if peak < 0.0:
        read.fail(f"{key}.peak_altitude", f"must be at or above the ground (>= 0), got {peak!r}",
                  "give the altitude of the density's peak above the ground, e.g. 25000.0")
    width = float(read.number(f"{key}.half_width", layer["half_width"]))
    if not 0.0 < width < radius:
        read.fail(f"{key}.half_width", f"must be positive and below medium.radius = {radius:g}, got {width!r}",
                  "give the altitude range from the peak to where the density reaches 0, e.g. 15000.0")
    return (TENT, peak, width)


def _profile_text(row):
    if row[0] == TENT:
        return f"at the peak, tent profile, peak altitude {row[1]:g}, half width {row[2]:g}"
    return f"at the ground, scale height {row[1]:g}"


# --- a layer's density and column: the layers table (K, 3), or a 1-D array of scale heights ------

def layer_density(layers, i, hx):
    """Layer i's density at altitude hx."""


def layer_column(layers, i, h, mu, t0, t1, radius):
    """Layer i's unit-density column over [t0, t1] (inside the top sphere) of the ray from altitude h
    with zenith cosine mu."""


@overload(layer_density)
def _layer_density(layers, i, hx):
    if layers.ndim == 1:
        return lambda layers, i, hx: math.exp(-hx / layers[i])
    return lambda layers, i, hx: (tent_density(hx, layers[i, 1], layers[i, 2]) if layers[i, 0] == TENT
                                  else math.exp(-hx / layers[i, 1]))


@overload(layer_column, inline="always")  # typed into `columns`: no compilation of its own
def _layer_column(layers, i, h, mu, t0, t1, radius):
    if layers.ndim == 1:
        return lambda layers, i, h, mu, t0, t1, radius: atmosphere_column(h, mu, t0, t1, radius, layers[i])
    return lambda layers, i, h, mu, t0, t1, radius: (
        tent_column(h, mu, t0, t1, radius, layers[i, 1], layers[i, 2]) if layers[i, 0] == TENT
        else atmosphere_column(h, mu, t0, t1, radius, layers[i, 1]))


@njit
def max_density_breaks(layers):
    """The most breakpoints `density_breaks` gives for these layers."""
    n = 1
    for i in range(layers.shape[0]):
        if layers[i, 0] == TENT:
            n += 6
    return n


@njit
def density_breaks(row, layers, radius, out):
    """The distances along a segment (its row, below) where the integrand's density factor is not
    smooth or peaks, into out; returns their count (at most `max_density_breaks`): the ray's lowest
    point, where the exponential densities peak, and where it crosses a tent's spheres (its ends
    and its peak); they may lie outside the segment."""
    out[0] = -(row[QX] * row[WX] + row[QY] * row[WY] + row[QZ] * row[WZ])
    n = 1
    for i in range(layers.shape[0]):
        if layers[i, 0] == TENT:
            n += tent_breaks(row[H0], row[MU0], radius, layers[i, 1], layers[i, 2], out[n:])
    return n


GROUND_MARGIN = 1e-9


@njit
def altitude_mu(qx, qy, qz, wx, wy, wz, radius):
    """(h, mu) of the point c + q looking along the unit w: altitude |q| - R (clamped at 0: a point
    on the ground computed a rounding below it) and the cosine of the zenith angle."""
    r = math.sqrt(qx * qx + qy * qy + qz * qz)
    if not r > 0.0:
        return 0.0, 1.0
    mu = min(max((qx * wx + qy * wy + qz * wz) / r, -1.0), 1.0)
    return max(r - radius, 0.0), mu


@njit
def shell(h, mu, radius, top):
    """(t_in, t_out): the part t >= 0 of the ray inside the top sphere (radius `top`); t_in > t_out
    when the ray never is. top^2 - b^2 = (top - r0)(top + r0) + s0^2 (b the impact parameter, s0 =
    r0 mu; not from b, whose rounding would cost ~eps r0 / (top - b) near the tangent), and both
    ends from products, without the cancellation of -s0 -+ sqrt(...)."""
    r0 = radius + h
    s0 = r0 * mu
    disc = (top - r0) * (top + r0) + s0 * s0
    if not disc > 0.0:
        return 1.0, 0.0
    half = math.sqrt(disc)
    if r0 <= top:
        t_out = half - s0 if s0 <= 0.0 else (top - r0) * (top + r0) / (half + s0)
        return 0.0, t_out
    if s0 >= 0.0:  # outside, going away
        return 1.0, 0.0
    t_in = (r0 - top) * (r0 + top) / (half - s0)
    return t_in, half - s0


@njit
def columns(h, mu, t0, t1, radius, top, layers, out):
    """out[i] = layer i's unit-density column over [t0, t1] (t1 may be inf) inside the top sphere;
    False (out untouched) when the ground lies within [t0, t1] (the transmittance is 0). A segment
    that ends on the ground is not blocked by it: the hit counts only 1e-9 (relative) before t1,
    since kernels compiled with `contract`/`reassoc` (jit.py) round the same ground distance
    differently by a few ulps."""
    if ground_distance(h, mu, radius) < t1 * (1.0 - GROUND_MARGIN):
        return False
    a, b = shell(h, mu, radius, top)
    lo, hi = max(t0, a), min(t1, b)
    for i in range(layers.shape[0]):
        out[i] = layer_column(layers, i, h, mu, lo, hi, radius) if hi > lo else 0.0
    return True


@njit
def optical_depth(cols, kt):
    """sum_i kt[i] cols[i] of one channel's layer extinctions kt (K,)."""
    tau = 0.0
    for i in range(kt.shape[0]):
        if kt[i] != 0.0:
            tau += kt[i] * cols[i]
    return tau


@njit
def ray_transmittance(origins, dirs, a, b, cx, cy, cz, radius, top, layers, kt, out):
    """out[n, c] = transmittance over [a[n], b[n]] of ray n (a may be negative: counted from the
    point origin + a dir; b may be inf) in channel c; kt (3, K): a channel's row is contiguous, as
    the kt of the other kernels' `optical_depth` (one specialisation)."""
    cols = np.empty(layers.shape[0])
    for n in range(origins.shape[0]):
        s = a[n]
        qx = origins[n, 0] + s * dirs[n, 0] - cx
        qy = origins[n, 1] + s * dirs[n, 1] - cy
        qz = origins[n, 2] + s * dirs[n, 2] - cz
        h, mu = altitude_mu(qx, qy, qz, dirs[n, 0], dirs[n, 1], dirs[n, 2], radius)
        if not columns(h, mu, 0.0, b[n] - s, radius, top, layers, cols):
            for c in range(3):
                out[n, c] = 0.0
            continue
        for c in range(3):
            out[n, c] = math.exp(-optical_depth(cols, kt[c]))


@njit
def planet_hits(origins, dirs, cx, cy, cz, radius, out):
    """out[n] = the distance to the ground along ray n (inf if it misses), in float64."""
    for n in range(origins.shape[0]):
        h, mu = altitude_mu(origins[n, 0] - cx, origins[n, 1] - cy, origins[n, 2] - cz, dirs[n, 0], dirs[n, 1],
                            dirs[n, 2], radius)
        out[n] = ground_distance(h, mu, radius)


# --- one segment's in-scattering integrand -------------------------------------------------------
# A segment's row (`segment_rows`): its start relative to the centre, its direction, its start's
# altitude and zenith cosine, the part [A, B] of [0, ell] inside the air, and the light: for the
# sun the unit vector toward it and the scattering cosine, for a point or spot light its position
# relative to the centre.
QX, QY, QZ, WX, WY, WZ, H0, MU0, A, B, LX, LY, LZ, COSD = range(14)
ROW = 14


@njit
def segment_rows(origins, dirs, ell, lpos, laxis, light, directional, cx, cy, cz, radius, top, rows):
    """Fill rows (S, ROW) of a segment batch (see above)."""
    for s in range(origins.shape[0]):
        r = rows[s]
        r[QX], r[QY], r[QZ] = origins[s, 0] - cx, origins[s, 1] - cy, origins[s, 2] - cz
        r[WX], r[WY], r[WZ] = dirs[s, 0], dirs[s, 1], dirs[s, 2]
        r[H0], r[MU0] = altitude_mu(r[QX], r[QY], r[QZ], r[WX], r[WY], r[WZ], radius)
        a, b = shell(r[H0], r[MU0], radius, top)
        r[A], r[B] = a, min(b, ell[s])
        li = light[s]
        if directional[s]:
            r[LX], r[LY], r[LZ] = -laxis[li, 0], -laxis[li, 1], -laxis[li, 2]
            r[COSD] = laxis[li, 0] * -dirs[s, 0] + laxis[li, 1] * -dirs[s, 1] + laxis[li, 2] * -dirs[s, 2]
        else:
            r[LX], r[LY], r[LZ] = lpos[li, 0] - cx, lpos[li, 1] - cy, lpos[li, 2] - cz
            r[COSD] = 0.0


@njit
def density_sum(hx, layers, coef):
    """sum_i coef[i] rho_i(hx): a channel's extinction (coef = kt) or scattering at altitude hx."""
    out = 0.0
    for i in range(coef.shape[0]):
        if coef[i] != 0.0:
            out += coef[i] * layer_density(layers, i, hx)
    return out


@njit
def light_frame(x, row, directional, radius):
    """At distance x of a segment: (h, p, l, d, cos, mu_l) with p = the point relative to the
    centre (3 floats), l the unit vector toward the light (3 floats), d the distance to it (inf
    for the sun), cos the scattering cosine (the light's travel direction . -w) and mu_l = the
    zenith cosine of l at p; d = 0 (a point on the light) gives d = 0 and l = 0."""
    px, py, pz = row[QX] + x * row[WX], row[QY] + x * row[WY], row[QZ] + x * row[WZ]
    r = math.sqrt(px * px + py * py + pz * pz)
    hx = max(r - radius, 0.0)
    if directional:
        lx, ly, lz, d, cos = row[LX], row[LY], row[LZ], math.inf, row[COSD]
    else:
        lx, ly, lz = row[LX] - px, row[LY] - py, row[LZ] - pz
        d = math.sqrt(lx * lx + ly * ly + lz * lz)
        if not d > 0.0:
            return hx, px, py, pz, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0
        lx, ly, lz = lx / d, ly / d, lz / d
        cos = lx * row[WX] + ly * row[WY] + lz * row[WZ]  # travel direction -l against the way back -w
    mul = min(max((px * lx + py * ly + pz * lz) / r, -1.0), 1.0)
    return hx, px, py, pz, lx, ly, lz, d, cos, mul


@njit
def scattering(hx, cos, ks, codes, gs, layers):
    """sum_i ks_i rho_i(hx) Phi_i(cos): the layers' scattering at altitude hx toward the camera."""
    acc = 0.0
    for i in range(ks.shape[0]):
        if ks[i] != 0.0:
            acc += ks[i] * layer_density(layers, i, hx) * phase_value(codes[i], gs[i], cos)
    return acc


@njit(inline="always")  # a one-line wrapper: typed into its caller, no compilation of its own
def inscatter(x, row, directional, kt, ks, codes, gs, layers, radius, top, cols, tau_cam):
    """In-scattered radiance per unit length at distance x of a segment, one channel, unit light,
    without a point light's 1/d^2 or spot falloff: T_cam(x) T_light(x) sum_i ks_i rho_i(x)
    Phi_i(cos), T_cam from the segment's start (`tau_cam`: its optical depth if the caller has it,
    else negative), T_light to the light or, for the sun, out of the atmosphere (0 behind the
    planet). kt, ks: (K,) of the channel."""
    return inscatter_parts(x, row, directional, kt, ks, codes, gs, layers, radius, top, cols, tau_cam, 0.0)[0]


@njit
def inscatter_parts(x, row, directional, kt, ks, codes, gs, layers, radius, top, cols, tau_cam, dz):
    """`inscatter` and what its rounding depends on (methods/quadrature.py's bound): (value, the
    optical depth T_cam T_light stands for, a bound on that depth's error when every altitude is off
    by at most dz (`depth_error`; the camera's part only where this computed tau_cam), the altitude
    of x, the distance d to the light)."""
    hx, _, _, _, _, _, _, d, cos, mul = light_frame(x, row, directional, radius)
    if not d > 0.0:
        return 0.0, 0.0, 0.0, hx, d
    if not columns(hx, mul, 0.0, d, radius, top, layers, cols):
        return 0.0, math.inf, 0.0, hx, d
    tau = optical_depth(cols, kt)
    err = depth_error(cols, kt, layers, radius, dz, min(d, 2.0 * top))
    if tau_cam < 0.0:
        columns(row[H0], row[MU0], 0.0, x, radius, top, layers, cols)
        tau_cam = optical_depth(cols, kt)
        err += depth_error(cols, kt, layers, radius, dz, x)
    return scattering(hx, cos, ks, codes, gs, layers) * math.exp(-tau - tau_cam), tau + tau_cam, err, hx, d


@njit
def depth_error(cols, kt, layers, radius, dz, length):
    """A bound on the error of `optical_depth`(cols, kt) of a path of `length` whose altitudes are
    off by at most dz (docs/error_bounds.md, "Atmospheres"): an exponential layer's column by
    dz / H relative (its density's) plus Chapman's rule's `relative_error` and 8 ulp; a tent's by
    dz / W absolutely over the path (its density 1 - |a - P| / W) plus 8 ulp; layers table (K, 3)."""
    err = 0.0
    for i in range(kt.shape[0]):
        if kt[i] != 0.0 and cols[i] > 0.0:
            if layers[i, 0] == TENT:
                err += kt[i] * (length * dz / layers[i, 2] + 8.0 * ULP * cols[i])
            else:
                H = layers[i, 1]
                err += kt[i] * cols[i] * (dz / H + relative_error(radius / H) + 8.0 * ULP)
    return err


@njit
def density_condition(hx, layers, ks):
    """max over the scattering layers (ks_i != 0) of |d log rho_i / d altitude| at hx: 1/H, or
    1 / (W rho) for a tent (inf where its density is 0 but for the rounding of hx)."""
    out = 0.0
    for i in range(ks.shape[0]):
        if ks[i] != 0.0:
            if layers[i, 0] == TENT:
                rho = tent_density(hx, layers[i, 1], layers[i, 2])
                out = max(out, 1.0 / (layers[i, 2] * rho) if rho > 0.0 else 0.0)
            else:
                out = max(out, 1.0 / layers[i, 1])
    return out


@njit
def free_path(row, x_lo, x_hi, target, kt, layers, radius, top, cols):
    """The x in [x_lo, x_hi] where the channel's optical depth from x_lo reaches `target` (which
    the caller keeps below the whole interval's): safeguarded Newton on the sum of the layers'
    closed-form columns (f' = the extinction at x, the article's eq. 17), bisection when a step leaves
    the bracket; stops at |f| <= 1e-13 target or when the bracket is two neighbouring doubles."""
    lo, hi = x_lo, x_hi
    h0, mu0 = row[H0], row[MU0]
    ext = extinction_at(x_lo, row, kt, layers, radius)
    x = x_lo + target / ext if ext > 0.0 else 0.5 * (lo + hi)
    if not lo < x < hi:
        x = 0.5 * (lo + hi)
    for _ in range(100):
        columns(h0, mu0, x_lo, x, radius, top, layers, cols)
        f = optical_depth(cols, kt) - target
        if abs(f) <= 1e-13 * target:
            return x
        if f < 0.0:
            lo = x
        else:
            hi = x
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            return x
        ext = extinction_at(x, row, kt, layers, radius)
        nxt = x - f / ext if ext > 0.0 else mid
        x = nxt if lo < nxt < hi else mid
    return x


@njit
def extinction_at(x, row, kt, layers, radius):
    """The channel's extinction sum_i kt_i rho_i at distance x of a segment."""
    px, py, pz = row[QX] + x * row[WX], row[QY] + x * row[WY], row[QZ] + x * row[WZ]
    return density_sum(max(math.sqrt(px * px + py * py + pz * pz) - radius, 0.0), layers, kt)


@njit
def planet_shadow(row, radius, out):
    """The x in (A, B) where the segment crosses the edge of the planet's shadow cylinder (the sun
    direction s = row[LX:LZ]; points with q.s < 0 and |q - (q.s) s| = R): T_sun jumps there.
    Returns their count (<= 2), ascending in out."""
    sx, sy, sz = row[LX], row[LY], row[LZ]
    qs = row[QX] * sx + row[QY] * sy + row[QZ] * sz
    ws = row[WX] * sx + row[WY] * sy + row[WZ] * sz
    ux, uy, uz = row[QX] - qs * sx, row[QY] - qs * sy, row[QZ] - qs * sz
    vx, vy, vz = row[WX] - ws * sx, row[WY] - ws * sy, row[WZ] - ws * sz
    a2 = vx * vx + vy * vy + vz * vz
    b1 = ux * vx + uy * vy + uz * vz
    c0 = (math.sqrt(ux * ux + uy * uy + uz * uz) - radius) * (math.sqrt(ux * ux + uy * uy + uz * uz) + radius)
    disc = b1 * b1 - a2 * c0
    if not (a2 > 0.0 and disc > 0.0):
        return 0
    q = -(b1 + math.copysign(math.sqrt(disc), b1))
    n = 0
    for x in (q / a2, c0 / q if q != 0.0 else math.inf):
        if row[A] < x < row[B] and qs + x * ws < 0.0:
            out[n] = x
            n += 1
    if n == 2 and out[1] < out[0]:
        out[0], out[1] = out[1], out[0]
    return n


@njit
def sunlit(row, radius, cuts, out):
    """The pieces of [A, B] from which the sun (row[LX:LZ]) is not behind the planet, split at
    `planet_shadow`'s crossings: out[k] = (lo, hi), ascending; returns their count (<= 3). cuts:
    scratch of 2."""
    n = planet_shadow(row, radius, cuts)
    sx, sy, sz = row[LX], row[LY], row[LZ]
    m = 0
    lo = row[A]
    for k in range(n + 1):
        hi = cuts[k] if k < n else row[B]
        mid = 0.5 * (lo + hi)
        qx, qy, qz = row[QX] + mid * row[WX], row[QY] + mid * row[WY], row[QZ] + mid * row[WZ]
        qs = qx * sx + qy * sy + qz * sz
        ux, uy, uz = qx - qs * sx, qy - qs * sy, qz - qs * sz
        if hi > lo and not (qs < 0.0 and ux * ux + uy * uy + uz * uz < radius * radius):
            out[m, 0], out[m, 1] = lo, hi
            m += 1
        lo = hi
    return m
