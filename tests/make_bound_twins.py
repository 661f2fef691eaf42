"""Regenerate tests/data/bound_twins.json, the 30-digit twins of tests/test_bound_twins.py.

    python tests/make_bound_twins.py            # about 15 minutes on one core
    python tests/make_bound_twins.py earth_     # redo the cases whose names contain earth_ (keeps the rest)

Each twin is the single-scattering air-light of one ray segment o + t w, t in [0, length], lit by one
light, written from the formulas alone (no project code): the integral over the ray of

    sigma_s rho(p) Phi(cos) I / r^2 exp(-sigma_t (tau_cam(t) + tau_light(t)))

(for the sun: its irradiance, r = 1, tau_light to infinity along the direction toward it), with
mpmath at 30 digits. Height fog: rho = exp(-z / H) or max(0, 1 - z / H), z = p.up - h0, and each
column is the density's exact antiderivative along the line (mpmath). Atmospheres: rho_i =
exp(-(|p - c| - R) / H_i) per layer, each column an mpmath quad of the densities along the chord,
split at its lowest point; the ground (|p - c| = R) blocks a sun path that meets it. The scene's
numbers are float64 as the renderer reads them (unit up, exact positions; the sun's direction
normalised), converted exactly.
"""
import json
import math
import sys
from pathlib import Path

import mpmath as mp

OUT = Path(__file__).resolve().parent / "data" / "bound_twins.json"
mp.mp.dps = 30

FOG = {"type": "height_fog", "sigma_a": 0.03, "sigma_s": 0.25, "h0": 0.5, "scale_height": 1.5,
       "up": [0.0, 1.0, 0.0], "phase": {"type": "hg", "g": 0.6}}
LAMP = {"position": [0.3, 1.2, -2.0], "intensity": 40.0}
SUN = {"type": "directional", "direction": [0.35, -0.3, 0.887], "irradiance": 3.0}
R = 1000.0
SMALL = {"type": "atmosphere", "center": [0.0, -R, 0.0], "radius": R, "top_radius": R + 75.0, "reflectance": 0.0,
         "layer": [{"name": "rayleigh", "sigma_s": 1.08e-2, "scale_height": 10.0, "phase": "rayleigh"},
                   {"name": "mie", "sigma_s": 3.2e-3, "sigma_a": 3.6e-4, "scale_height": 1.5,
                    "phase": {"type": "hg", "g": 0.76}}]}
RE = 6360e3
EARTH = {"type": "atmosphere", "center": [0.0, -RE, 0.0], "radius": RE, "top_radius": RE + 60e3, "reflectance": 0.0,
         "layer": [{"name": "rayleigh", "sigma_s": 1.35e-5, "scale_height": 8000.0, "phase": "rayleigh"},
                   {"name": "mie", "sigma_s": 3.996e-6, "sigma_a": 4.4e-7, "scale_height": 1200.0,
                    "phase": {"type": "hg", "g": 0.8}}]}
SKY_SUN = {"type": "directional", "direction": [-0.4, -0.55, 0.733], "irradiance": 20.0}


def _unit(v):
    n = math.sqrt(sum(x * x for x in v))
    return [x / n for x in v]


def fog_rays():
    """(name, origin, direction, length, light) of the height-fog grid: up, down, horizontal,
    grazing, near the lamp, to infinity, with the lamp and with the sun, both profiles."""
    o = [0.0, 1.0, 3.0]
    rays = [("up", o, _unit([0.1, 1.0, -0.6]), math.inf), ("up_steep", o, _unit([0.0, 1.0, -0.05]), 30.0),
            ("down", o, _unit([0.05, -0.4, -1.0]), 2.0 / 0.4 * math.sqrt(0.05 ** 2 + 0.4 ** 2 + 1.0)),
            ("horizontal", o, [0.0, 0.0, -1.0], 40.0), ("horizontal_far", [0.0, 1.2, 3.0], [0.6, 0.0, -0.8], math.inf),
            ("grazing_up", o, _unit([0.0, 1e-3, -1.0]), math.inf), ("grazing_down", o, _unit([0.0, -1e-3, -1.0]), 60.0),
            ("near_lamp", o, _unit([0.3, 0.2 + 1e-3, -5.0]), 20.0), ("through_lamp_side", o, _unit([0.3, 0.2, -5.0 + 0.02]), 20.0),
            ("short", [0.3, 1.2, -1.9], _unit([0.0, -0.2, -1.0]), 0.5), ("from_above", [0.0, 6.0, 3.0],
                                                                             _unit([0.1, -1.0, -0.4]), 6.0)]
    out = []
    for profile in ("exponential", "linear"):
        medium = dict(FOG, profile="linear", scale_height=4.0) if profile == "linear" else FOG
        for light_name, light in (("lamp", LAMP), ("sun", SUN)):
            for name, origin, direction, length in rays:
                out.append({"case": f"fog_{profile}_{light_name}_{name}", "medium": medium, "light": light,
                            "origin": origin, "dir": direction, "length": length})
    return out


def atmosphere_rays():
    """The atmosphere's grid: from the ground (up, toward the sun, at the horizon), from space
    (down to the ground, through the air, grazing the limb), on a small planet and an Earth."""
    out = []
    for tag, med, r in (("small", SMALL, R), ("earth", EARTH, RE)):
        top = med["top_radius"] - r
        ground = [0.0, 0.002 * top, 0.0]
        space = [0.0, 3.0 * top, 0.0]
        rays = [("ground_zenith", ground, [0.0, 1.0, 0.0], math.inf), ("ground_up", ground, _unit([0.2, 0.5, -1.0]), math.inf),
                ("ground_horizon", ground, _unit([0.0, 0.02, -1.0]), math.inf),
                ("ground_toward_sun", ground, _unit([0.4, 0.3, -0.733]), math.inf)]
        # from space: to the ground below (finite), and rays whose lowest point is 0.3 H_mie and 3 H_rayleigh up
        down = _unit([0.0, -1.0, -0.3])
        rays.append(("space_down", space, down, _ground_distance(space, down, med)))
        h_rayleigh, h_mie = (layer["scale_height"] for layer in med["layer"])
        for alt, name in ((0.3 * h_mie, "space_limb_low"), (3.0 * h_rayleigh, "space_limb_high")):
            rays.append((name, space, _tangent_direction(space, med, alt), math.inf))
        for name, origin, direction, length in rays:
            out.append({"case": f"atmosphere_{tag}_{name}", "medium": med, "light": SKY_SUN if tag == "earth" else SUN,
                        "origin": origin, "dir": direction, "length": length})
    return out


def _ground_distance(o, w, med):
    c, r = med["center"], med["radius"]
    q = [o[i] - c[i] for i in range(3)]
    b = sum(q[i] * w[i] for i in range(3))
    disc = b * b - (sum(x * x for x in q) - r * r)
    return -b - math.sqrt(disc)


def _tangent_direction(o, med, alt):
    """The unit direction from o (above the centre) in the y-z plane whose lowest point lies at altitude alt."""
    c, r = med["center"], med["radius"]
    d = o[1] - c[1]
    s = (r + alt) / d  # sin of the angle between the direction and the line to the centre
    return [0.0, -math.sqrt(1.0 - s * s), -s]


# --- the twins --------------------------------------------------------------------------------------

def _mp_unit(v):
    """The light's direction as the scene format reads it: normalised."""
    v = [mp.mpf(x) for x in v]
    n = mp.sqrt(mp.fsum(x * x for x in v))
    return [x / n for x in v]


def _phase(phase, cos):
    if phase == "isotropic":
        return 1 / (4 * mp.pi)
    if phase == "rayleigh":
        return 3 / (16 * mp.pi) * (1 + cos * cos)
    g = mp.mpf(phase["g"])
    return (1 - g * g) / (4 * mp.pi * (1 + g * g - 2 * g * cos) ** mp.mpf(1.5))


def _fog_column(med, z, mu, length):
    """The unit column from height z (above h0) along up-cosine mu over [0, length] (may be inf)."""
    H = mp.mpf(med["scale_height"])
    if med.get("profile", "exponential") == "exponential":
        if mu == 0:
            return length * mp.exp(-z / H) if length != mp.inf else mp.inf
        if length == mp.inf:
            return H / mu * mp.exp(-z / H) if mu > 0 else mp.inf
        return H / mu * mp.exp(-z / H) * (1 - mp.exp(-mu * length / H))
    # linear: max(0, 1 - (z + mu t)/H), the antiderivative of its positive part
    def F(t):  # int_0^t (1 - (z + mu s)/H) ds
        return t - (z * t + mu * t * t / 2) / H
    lo, hi = mp.mpf(0), length
    if mu == 0:
        return (1 - z / H) * length if z < H else mp.mpf(0)
    t_zero = (H - z) / mu
    if mu > 0:
        hi = min(hi, t_zero)
    else:
        lo = max(lo, t_zero)
    if hi == mp.inf:
        return mp.inf
    return F(hi) - F(lo) if hi > lo else mp.mpf(0)


def fog_twin(ray):
    med, light = ray["medium"], ray["light"]
    up = [mp.mpf(x) for x in med["up"]]
    h0, H = mp.mpf(med["h0"]), mp.mpf(med["scale_height"])
    kt = mp.mpf(med["sigma_a"]) + mp.mpf(med["sigma_s"])
    ks = mp.mpf(med["sigma_s"])
    o = [mp.mpf(x) for x in ray["origin"]]
    w = [mp.mpf(x) for x in ray["dir"]]
    length = mp.inf if ray["length"] == math.inf else mp.mpf(ray["length"])
    z0 = mp.fsum(o[i] * up[i] for i in range(3)) - h0
    mu = mp.fsum(w[i] * up[i] for i in range(3))
    linear = med.get("profile", "exponential") == "linear"
    sun = light.get("type") == "directional"
    if sun:
        axis = _mp_unit(light["direction"])
        toward = [-x for x in axis]
        mus = mp.fsum(toward[i] * up[i] for i in range(3))
        cos = mp.fsum(axis[i] * -w[i] for i in range(3))
        E = mp.mpf(light["irradiance"])
    else:
        L = [mp.mpf(x) for x in light["position"]]
        I = mp.mpf(light["intensity"])
        zl = mp.fsum(L[i] * up[i] for i in range(3)) - h0

    def density(z):
        return max(mp.mpf(0), 1 - z / H) if linear else mp.exp(-z / H)

    def f(t):
        z = z0 + mu * t
        rho = density(z)
        if rho == 0:
            return mp.mpf(0)
        tau = _fog_column(med, z0, mu, t)
        if sun:
            tau += _fog_column(med, z, mus, mp.inf)
            return ks * rho * _phase(med["phase"], cos) * E * mp.exp(-kt * tau)
        p = [o[i] + t * w[i] for i in range(3)]
        r = [L[i] - p[i] for i in range(3)]
        d = mp.sqrt(mp.fsum(x * x for x in r))
        tau += _fog_column(med, z, (zl - z) / d, d)
        c = mp.fsum(-r[i] / d * -w[i] for i in range(3))
        return ks * rho * _phase(med["phase"], c) * I / (d * d) * mp.exp(-kt * tau)

    pts = [mp.mpf(0)]
    if not sun:
        xh = mp.fsum((L[i] - o[i]) * w[i] for i in range(3))
        h = mp.sqrt(mp.fsum((L[i] - o[i] - xh * w[i]) ** 2 for i in range(3)))
        pts += [xh + k * h for k in (-30, -3, -0.3, 0, 0.3, 3, 30)]
    if linear and mu != 0:
        pts.append((H - z0) / mu)
    if length != mp.inf:
        pts = [t for t in pts if 0 <= t < length] + [length]
    else:
        pts = [t for t in pts if t >= 0]
        pts.append(pts[-1] + 10 * H)
        pts.append(mp.inf)
    pts = sorted(set(pts))
    return _quad(f, pts)


def _quad(f, pts):
    """mpmath's tanh-sinh quad over the pieces between pts, refusing a result whose own error
    estimate exceeds 1e-20 of it."""
    value, err = mp.quad(f, pts, error=True, maxdegree=10)
    assert err <= mp.mpf(10) ** -20 * abs(value), (value, err)
    return value


def _atm_density(layers, r, R):
    return [mp.exp(-(r - R) / mp.mpf(l["scale_height"])) for l in layers]


def _atm_columns(med, p, w, length, blocked=True):
    """Unit columns (per layer) from p along unit w over [0, length] inside the top sphere (length
    may be inf); None where the path meets the ground (if `blocked`: not the camera ray's own, which
    ends there)."""
    c = [mp.mpf(x) for x in med["center"]]
    R, top = mp.mpf(med["radius"]), mp.mpf(med["top_radius"])
    q = [p[i] - c[i] for i in range(3)]
    b = mp.fsum(q[i] * w[i] for i in range(3))
    qq = mp.fsum(x * x for x in q)
    disc_g = b * b - (qq - R * R)
    if blocked and disc_g > 0 and 0 < -b - mp.sqrt(disc_g) < length:
        return None
    disc = b * b - (qq - top * top)
    if disc <= 0:
        return [mp.mpf(0)] * len(med["layer"])
    t_out = min(-b + mp.sqrt(disc), length)
    t_in = max(-b - mp.sqrt(disc), mp.mpf(0))
    if not t_out > t_in:
        return [mp.mpf(0)] * len(med["layer"])
    pts = [t_in] + ([-b] if t_in < -b < t_out else []) + [t_out]

    def rad(t):
        return mp.sqrt(mp.fsum((q[i] + t * w[i]) ** 2 for i in range(3)))

    return [mp.quad(lambda t: mp.exp(-(rad(t) - R) / mp.mpf(layer["scale_height"])), pts)
            for layer in med["layer"]]


def atmosphere_twin(ray):
    med, light = ray["medium"], ray["light"]
    c = [mp.mpf(x) for x in med["center"]]
    R, top = mp.mpf(med["radius"]), mp.mpf(med["top_radius"])
    o = [mp.mpf(x) for x in ray["origin"]]
    w = [mp.mpf(x) for x in ray["dir"]]
    length = mp.inf if ray["length"] == math.inf else mp.mpf(ray["length"])
    toward = [-x for x in _mp_unit(light["direction"])]
    cos = mp.fsum(-toward[i] * -w[i] for i in range(3))
    E = mp.mpf(light["irradiance"])
    layers = med["layer"]
    kt = [mp.mpf(l.get("sigma_a", 0.0)) + mp.mpf(l["sigma_s"]) for l in layers]
    ks = [mp.mpf(l["sigma_s"]) for l in layers]
    q = [o[i] - c[i] for i in range(3)]
    b = mp.fsum(q[i] * w[i] for i in range(3))
    qq = mp.fsum(x * x for x in q)
    disc = b * b - (qq - top * top)
    if disc <= 0:
        return mp.mpf(0)
    t_in, t_out = max(-b - mp.sqrt(disc), mp.mpf(0)), min(-b + mp.sqrt(disc), length)

    def f(t):
        p = [o[i] + t * w[i] for i in range(3)]
        r = mp.sqrt(mp.fsum((p[i] - c[i]) ** 2 for i in range(3)))
        cam = _atm_columns(med, o, w, t, blocked=False)
        sun = _atm_columns(med, p, toward, mp.inf)
        if sun is None:
            return mp.mpf(0)
        rho = _atm_density(layers, r, R)
        tau = mp.fsum(kt[i] * (cam[i] + sun[i]) for i in range(len(layers)))
        scat = mp.fsum(ks[i] * rho[i] * _phase(layers[i]["phase"], cos) for i in range(len(layers)))
        return scat * E * mp.exp(-tau)

    pts = [t_in] + ([-b] if t_in < -b < t_out else []) + [t_out]
    return _quad(f, pts)


def main():
    rays = fog_rays() + atmosphere_rays()
    only = sys.argv[1:]
    old = {r["case"]: r for r in json.loads(OUT.read_text())["rays"]} if OUT.exists() else {}
    out = []
    for ray in rays:  # written after each ray; cases named on the command line (substrings) are redone
        if ray["case"] in old and not any(s in ray["case"] for s in only):
            out.append(old[ray["case"]])
            continue
        twin = fog_twin(ray) if ray["medium"]["type"] == "height_fog" else atmosphere_twin(ray)
        print(f"{ray['case']}: {mp.nstr(twin, 20)}", flush=True)
        out.append({**ray, "length": None if ray["length"] == math.inf else ray["length"],
                    "twin": mp.nstr(twin, 30)})
        OUT.write_text(json.dumps({"generator": "tests/make_bound_twins.py", "digits": 30, "rays": out}, indent=1)
                       + "\n")


if __name__ == "__main__":
    main()
