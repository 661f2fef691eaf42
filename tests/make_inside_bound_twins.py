"""Regenerate tests/data/inside_bound_twins.json, the 30-digit twins of tests/test_inside_bounds.py.

    python tests/make_inside_bound_twins.py          # about a minute on one core

Each twin is the single scattering, at its start, of one segment o + x w, x in [0, length], inside a
closed shape holding a homogeneous index-matched medium (sigma_t, sigma_s, Henyey-Greenstein g) in
an absorbing outside (kt_out), lit by a point or spot light at p (intensity I; a spot's smoothstep
falloff F in the cosine to its axis between cos(cone_angle) and cos(falloff_start), pbrt-v4's
SpotLight), written from the geometry alone (no project code):

    ∫_0^length sigma_s Phi(u·w) F I exp(-sigma_t (x + k(x)) - kt_out (d(x) - k(x))) / d(x)^2 dx,

X = o + x w, d = |p - X|, u = (p - X) / d, k(x) the length of the straight segment from X to p
inside the shape. Shapes: a box (slab tests), a convex icosahedron (its twenty face planes from the
stored vertices, the segment clipped by each half-space), a U-shaped prism that is the union of
three boxes with disjoint interiors (k = the sum of the three slab lengths: a path may leave one arm
and enter the other), an exact sphere (k between the roots of |X + t u - c| = r). The segments are the first inside stretches of camera rays from outside, on a
grid of directions toward the shape (entry and exit found here in mpmath, then rounded to float64:
the twin integrates the stored float64 segment exactly). The integrand's kinks and the cone's
edges (where the face a path leaves by, a box's slab faces, or the falloff's piece change) are
found by bisection on 160 samples of the segment (2560 where mpmath's estimate says a kink was
missed), and mpmath's quad integrates between them at 30
digits; its own error estimate is stored and must be below 1e-20 of the value.
"""
import json
import math
from pathlib import Path

import mpmath as mp

OUT = Path(__file__).resolve().parent / "data" / "inside_bound_twins.json"
mp.mp.dps = 30
SAMPLES = 160

SIGMA_A, SIGMA_S, G, KT_OUT = 0.3, 0.5, 0.3, 0.05
BOX = ((-1.0, -0.5, -0.8), (1.0, 0.5, 0.8))
U_BOXES = [((-1.0, -1.0, -0.5), (1.0, -0.5, 0.5)), ((-1.0, -0.5, -0.5), (-0.4, 0.5, 0.5)),
           ((0.4, -0.5, -0.5), (1.0, 0.5, 0.5))]
U_OUTLINE = [(-1, -1), (1, -1), (1, -0.5), (1, 0.5), (0.4, 0.5), (0.4, -0.5), (-0.4, -0.5), (-0.4, 0.5), (-1, 0.5),
             (-1, -0.5)]
U_CAP = [(0, 1, 2), (0, 2, 5), (0, 5, 6), (0, 6, 9), (9, 6, 7), (9, 7, 8), (2, 3, 4), (2, 4, 5)]
LAMP = {"type": "point", "position": [1.6, 0.9, 0.45], "intensity": 3.0}
SPOT = {"type": "spot", "position": [1.6, 0.9, 0.45], "look_at": [0.2, -0.1, 0.0], "intensity": 3.0,
        "cone_angle": 25.0, "falloff_start": 14.0}
U_LAMP = {"type": "point", "position": [1.6, 0.25, 0.1], "intensity": 3.0}
U_SPOT = U_LAMP | {"type": "spot", "look_at": [-0.3, -0.35, 0.0], "cone_angle": 22.0, "falloff_start": 14.0}
SPHERE = ((0.1, 0.05, -0.1), 0.9)


def icosahedron():
    """Vertices (radius 0.9 about (0.1, 0.05, -0.1)) and outward-wound faces of a regular icosahedron."""
    phi = (1.0 + math.sqrt(5.0)) / 2.0
    raw = [(0, s1, s2 * phi) for s1 in (-1, 1) for s2 in (-1, 1)]
    raw = raw + [(y, z, x) for x, y, z in raw] + [(z, x, y) for x, y, z in raw]
    r = 0.9 / math.sqrt(1.0 + phi * phi)
    verts = [[0.1 + r * a, 0.05 + r * b, -0.1 + r * c] for a, b, c in raw]
    faces = []
    for i in range(12):
        for j in range(i + 1, 12):
            for k in range(j + 1, 12):
                if all(abs(math.dist(raw[a], raw[b]) - 2.0) < 1e-9 for a, b in ((i, j), (j, k), (i, k))):
                    a, b, c = (mp.matrix(raw[q]) for q in (i, j, k))
                    n = _cross(b - a, c - a)
                    faces.append([i, j, k] if _dot(n, a + b + c) > 0 else [i, k, j])
    assert len(faces) == 20
    return verts, faces


def icosphere():
    """The icosahedron with each face cut in four at its edges' midpoints, pushed out to its sphere
    (radius 0.9 about (0.1, 0.05, -0.1)): a convex mesh of 80 faces, more than the 64 planes of
    media/slab.py's kernel (its paths are measured on the facet walk's planes)."""
    verts, faces = icosahedron()
    centre = (0.1, 0.05, -0.1)
    verts = [list(v) for v in verts]
    mids = {}

    def mid(i, j):
        if (min(i, j), max(i, j)) not in mids:
            m = [0.5 * (verts[i][k] + verts[j][k]) - centre[k] for k in range(3)]
            scale = 0.9 / math.sqrt(sum(x * x for x in m))
            verts.append([centre[k] + scale * m[k] for k in range(3)])
            mids[(min(i, j), max(i, j))] = len(verts) - 1
        return mids[(min(i, j), max(i, j))]
    out = []
    for a, b, c in faces:
        ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
        out += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
    return verts, out


def u_mesh():
    """The U prism's vertices and faces (the outline extruded from z = -0.5 to 0.5)."""
    verts = [[float(x), float(y), z] for z in (-0.5, 0.5) for x, y in U_OUTLINE]
    m = len(U_OUTLINE)
    faces = [[a, c, b] for a, b, c in U_CAP] + [[a + m, b + m, c + m] for a, b, c in U_CAP]
    for i in range(m):
        j = (i + 1) % m
        faces += [[i, j, j + m], [i, j + m, i + m]]
    return verts, faces


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a, b):
    return mp.matrix([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _vec(v):
    return mp.matrix([mp.mpf(float(c)) for c in v])


def slab(o, d, lo, hi, t0, t1):
    """(entry, exit, signature) of the part of o + t d, t in [t0, t1], inside the box [lo, hi]; None if
    it misses; the signature names the faces that bound it."""
    sig = []
    for k in range(3):
        if d[k] == 0:
            if not lo[k] <= o[k] <= hi[k]:
                return None, ("miss",)
            continue
        ta, tb = (lo[k] - o[k]) / d[k], (hi[k] - o[k]) / d[k]
        if ta > tb:
            ta, tb = tb, ta
        if ta > t0:
            t0, sig = ta, sig + [("in", k)]
        if tb < t1:
            t1, sig = tb, sig + [("out", k)]
    if t1 <= t0:
        return None, ("miss",)
    return (t0, t1), tuple(sig)


def box_shape(lo, hi):
    lo, hi = [mp.mpf(c) for c in lo], [mp.mpf(c) for c in hi]

    def chord(X, u, dist):
        part, sig = slab(X, u, lo, hi, mp.mpf(0), dist)
        return (part[1] - part[0] if part else mp.mpf(0)), sig
    return chord, [(lo, hi)]


def u_shape():
    boxes = [([mp.mpf(c) for c in lo], [mp.mpf(c) for c in hi]) for lo, hi in U_BOXES]

    def chord(X, u, dist):
        total, sigs = mp.mpf(0), []
        for lo, hi in boxes:
            part, sig = slab(X, u, lo, hi, mp.mpf(0), dist)
            total += part[1] - part[0] if part else 0
            sigs.append(sig)
        return total, tuple(sigs)
    return chord, boxes


def polytope_shape(verts, faces):
    """The chord function of the convex hull of the faces: planes n·x <= c from each face's vertices."""
    planes = []
    for f in faces:
        a, b, c = (_vec(verts[i]) for i in f)
        n = _cross(b - a, c - a)
        n = n / mp.sqrt(_dot(n, n))
        planes.append((n, _dot(n, a)))

    def chord(X, u, dist):
        t0, t1, sig = mp.mpf(0), dist, []
        for i, (n, c) in enumerate(planes):
            den, num = _dot(n, u), c - _dot(n, X)
            if den > 0:
                if num / den < t1:
                    t1, sig = num / den, [("out", i)]
            elif den < 0:
                t0 = max(t0, num / den)
        return max(t1 - t0, mp.mpf(0)), tuple(sig)
    return chord, planes


def sphere_shape(centre, radius):
    """The chord function of the sphere: between the roots of |X + t u - c| = r, clipped to [0, dist]."""
    c, r = _vec(centre), mp.mpf(radius)

    def chord(X, u, dist):
        f = X - c
        b = _dot(f, u)
        q = b * b - (_dot(f, f) - r * r)
        if q <= 0:
            return mp.mpf(0), ("miss",)
        lo, hi = max(-b - mp.sqrt(q), mp.mpf(0)), min(-b + mp.sqrt(q), dist)
        return max(hi - lo, mp.mpf(0)), ("sphere",)
    return chord, (c, r)


def spot_terms(light):
    """(axis, cos_end, cos_start) in float64 as a scene file gives them (None for a point light)."""
    if light["type"] != "spot":
        return None
    p, q = light["position"], light["look_at"]
    a = [q[i] - p[i] for i in range(3)]
    n = math.sqrt(sum(c * c for c in a))
    return ([c / n for c in a], math.cos(math.radians(light["cone_angle"])),
            math.cos(math.radians(light["falloff_start"])))


def falloff(spot, c):
    """pbrt-v4's smoothstep falloff and the piece of the cone that c lies in."""
    if spot is None:
        return mp.mpf(1), 0
    _, ce, cs = spot
    if c >= cs:
        return mp.mpf(1), 1
    if c <= ce:
        return mp.mpf(0), 2
    t = (c - ce) / (mp.mpf(cs) - ce)
    return t * t * (3 - 2 * t), 3


def hg(g, mu):
    g = mp.mpf(g)
    return (1 - g * g) / (4 * mp.pi * (1 + g * g - 2 * g * mu) ** mp.mpf(1.5))


def twin(chord, o, w, length, light, samples=SAMPLES):
    """The integral of the module docstring and mpmath's error estimate (kinks bracketed on `samples`)."""
    o, w, ell = _vec(o), _vec(w), mp.mpf(length)
    p = _vec(light["position"])
    spot = spot_terms(light)
    axis = _vec(spot[0]) if spot else None
    kt, ks = mp.mpf(SIGMA_A) + mp.mpf(SIGMA_S), mp.mpf(SIGMA_S)

    def geometry(x):
        X = o + x * w
        r = p - X
        d = mp.sqrt(_dot(r, r))
        u = r / d
        k, sig = chord(X, u, d)
        f, piece = falloff(spot, -_dot(u, axis) if spot else 0)
        return X, d, u, k, f, (sig, piece)

    def f(x):
        _, d, u, k, fall, _ = geometry(x)
        if fall == 0:
            return mp.mpf(0)
        return ks * hg(G, _dot(u, w)) * fall * light["intensity"] * mp.exp(-kt * (x + k) - KT_OUT * (d - k)) / d ** 2

    xs = [ell * i / samples for i in range(samples + 1)]
    sigs = [geometry(x)[5] for x in xs]
    cuts = [mp.mpf(0)]
    for i in range(samples):
        if sigs[i] != sigs[i + 1]:
            a, b = xs[i], xs[i + 1]
            for _ in range(110):
                m = (a + b) / 2
                if geometry(m)[5] == sigs[i]:
                    a = m
                else:
                    b = m
            cuts.append(a)
    cuts.append(ell)
    value, error = mp.mpf(0), mp.mpf(0)
    for a, b in zip(cuts, cuts[1:]):
        if b > a:
            v, e = mp.quad(f, [a, b], error=True)
            value, error = value + v, error + e
    return value, error


def first_stretch(boxes_or_planes, kind, cam, target):
    """(origin, direction, length, entry normal) in float64 of the first inside stretch of the ray from
    cam toward target; None if it misses."""
    c, t = _vec(cam), _vec(target)
    d = t - c
    d = d / mp.sqrt(_dot(d, d))
    big = mp.mpf(100)
    if kind == "sphere":
        centre, r = boxes_or_planes
        f = c - centre
        b = _dot(f, d)
        q = b * b - (_dot(f, f) - r * r)
        if q <= 0:
            return None
        t0, t1 = -b - mp.sqrt(q), -b + mp.sqrt(q)
        normal = [float(v) for v in (c + t0 * d - centre) / r]
    elif kind == "polytope":
        t0, t1, face = mp.mpf(0), big, None
        for n, cc in boxes_or_planes:
            den, num = _dot(n, d), cc - _dot(n, c)
            if den > 0:
                t1 = min(t1, num / den)
            elif den < 0 and num / den > t0:
                t0, face = num / den, n
        if t1 <= t0:
            return None
        normal = [float(v) for v in face]
    else:
        parts = sorted(p for p in (slab(c, d, lo, hi, mp.mpf(0), big)[0] for lo, hi in boxes_or_planes) if p)
        if not parts:
            return None
        t0, t1 = parts[0]
        for a, b in parts[1:]:
            if a <= t1 + mp.mpf(10) ** -25:
                t1 = max(t1, b)
        X = c + t0 * d
        lo, hi = next((lo, hi) for lo, hi in boxes_or_planes if all(lo[k] - 1e-20 <= X[k] <= hi[k] + 1e-20
                                                                     for k in range(3)))
        k = min(range(3), key=lambda k: min(abs(X[k] - lo[k]), abs(X[k] - hi[k])))
        normal = [0.0, 0.0, 0.0]
        normal[k] = -1.0 if abs(X[k] - lo[k]) < abs(X[k] - hi[k]) else 1.0
    o = [float(v) for v in c + t0 * d]
    w = [float(v) for v in d]
    return o, w, float(t1 - t0), normal


def cases():
    """(name, shape table, chord, boxes or planes, kind, camera, targets, lights)."""
    grid = [(a, b) for a in (-0.75, -0.35, 0.05, 0.45, 0.8) for b in (-0.6, -0.2, 0.2, 0.55)]
    box_chord, box_boxes = box_shape(*BOX)
    verts, faces = icosahedron()
    ico_chord, ico_planes = polytope_shape(verts, faces)
    sv, sf = icosphere()
    fine_chord, fine_planes = polytope_shape(sv, sf)
    uv, uf = u_mesh()
    u_chord, u_boxes = u_shape()
    sphere_chord, sphere_geom = sphere_shape(*SPHERE)
    yield ("box", {"primitive": "box", "min": list(BOX[0]), "max": list(BOX[1])}, box_chord, box_boxes, "boxes",
           [-0.7, 1.3, 3.2], [[a, 0.3 * b, 0.8 * b] for a, b in grid], [("lamp", LAMP), ("spot", SPOT)])
    yield ("icosahedron", {"primitive": "triangles", "vertices": verts, "faces": faces}, ico_chord, ico_planes,
           "polytope", [-0.9, 1.1, 3.0], [[0.1 + 0.7 * a, 0.05 + 0.6 * b, -0.1] for a, b in grid], [("lamp", LAMP)])
    yield ("icosphere", {"primitive": "triangles", "vertices": sv, "faces": sf}, fine_chord, fine_planes,
           "polytope", [-0.9, 1.1, 3.0], [[0.1 + 0.7 * a, 0.05 + 0.6 * b, -0.1] for a, b in grid],
           [("lamp", LAMP)])
    yield ("u", {"primitive": "triangles", "vertices": uv, "faces": uf}, u_chord, u_boxes, "boxes",
           [0.3, 1.4, 3.0], [[0.9 * a, 0.7 * b - 0.2, 0.0] for a, b in grid], [("lamp", U_LAMP), ("spot", U_SPOT)])
    yield ("sphere", {"primitive": "sphere", "center": list(SPHERE[0]), "radius": SPHERE[1], "exact": True},
           sphere_chord, sphere_geom, "sphere", [-0.9, 1.1, 3.0],
           [[0.1 + 0.8 * a, 0.05 + 0.7 * b, -0.1] for a, b in grid], [("lamp", LAMP), ("spot", SPOT)])


def main():
    rays = []
    for name, shape, chord, geom, kind, cam, targets, lights in cases():
        for target in targets:
            seg = first_stretch(geom, kind, cam, target)
            if seg is None:
                continue
            o, w, length, normal = seg
            for lname, light in lights:
                value, error = twin(chord, o, w, length, light)
                if error > mp.mpf(10) ** -20 * value:  # two kinks within one sample: bracket them finer
                    value, error = twin(chord, o, w, length, light, 16 * SAMPLES)
                assert error < mp.mpf(10) ** -20 * max(value, mp.mpf(10) ** -300), (name, target, error, value)
                if value == 0:  # a segment outside the spot's cone: not stored
                    continue
                rays.append({"case": f"{name}_{lname}", "origin": o, "dir": w, "length": length, "normal": normal,
                             "twin": mp.nstr(value, 30)})
                print(name, lname, target, mp.nstr(value, 12), flush=True)
    shapes = {name: shape for name, shape, *_ in cases()}
    lights = {f"{name}_{lname}": light for name, _, _, _, _, _, _, ls in cases() for lname, light in ls}
    medium = {"interior": {"sigma_a": SIGMA_A, "sigma_s": SIGMA_S, "phase": {"type": "hg", "g": G}},
              "outside": {"sigma_a": KT_OUT}}
    head = json.dumps({"media": medium, "shapes": shapes, "lights": lights})[:-1]
    OUT.write_text(head + ', "rays": [\n' + ",\n".join(json.dumps(r) for r in rays) + "\n]}\n")


if __name__ == "__main__":
    main()
