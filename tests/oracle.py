"""Slow, obvious twins of the renderer, written from SCENE_FORMAT.md and METHODS.md alone.

Nothing here imports the renderer: the camera rays, the ray-box intersection, the surface term
and the air-light (scipy `quad` of eq. 4 in the distance x, split at the light's foot point) are
re-derived, so agreement with the renderer tests the conventions as well as the numbers.
Only box rooms with lights inside are supported (every surface point sees every light); lights
may be spot lights. Height fogs (`fog_pixel`): box rooms or the ground plane y = 0, with point,
spot and directional lights, every optical depth a scipy quad of the density.
"""
from __future__ import annotations

import math

import numpy as np
from scipy import integrate, optimize


def triangle_hits(tris, o, d):
    """Moller-Trumbore in float64 against every triangle of tris (T, 3, 3): (t, u, v, det) (T,) each, the ray
    o + t d meeting the triangle's plane at barycentric (u, v) (inf or nan where det = 0); the caller decides
    what counts as a hit."""
    e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        s = o - tris[:, 0]
        u = np.einsum("ij,ij->i", s, p) * inv
        q = np.cross(s, e1)
        v = (q @ d) * inv
        t = np.einsum("ij,ij->i", e2, q) * inv
    return t, u, v, det


def set_changes(signature, ell: float, n: int = 401) -> list[float]:
    """[0, ..., ell]: the points of (0, ell) where `signature(x)` (a set of the paths lighting x) changes, found on
    a grid of n points (its ends 1e-9 of ell inside) and bisected 50 times each."""
    grid = np.linspace(0.0, ell, n)
    grid[0], grid[-1] = 1e-9 * ell, ell * (1 - 1e-9)
    sig = [signature(x) for x in grid]
    cuts = [0.0]
    for a, b, sa, sb in zip(grid, grid[1:], sig, sig[1:]):
        if sa != sb:
            for _ in range(50):
                m = 0.5 * (a + b)
                if signature(m) == sa:
                    a = m
                else:
                    b = m
            cuts.append(0.5 * (a + b))
    return cuts + [ell]


def phase(name: str, g: float, mu: float) -> float:
    if name == "isotropic":
        return 1.0 / (4.0 * math.pi)
    if name == "rayleigh":
        return 3.0 / (16.0 * math.pi) * (1.0 + mu * mu)
    return (1.0 - g * g) / (4.0 * math.pi * (1.0 + g * g - 2.0 * g * mu) ** 1.5)


def camera_ray(cam: dict, i: int, j: int, s: float = 0.5, t: float = 0.5):
    pos = np.array(cam["position"], float)
    fwd = np.array(cam["look_at"], float) - pos
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, np.array(cam.get("up", [0.0, 1.0, 0.0]), float))
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    W, H = cam["width"], cam["height"]
    if cam.get("type", "perspective") == "perspective":
        tan = math.tan(math.radians(cam.get("fov", 60.0)) / 2)
        d = fwd + (2 * (i + s) / W - 1) * tan * (W / H) * right + (1 - 2 * (j + t) / H) * tan * up
    else:
        phi = 2 * math.pi * ((i + s) / W - 0.5)
        theta = math.pi * (j + t) / H
        d = math.sin(theta) * (math.cos(phi) * fwd + math.sin(phi) * right) + math.cos(theta) * up
    return pos, d / np.linalg.norm(d)


def box_exit(o, d, lo, hi):
    """Distance to the wall of the box [lo, hi] that a ray from inside leaves through, and its
    inward normal."""
    best, normal = math.inf, None
    for a in range(3):
        if d[a] > 0:
            t, n = (hi[a] - o[a]) / d[a], -1.0
        elif d[a] < 0:
            t, n = (lo[a] - o[a]) / d[a], 1.0
        else:
            continue
        if t < best:
            best = t
            normal = np.zeros(3)
            normal[a] = n
    return best, normal


def spot_of(light: dict):
    """(axis, cos_end, cos_start) of a [[light]] table of type "spot" (SCENE_FORMAT.md, pbrt-v4's
    SpotLight: defaults cone_angle 30, falloff_start cone_angle - 5), None for a point light."""
    if light.get("type", "point") != "spot":
        return None
    p = np.asarray(light["position"], float)
    axis = np.asarray(light["look_at"], float) - p if "look_at" in light else np.asarray(light["direction"], float)
    cone = light.get("cone_angle", 30.0)
    start = light.get("falloff_start", max(cone - 5.0, 0.0))
    return axis / np.linalg.norm(axis), math.cos(math.radians(cone)), math.cos(math.radians(start))


def emission(spot, direction, curve="smoothstep") -> float:
    """The spot's falloff toward the unit `direction` from the light, between its core and its cone:
    "smoothstep" in the cosine (pbrt-v4's SpotLight), "mitsuba" linear in the angle from the axis
    (Mitsuba 3's spot: (cutoff_angle - angle) / (cutoff_angle - beam_width)), "gltf" the ramp
    (cos - cos_outer) / (cos_inner - cos_outer) squared (KHR_lights_punctual)."""
    if spot is None:
        return 1.0
    axis, cos_end, cos_start = spot
    c = float(direction @ axis)
    if c >= cos_start:
        return 1.0
    if c <= cos_end:
        return 0.0
    if curve == "mitsuba":
        (ax, ay, az), (dx, dy, dz) = axis, direction
        angle = math.atan2(math.hypot(ay * dz - az * dy, az * dx - ax * dz, ax * dy - ay * dx), c)
        cutoff, beam = math.acos(cos_end), math.acos(cos_start)
        return (cutoff - angle) / (cutoff - beam)
    t = (c - cos_end) / (cos_start - cos_end)
    if curve == "gltf":
        return min(max(t, 0.0), 1.0) ** 2
    assert curve == "smoothstep", curve
    return t * t * (3 - 2 * t)


def lamp_at(light: dict, X):
    """(unit direction from X to the point or spot light, distance, unattenuated irradiance on a
    surface facing it, the spot's falloff toward X)."""
    rel = np.asarray(light["position"], float) - X
    dist = float(np.linalg.norm(rel))
    fall = emission(spot_of(light), -rel / dist, light.get("falloff", "smoothstep"))
    return rel / dist, dist, light["intensity"] * fall / dist**2, fall


def cone_crossings(o, d, tmax, p, spot):
    """Distances in (0, tmax) where the ray crosses the spot's cone or core, by bracketing the
    cosine to the axis on a grid uniform in the distance and in the angle seen from the light (rays
    to infinity: up to 1e4 beyond the light) and brentq."""
    if spot is None:
        return []
    axis, cos_end, cos_start = spot
    end = tmax if math.isfinite(tmax) else float(np.linalg.norm(p - o)) + 1e4

    def cos(x):
        r = o + x * d - p
        return float(r @ axis) / math.sqrt(r @ r)

    xh, h = float((p - o) @ d), float(np.linalg.norm(np.cross(p - o, d)))
    angles = np.linspace(-0.5 * math.pi, 0.5 * math.pi, 2001)[1:-1]
    xs = np.concatenate([np.linspace(0.0, end, 2001)[1:-1], [xh], xh + h * np.tan(angles)])
    xs = np.sort(xs[(xs > 0) & (xs < end)])
    out = []
    for level in (cos_end, cos_start):
        vals = np.array([cos(x) for x in xs]) - level
        for i in np.nonzero(np.sign(vals[:-1]) != np.sign(vals[1:]))[0]:
            out.append(optimize.brentq(lambda x: cos(x) - level, xs[i], xs[i + 1], xtol=1e-14, rtol=1e-15))
    return out


def airlight(o, d, tmax, light, intensity, kt, ks, phase_name, g, spot=None, curve="smoothstep"):
    if ks == 0.0:
        return 0.0
    p = np.asarray(light, float)

    def f(x):
        q = o + x * d
        to = p - q
        dist = math.sqrt(to @ to)
        mu = -(x - xh) / dist  # cosine between the light's travel direction and the way back to the camera
        return (math.exp(-kt * (x + dist)) * ks * intensity * phase(phase_name, g, mu) * emission(spot, -to / dist, curve)
                / dist**2)

    xh = float((p - o) @ d)
    h = float(np.linalg.norm(np.cross(p - o, d)))
    points = {x for x in (xh - 10 * h, xh - h, xh, xh + h, xh + 10 * h) if 0.0 < x < tmax}
    points = sorted(points | set(cone_crossings(o, d, tmax, p, spot)))
    edges = [0.0] + points + [tmax]
    total = 0.0
    for a, b in zip(edges[:-1], edges[1:]):
        val, _ = integrate.quad(f, a, b, epsabs=0.0, epsrel=1e-12, limit=400)
        total += val
    return total


def box_room_pixel(scene: dict, i: int, j: int) -> np.ndarray:
    """Radiance of the pixel centre (spp = 1) of a box-room scene described as a plain dict."""
    cam = scene["camera"]
    box = scene["shape"][0]
    lo, hi = np.array(box["min"], float), np.array(box["max"], float)
    rho = np.broadcast_to(np.array(box.get("reflectance", 0.5), float), 3)
    med = scene.get("medium", {})
    ka = np.broadcast_to(np.array(med.get("sigma_a", 0.0), float), 3)
    ks = np.broadcast_to(np.array(med.get("sigma_s", 0.0), float), 3)
    kt = ka + ks
    ph = med.get("phase", "isotropic")
    name, g = (ph, 0.0) if isinstance(ph, str) else (ph.get("type", "hg"), ph.get("g", 0.0))
    o, d = camera_ray(cam, i, j)
    t, n = box_exit(o, d, lo, hi)
    x = o + t * d
    out = np.zeros(3)
    for light in scene["light"]:
        p = np.array(light["position"], float)
        inten = np.broadcast_to(np.array(light["intensity"], float), 3)
        spot = spot_of(light)
        to = p - x
        dist = math.sqrt(to @ to)
        curve = light.get("falloff", "smoothstep")
        cos = max(0.0, float(n @ to) / dist) * emission(spot, -to / dist, curve)
        for c in range(3):
            surface = rho[c] / math.pi * inten[c] * math.exp(-kt[c] * dist) / dist**2 * cos
            out[c] += math.exp(-kt[c] * t) * surface
            out[c] += airlight(o, d, t, p, inten[c], kt[c], ks[c], name, g, spot, curve)
    return out


def plate_shadow_breaks(o, d, tmax, light, plate):
    """Distances along the ray o + x d (0 < x < tmax) where the segment light → point starts or stops
    crossing the rectangle plate = (y0, (xmin, xmax), (zmin, zmax)) in the plane y = y0. The crossing
    point's x and z coordinates are ratios of linear functions of x, so every edge gives one linear
    equation."""
    y0, (x_lo, x_hi), (z_lo, z_hi) = plate
    L = np.asarray(light, float)
    breaks = set()
    # y of the point equals y0: the segment starts or stops reaching the plane
    if d[1] != 0.0:
        breaks.add((y0 - o[1]) / d[1])
    for axis, edges in ((0, (x_lo, x_hi)), (2, (z_lo, z_hi))):
        for e in edges:
            # L_a + (y0 - L_y) (o_a + x d_a - L_a) / (o_y + x d_y - L_y) = e, linear in x
            a = (y0 - L[1]) * d[axis] - (e - L[axis]) * d[1]
            b = (y0 - L[1]) * (o[axis] - L[axis]) - (e - L[axis]) * (o[1] - L[1])
            if a != 0.0:
                breaks.add(-b / a)
    return sorted(x for x in breaks if 0.0 < x < tmax)


def plate_blocks(o, d, x, light, plate) -> bool:
    y0, (x_lo, x_hi), (z_lo, z_hi) = plate
    L = np.asarray(light, float)
    p = o + x * d
    if (p[1] - y0) * (L[1] - y0) >= 0.0:  # both on one side of the plane
        return False
    s = (y0 - L[1]) / (p[1] - L[1])
    q = L + s * (p - L)
    return x_lo < q[0] < x_hi and z_lo < q[2] < z_hi


def shadowed_airlight(o, d, tmax, light, intensity, kt, ks, phase_name, g, plates, spot=None, curve="smoothstep"):
    """Air-light of eq. 4 over the lit parts of [0, tmax]: the visibility of the light is 0 where a
    plate lies between the light and the point; integrated piece by piece between the analytic
    shadow boundaries (a spot light's `spot` and `curve` as `airlight`)."""
    breaks = sorted({0.0, tmax, *(b for p in plates for b in plate_shadow_breaks(o, d, tmax, light, p))})
    total = 0.0
    for a, b in zip(breaks[:-1], breaks[1:]):
        mid = 0.5 * (a + b)
        if not any(plate_blocks(o, d, mid, light, p) for p in plates):
            total += airlight_between(o, d, a, b, light, intensity, kt, ks, phase_name, g, spot, curve)
    return total


def airlight_between(o, d, a, b, light, intensity, kt, ks, phase_name, g, spot=None, curve="smoothstep"):
    """eq. 4 over [a, b]: the air-light of [0, b] minus that of [0, a] would cancel; integrate [a, b]
    from its own start and attenuate by exp(-kt a)."""
    start = o + a * d
    return math.exp(-kt * a) * airlight(start, d, b - a, light, intensity, kt, ks, phase_name, g, spot, curve)


def plate_hit(o, d, plate):
    y0, (x_lo, x_hi), (z_lo, z_hi) = plate
    if d[1] == 0.0:
        return math.inf
    t = (y0 - o[1]) / d[1]
    q = o + t * d
    return t if t > 0.0 and x_lo < q[0] < x_hi and z_lo < q[2] < z_hi else math.inf


# --- height fog (seed 004), brute force: every optical depth a scipy quad of the density ----------


class Fog:
    """A [medium] table of type "height_fog" as plain numbers, with its density and numerically
    integrated unit optical depth (no closed form)."""

    def __init__(self, med: dict):
        up = np.array(med.get("up", [0.0, 1.0, 0.0]), float)
        self.up = up / np.linalg.norm(up)
        self.h0, self.H = float(med.get("h0", 0.0)), float(med["scale_height"])
        self.linear = med.get("profile", "exponential") == "linear"
        self.ka = np.broadcast_to(np.array(med.get("sigma_a", 0.0), float), 3)
        self.ks = np.broadcast_to(np.array(med.get("sigma_s", 0.0), float), 3)
        ph = med.get("phase", "isotropic")
        self.phase = (ph, 0.0) if isinstance(ph, str) else (ph.get("type", "hg"), ph.get("g", 0.0))

    def density(self, p) -> float:
        h = float(p @ self.up) - self.h0
        return max(0.0, 1.0 - h / self.H) if self.linear else math.exp(-h / self.H)

    def top(self, a, w, length):
        """Where the ray a + s w crosses the linear fog's top, if inside (0, length)."""
        mu = float(w @ self.up)
        if not self.linear or mu == 0.0:
            return []
        s = (self.H - (float(a @ self.up) - self.h0)) / mu
        return [s] if 0.0 < s < length * (1.0 - 1e-12) else []

    def depth(self, a, w, length) -> float:
        """∫_0^length density(a + s w) ds by scipy quad (length may be inf on a rising ray)."""
        edges = [0.0] + self.top(a, w, length) + [length]
        return sum(integrate.quad(lambda s: self.density(a + s * w), lo, hi, epsabs=0.0, epsrel=1e-13, limit=200)[0]
                   for lo, hi in zip(edges[:-1], edges[1:]))


def fog_pixel(scene: dict, i: int, j: int, first_hit, plates=()) -> np.ndarray:
    """Radiance of pixel (i, j)'s centre in a height fog: T_cam(t) Lb + the single-scattering
    integral, every transmittance exp(-kt Fog.depth). `first_hit(o, d)` -> (t, inward normal or
    None): the scene's first surface (every light reaches every surface point it faces). `plates`
    (as `plate_blocks`) shadow the point lights' air-light (volumetric shadows), not the surfaces."""
    cam = scene["camera"]
    fog = Fog(scene["medium"])
    kt = fog.ka + fog.ks
    rho_s = np.broadcast_to(np.array(scene["shape"][0].get("reflectance", 0.5), float), 3)
    o, d = camera_ray(cam, i, j)
    t, n = first_hit(o, d)
    lights = []
    for light in scene["light"]:
        if light.get("type") == "directional":
            axis = np.array(light["direction"], float)
            lights.append((None, axis / np.linalg.norm(axis), np.broadcast_to(np.array(light["irradiance"], float), 3)))
        else:
            lights.append((np.array(light["position"], float), spot_of(light),
                           np.broadcast_to(np.array(light["intensity"], float), 3)))

    def toward(light, x):
        """(unattenuated irradiance per channel on a surface facing the light, unit vector to it,
        optical depth to it) at the point x."""
        p, spot, power = light
        if p is None:
            return power, -spot, fog.depth(x, -spot, math.inf)
        to = p - x
        dist = math.sqrt(to @ to)
        return power * emission(spot, -to / dist) / dist**2, to / dist, fog.depth(x, to / dist, dist)

    out = np.zeros(3)
    if t < math.inf:
        x = o + t * d
        for light in lights:
            e, wi, tau = toward(light, x)
            out += rho_s / math.pi * e * np.exp(-kt * tau) * max(0.0, float(n @ wi))
        out *= np.exp(-kt * fog.depth(o, d, t))
    for light in lights:
        def f(x):
            q = o + x * d
            e, wi, tau = toward(light, q)
            cos = float(wi @ d)  # the light's travel direction (-wi) against the way back (-d)
            return (fog.ks * fog.density(q) * phase(*fog.phase, cos) * e
                    * np.exp(-kt * (fog.depth(o, d, x) + tau)))

        points = fog.top(o, d, t)
        if light[0] is not None:
            xh = float((light[0] - o) @ d)
            h = float(np.linalg.norm(np.cross(light[0] - o, d)))
            points += [x for x in (xh - 10 * h, xh - h, xh, xh + h, xh + 10 * h) if 0.0 < x < t]
            points += cone_crossings(o, d, t, light[0], light[1])
            points += [x for p in plates for x in plate_shadow_breaks(o, d, t, light[0], p)]
        edges = [0.0] + sorted(points) + [t]
        for lo, hi in zip(edges[:-1], edges[1:]):
            mid = 0.5 * (lo + hi) if hi < math.inf else lo + 1.0
            if light[0] is not None and any(plate_blocks(o, d, mid, light[0], p) for p in plates):
                continue
            out += integrate.quad_vec(f, lo, hi, epsabs=1e-13, epsrel=1e-10, limit=400)[0]
    return out


def ground_hit(o, d):
    """The ground plane y = 0 seen from above: (t, upward normal), or (inf, None)."""
    if d[1] < 0.0 and o[1] > 0.0:
        return -o[1] / d[1], np.array([0.0, 1.0, 0.0])
    return math.inf, None


def box_hit(scene: dict):
    box = scene["shape"][0]
    lo, hi = np.array(box["min"], float), np.array(box["max"], float)
    return lambda o, d: box_exit(o, d, lo, hi)
