"""Against Mitsuba 3 (issues 9, 14): the same scenes in Mitsuba's `volpath` and in ours, Mitsuba's
error and bias against our noise-free reference, and the time each needs for the same error.

    pip install -e '.[bench]'       # mitsuba >= 3.5; exits 0 with a skip message without it
    RAYTRACE_ASSETS=../shared/scenes python benchmarks/vs_mitsuba.py [--quick] [--out out/vs_mitsuba.json]

Mitsuba side: variant `llvm_ad_rgb` (needs libLLVM >= 16: DRJIT_LIBLLVM_PATH, else the newest
libLLVM found in the usual folders; LLVM 15 fails with "Cannot select: fminimum"), probed in a
subprocess, else `scalar_rgb` (said in the output). Integrator `volpath` with max_depth = 2, which
is exactly single scattering with shadowed next-event estimation plus direct surface lighting
(METHODS.md 9.3); the medium is a `homogeneous` medium attached to the sensor (it fills all space,
as ours), sigma_t = sigma_a + sigma_s, albedo = sigma_s / sigma_t, phase `isotropic` or `hg`;
`point` emitters with our radiant intensity (W/sr); our triangles (scene_triangles: the same
geometry, the MTL reflectances) as meshes with a `twosided` `diffuse` BSDF per reflectance; a
`perspective` sensor with fov_axis = 'y' and our camera's look-at frame.

What is compared: our renders sample each pixel at its centre (spp = 1, SCENE_FORMAT.md), Mitsuba's
film integrates the pixel with a box filter. To compare like with like, Mitsuba is run on our
pixel centres: its sensor makes the ray of each pixel centre, its integrator's `sample()` estimates
the radiance, the samples are summed per pixel (timed like `mi.render`, which costs the same). The
film path itself (`mi.render`, `rfilter` box) is checked separately against our stratified
pixel-averaged quadrature (check 4). With `scalar_rgb`, Mitsuba is only run through `mi.render`
and compared against the pixel-averaged reference.

Checks first (a small non-square image, a camera looking off-axis, so that flips and the fov axis
show): (1) Mitsuba's sensor rays against ours at the pixel centres; (2) surfaces only in vacuum,
where Mitsuba is deterministic; (3) air-light only (black walls) at many spp: mean ratio +- its
standard error, a few pixels, and the error against the flipped references; (4) the box filter.

Scenes: the box room (no occluders, so unshadowed; isotropic and HG g = 0.5), the box room with a
plate between the light and the floor (our renders with volumetric_shadows = True), and Sibenik
(RAYTRACE_ASSETS) seen by a perspective camera at the environment camera's position (Mitsuba has
no equirectangular sensor in every version), with volumetric shadows. Reference: `quadrature`.
Error: mean relative error over pixels and channels where the reference exceeds 1e-3 of its max.
Mitsuba climbs an spp ladder; our `analytic` runs at precision 1e-2 and 1e-3, `montecarlo` climbs
a ladder of distance samples per ray. Times are wall-clock seconds of one call on all cores
(Mitsuba's include its Python-side tracing and the copy to numpy, ours the whole `raytrace.render`),
kernel compilation excluded by a warm-up; all runs of a scene take turns in rounds (median; the
machine may be shared). About 6 minutes on 2 cores, --quick about 20 s. The time to reach a target
error is interpolated on a log-log line between the bracketing points of a ladder; below the
ladder's best error it is extrapolated (marked ~: error ~ n^slope and seconds = a + b n, both
fitted on the last three points); when the cheapest setting already beats the target its time is an
upper bound (marked <=, which makes Mitsuba's time over ours a lower bound, >=). Bias: the mean over pixels of Mitsuba /
ours (channel sums) at the top spp, pooled over the rounds, with its standard error, beside what
Mitsuba's shadow-ray shortening predicts: every shadow ray stops at (1 - ShadowEpsilon) of the
distance to the light (8.94e-4 in float variants), which overestimates the transmittance to the
light by exp(sigma_t * 8.94e-4 * d); `epsilon_prediction` integrates our image with and without
that factor (Gauss-Legendre in the angle seen from the light, a shadow ray per node).
"""
from __future__ import annotations

import argparse
import glob
import importlib.util
import json
import os
import platform
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

TARGETS = (1e-2, 1e-3)
PROBE = r"""
import mitsuba as mi, drjit as dr
mi.set_variant("llvm_ad_rgb")
s = mi.load_dict({"type": "scene", "integrator": {"type": "volpath", "max_depth": 2},
    "sensor": {"type": "perspective", "fov": 60, "film": {"type": "hdrfilm", "width": 8, "height": 6},
               "medium": {"type": "homogeneous", "sigma_t": 0.2, "albedo": 0.75, "phase": {"type": "hg", "g": 0.5}}},
    "light": {"type": "point", "position": [0, 0, 2], "intensity": 5.0},
    "wall": {"type": "rectangle", "to_world": mi.ScalarTransform4f().translate([0, 0, 3]).scale(5)}})
import numpy as np
print(float(np.array(mi.render(s, spp=4)).mean()))
"""


# ----------------------------------------------------------------------------------------- Mitsuba

def find_libllvm():
    """DRJIT_LIBLLVM_PATH if set, else the newest libLLVM >= 16 in the usual folders (None if none)."""
    if os.environ.get("DRJIT_LIBLLVM_PATH"):
        return os.environ["DRJIT_LIBLLVM_PATH"]
    best = None
    for pattern in ("/usr/lib/x86_64-linux-gnu/libLLVM*.so*", "/usr/lib/aarch64-linux-gnu/libLLVM*.so*",
                    "/usr/lib/llvm-*/lib/libLLVM*.so*", "/usr/lib64/libLLVM*.so*", "/usr/local/lib/libLLVM*.so*",
                    "/opt/homebrew/opt/llvm/lib/libLLVM.dylib"):
        for path in glob.glob(pattern):
            m = re.search(r"libLLVM[-.](?:so\.)?(\d+)", os.path.basename(path)) or re.search(r"llvm-(\d+)", path)
            major = int(m.group(1)) if m else 0
            if major >= 16 and (best is None or major > best[0]):
                best = (major, path)
    return best[1] if best else None


def choose_variant(requested):
    """('llvm_ad_rgb' or 'scalar_rgb', a note on why). The LLVM variant is probed in a subprocess
    because a JIT failure may abort the process."""
    if requested == "scalar_rgb":
        return "scalar_rgb", "scalar_rgb requested"
    llvm = find_libllvm()
    if llvm is None:
        return "scalar_rgb", "no libLLVM >= 16 found (set DRJIT_LIBLLVM_PATH); fell back to scalar_rgb"
    os.environ["DRJIT_LIBLLVM_PATH"] = llvm
    try:
        r = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, timeout=300,
                           env=dict(os.environ))
    except subprocess.TimeoutExpired:
        return "scalar_rgb", f"llvm_ad_rgb probe with {llvm} timed out; fell back to scalar_rgb"
    if r.returncode != 0:
        lines = r.stderr.strip().splitlines() or ["(no message)"]
        why = next((x for x in lines if "Cannot select" in x or "rror" in x), lines[-1]).strip()[:200]
        return "scalar_rgb", f"llvm_ad_rgb failed with {llvm} ({why}); fell back to scalar_rgb"
    return "llvm_ad_rgb", f"llvm_ad_rgb with DRJIT_LIBLLVM_PATH={llvm}"


class Mitsuba:
    """Our parsed scene rebuilt in Mitsuba, rendered at our pixel centres or through its film."""

    def __init__(self, mi, dr, scene, max_lanes=1 << 22):
        from raytrace.media.phase import HG, ISOTROPIC, RAYLEIGH
        from raytrace.scene.meshes import scene_triangles

        self.mi, self.dr, self.max_lanes = mi, dr, max_lanes
        cam, med = scene.camera, scene.medium
        if cam.type != "perspective":
            raise ValueError("Mitsuba gets a perspective camera (no equirectangular sensor in every version)")
        if np.any(np.asarray(scene.background) != 0.0):
            raise ValueError("the background must be black (Mitsuba scenes here have no environment)")
        self.W, self.H = cam.width, cam.height
        sensor = {"type": "perspective", "fov": float(cam.fov), "fov_axis": "y", "near_clip": 1e-5,
                  "far_clip": 1e7,
                  "to_world": mi.ScalarTransform4f().look_at(origin=cam.position.tolist(),
                                                            target=cam.look_at.tolist(), up=cam.up.tolist()),
                  "film": {"type": "hdrfilm", "width": self.W, "height": self.H, "rfilter": {"type": "box"},
                           "pixel_format": "rgb", "component_format": "float32"},
                  "sampler": {"type": "independent", "sample_count": 1}}
        st = np.asarray(med.sigma_t, float)
        if np.any(st > 0.0):
            if not np.allclose(st, st[0]):
                raise ValueError("per-channel extinction: render one channel at a time")
            phase = {ISOTROPIC: {"type": "isotropic"}, RAYLEIGH: {"type": "rayleigh"},
                     HG: {"type": "hg", "g": float(med.g)}}[med.phase]
            sensor["medium"] = {"type": "homogeneous", "sigma_t": float(st[0]),
                                "albedo": {"type": "rgb", "value": (np.asarray(med.sigma_s) / st).tolist()},
                                "phase": phase}
        d = {"type": "scene", "integrator": {"type": "volpath", "max_depth": 2}, "sensor": sensor}
        for i, light in enumerate(scene.lights):
            d[f"light{i}"] = {"type": "point", "position": np.asarray(light.position, float).tolist(),
                              "intensity": {"type": "rgb", "value": np.asarray(light.intensity, float).tolist()}}
        tris, refl = scene_triangles(scene)
        colours, which = np.unique(refl, axis=0, return_inverse=True)
        for k, rho in enumerate(colours):
            t = tris[which.ravel() == k]
            props = mi.Properties()
            props["bsdf"] = mi.load_dict({"type": "twosided", "material": {
                "type": "diffuse", "reflectance": {"type": "rgb", "value": rho.tolist()}}})
            mesh = mi.Mesh(f"group{k}", vertex_count=3 * len(t), face_count=len(t), props=props,
                           has_vertex_normals=False, has_vertex_texcoords=False)  # flat: geometric normals
            p = mi.traverse(mesh)
            p["vertex_positions"] = t.reshape(-1).astype(np.float32)
            p["faces"] = np.arange(3 * len(t), dtype=np.uint32)
            p.update()
            d[f"mesh{k}"] = mesh
        self.scene = mi.load_dict(d)
        self.shadow_epsilon = float(mi.math.ShadowEpsilon)
        self.sensor = self.scene.sensors()[0]
        self.integrator = self.scene.integrator()
        self.vectorised = "llvm" in mi.variant() or "cuda" in mi.variant()

    @classmethod
    def from_file(cls, mi, dr, path, max_lanes=1 << 22, **params):
        """A Mitsuba XML scene as Mitsuba loads it (its own sensor, integrator and emitters; `params` set
        the file's <default> values, as `mi.load_file`)."""
        self = cls.__new__(cls)
        self.mi, self.dr, self.max_lanes = mi, dr, max_lanes
        self.scene = mi.load_file(str(path), **params)
        self.sensor, self.integrator = self.scene.sensors()[0], self.scene.integrator()
        self.W, self.H = (int(n) for n in self.sensor.film().size())
        self.vectorised = "llvm" in mi.variant() or "cuda" in mi.variant()
        return self

    def rays(self):
        """Origins and directions (H*W, 3) of Mitsuba's sensor at our pixel centres (row 0 on top)."""
        mi, dr = self.mi, self.dr
        idx = dr.arange(mi.UInt32, self.W * self.H)
        pos = mi.Point2f((mi.Float(idx % self.W) + 0.5) / self.W, (mi.Float(idx // self.W) + 0.5) / self.H)
        ray, _ = self.sensor.sample_ray(0.0, 0.5, pos, mi.Point2f(0.5, 0.5))
        return (np.array(ray.o, dtype=np.float64).reshape(3, -1).T,
                np.array(ray.d, dtype=np.float64).reshape(3, -1).T)

    def centres(self, spp, seed):
        """(H, W, 3): volpath's estimate at our pixel centres, spp samples each, in passes of at most
        max_lanes samples (pixel index = lane mod W*H, summed by an atomic scatter)."""
        mi, dr = self.mi, self.dr
        WH = self.W * self.H
        passes = -(-spp // max(1, self.max_lanes // WH))
        per_pass = -(-spp // passes)
        acc = np.zeros(WH * 3)
        done, k = 0, 0
        while done < spp:
            n = min(per_pass, spp - done)
            sampler = mi.load_dict({"type": "independent"})
            sampler.seed((seed * 65537 + k) % 2**32, WH * n)
            pix = dr.arange(mi.UInt32, WH * n) % WH
            pos = mi.Point2f((mi.Float(pix % self.W) + 0.5) / self.W, (mi.Float(pix // self.W) + 0.5) / self.H)
            ray, weight = self.sensor.sample_ray(0.0, 0.5, pos, mi.Point2f(0.5, 0.5))
            radiance, _, _ = self.integrator.sample(self.scene, sampler, ray, self.sensor.get_medium(), True)
            radiance = radiance * weight
            img = dr.zeros(mi.Float, WH * 3)
            for c in range(3):
                dr.scatter_reduce(dr.ReduceOp.Add, img, radiance[c], pix * 3 + c)
            dr.eval(img)
            acc += np.array(img, dtype=np.float64)
            done, k = done + n, k + 1
        return (acc / spp).reshape(self.H, self.W, 3)

    def film(self, spp, seed):
        """(H, W, 3): `mi.render` through the film (box filter: the pixel average)."""
        return np.array(self.mi.render(self.scene, spp=spp, seed=seed), dtype=np.float64)[..., :3]

    def render(self, spp, seed):
        return self.centres(spp, seed) if self.vectorised else self.film(spp, seed)


# ----------------------------------------------------------------------------------------- scenes

def box_room(w, h, shapes=(), phase="isotropic", reflectance=(0.6, 0.5, 0.4), sigma=(0.05, 0.15)):
    """tests/conftest.py's box room (6 x 4 x 8, camera inside looking down -z, one light)."""
    return {"camera": {"type": "perspective", "position": [0.3, 0.2, 3.0], "look_at": [0.0, 0.0, -1.0],
                       "fov": 70.0, "width": w, "height": h, "spp": 1},
            "shape": [{"primitive": "box", "min": [-3.0, -2.0, -4.0], "max": [3.0, 2.0, 4.0],
                       "reflectance": list(reflectance)}] + list(shapes),
            "light": [{"position": [0.5, 1.0, -1.0], "intensity": [10.0, 8.0, 6.0]}],
            "medium": {"sigma_a": sigma[0], "sigma_s": sigma[1], "phase": phase}}


# a tilted plate under the light (its lit top faces the camera): shadows the floor and the medium below it
PLATE = {"primitive": "quad", "reflectance": 0.5,
         "corners": [[-0.8, 0.6, -2.2], [1.6, 0.6, -2.2], [1.6, 0.0, -0.4], [-0.8, 0.0, -0.4]]}


def scenes(quick):
    """[(name, Scene, volumetric_shadows)]."""
    import raytrace

    w, h = (64, 48) if quick else (128, 96)
    out = [("box room", raytrace.load(box_room(w, h)), False),
           ("box room, HG g=0.5", raytrace.load(box_room(w, h, phase={"type": "hg", "g": 0.5})), False),
           ("box room + plate (shadowed)", raytrace.load(box_room(w, h, shapes=[PLATE])), True)]
    sw, sh = (64, 32) if quick else (128, 64)
    try:
        sib = raytrace.load("sibenik", overrides=['camera.type="perspective"', "camera.fov=60.0",
                                                  f"camera.width={sw}", f"camera.height={sh}", "camera.spp=1"])
        from raytrace.scene.meshes import scene_triangles
        scene_triangles(sib)  # the meshes are there
        out.append(("Sibenik, perspective crop (shadowed)", sib, True))
    except raytrace.UserError as exc:
        print(f"(Sibenik skipped: {exc})")
    return out


def epsilon_prediction(prep, eps, nodes=64):
    """What Mitsuba's shortened shadow rays should do to our image: every light's transmittance
    exp(-kt d) becomes exp(-kt (1 - eps) d). Evaluated at the pixel centres with Gauss-Legendre in the
    angle seen from the light (dx / d^2 = dtheta / h, PP09) and a shadow ray per node, for the exact
    and the shortened transmittance: (L exact (H, W, 3), L shortened (H, W, 3)). The quadrature is
    coarse at shadow boundaries, which cancels in the ratio of the two."""
    from raytrace.camera import generate_rays
    from raytrace.media import Homogeneous
    from raytrace.media.phase import phase_value
    from raytrace.shading import facing_normals, surface_radiance

    scene, accel = prep.scene, prep.accel
    cam, med = scene.camera, scene.medium
    spp, cam.spp = cam.spp, 1
    o, d = generate_rays(cam)
    cam.spp = spp
    t, prim = accel.first_hit(o, d)
    hit = prim >= 0
    kt, ks = np.asarray(med.sigma_t, float), np.asarray(med.sigma_s, float)
    out = [np.zeros((len(o), 3)), np.zeros((len(o), 3))]
    if hit.any():
        pts = o[hit] + t[hit, None] * d[hit]
        nrm = facing_normals(accel.normals[prim[hit]], d[hit])
        for k, m in enumerate((med, Homogeneous(kt * (1.0 - eps), np.zeros(3)))):
            out[k][hit] = surface_radiance(accel, pts, nrm, prep.reflectance[prim[hit]], prep.lights, m) * \
                np.exp(-kt[None, :] * t[hit, None])
    if np.any(ks > 0.0):
        u, w = np.polynomial.legendre.leggauss(nodes)
        far = np.where(hit, t, np.inf)
        for li, pl in enumerate(prep.lights.position):
            v = pl[None, :] - o
            xh = np.einsum("ij,ij->i", v, d)
            h = np.linalg.norm(v - xh[:, None] * d, axis=1)
            ok = h > 1e-9
            ta = np.arctan2(-xh, h)
            tb = np.where(np.isinf(far), np.pi / 2, np.arctan2(far - xh, h))
            th = 0.5 * (ta + tb)[:, None] + 0.5 * (tb - ta)[:, None] * u[None, :]  # (N, nodes)
            x = xh[:, None] + h[:, None] * np.tan(th)
            dist = h[:, None] / np.cos(th)
            p = o[:, None, :] + x[..., None] * d[:, None, :]
            to_l = (pl[None, None, :] - p) / dist[..., None]
            vis = ~accel.occluded(p.reshape(-1, 3), to_l.reshape(-1, 3), (dist * (1.0 - 1e-7)).ravel()).reshape(x.shape)
            mu = -np.sin(th)  # the scattering angle's cosine (0 towards the light's foot point)
            phase = np.vectorize(lambda c: phase_value(med.phase, med.g, c))(mu)
            base = (0.5 * (tb - ta))[:, None] * w[None, :] * vis * phase / np.where(ok, h, 1.0)[:, None]
            for k, f in enumerate((1.0, 1.0 - eps)):
                val = base[..., None] * np.exp(-kt * x[..., None] - f * kt * dist[..., None])  # (N, nodes, 3)
                out[k][ok] += (val.sum(axis=1) * ks * prep.lights.intensity[li])[ok]
    return tuple(a.reshape(cam.height, cam.width, 3) for a in out)


# ----------------------------------------------------------------------------------------- numbers

def mre(img, ref):
    """Mean relative error over pixels and channels where the reference exceeds 1e-3 of its max."""
    mask = ref > 1e-3 * ref.max()
    return float(np.mean(np.abs(img[mask] - ref[mask]) / ref[mask]))


def ratio(img, ref):
    """Mean over pixels of img / ref (channel sums, pixels above 1e-3 of the max), its standard error, N."""
    a, b = img.sum(axis=2), ref.sum(axis=2)
    mask = b > 1e-3 * b.max()
    r = a[mask] / b[mask]
    return float(r.mean()), float(r.std(ddof=1) / np.sqrt(r.size)), int(r.size)


def time_to_error(ladder, target, extrapolate=True):
    """Seconds to reach `target` on a ladder [(n, seconds, error)] in increasing n (spp, samples), and
    how: 'interp' (log error and log seconds interpolated linearly in log n between the bracketing
    points), '~' (extrapolated: error ~ n^slope on the last three points, seconds = a + b n fitted on
    them), '<=' (the cheapest point already beats it: its seconds), or (None, 'not reached')."""
    pts = [(n, t, e) for n, t, e in ladder if t > 0 and e > 0]
    if not pts:
        return None, "not reached"
    if pts[0][2] <= target:
        return min(t for _, t, e in pts if e <= target), "<="
    for (n0, t0, e0), (n1, t1, e1) in zip(pts, pts[1:]):
        if e0 >= target >= e1 and e0 > e1:
            f = (np.log(target) - np.log(e0)) / (np.log(e1) - np.log(e0))
            return float(np.exp(np.log(t0) + f * (np.log(t1) - np.log(t0)))), "interp"
    if not extrapolate or len(pts) < 3:
        return None, "not reached"
    n, t, e = (np.array(x, float) for x in zip(*pts[-3:]))
    slope = np.polyfit(np.log(n), np.log(e), 1)[0]
    if not slope < 0:
        return None, "not reached"
    n_star = n[-1] * (target / e[-1]) ** (1.0 / slope)
    b, a = np.polyfit(n, t, 1)
    seconds = a + b * n_star if b > 0 else t[-1] * n_star / n[-1]
    return float(seconds), "~"


def machine():
    cpu = platform.processor() or "?"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True).stdout.strip()
    except OSError:
        commit = "?"
    return {"cpu": cpu, "cores": os.cpu_count(),
            "usable_cores": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count(),
            "os": platform.platform(), "python": platform.python_version(), "numpy": np.__version__,
            "raytrace_commit": commit, "date": time.strftime("%Y-%m-%d %H:%M")}


# ----------------------------------------------------------------------------------------- checks

def checks(mi_mod, dr, quick, vectorised):
    """Conventions on small non-square images with an off-axis camera: rays, vacuum, air-light, film."""
    import raytrace
    from raytrace.camera import generate_rays

    out = {}
    w, h = 48, 32

    def off_axis(sc):
        sc["camera"].update(position=[0.9, -0.4, 2.6], look_at=[-0.6, 0.5, -1.5])
        return sc

    # 1. rays at the pixel centres
    plate_vac = raytrace.load(off_axis(box_room(w, h, shapes=[PLATE], sigma=(0.0, 0.0))))
    m = Mitsuba(mi_mod, dr, plate_vac)
    if vectorised:
        o, d = m.rays()
        cam = plate_vac.camera
        o2, d2 = generate_rays(cam)
        out["rays"] = {"max_origin_diff": float(np.abs(o - o2).max()),
                       "max_direction_diff": float(np.linalg.norm(d - d2, axis=1).max()),
                       "pixel_angle": float(np.radians(cam.fov) / h)}
        print(f"check 1, rays at the pixel centres ({w}x{h}, off-axis camera): max |origin diff| "
              f"{out['rays']['max_origin_diff']:.1e}, max |direction diff| {out['rays']['max_direction_diff']:.1e} "
              f"(a pixel is {out['rays']['pixel_angle']:.1e} rad)")

    # 2. surfaces only, vacuum (deterministic in Mitsuba: delta light, no medium), with the plate's shadow
    ref = raytrace.render(plate_vac, method="quadrature", spp=1).array
    img = m.render(1 if vectorised else 64, 1)
    if not vectorised:
        ref = raytrace.render(plate_vac, method="quadrature", spp=64).array
    mask = ref > 1e-3 * ref.max()
    rel = np.abs(img - ref)[mask] / ref[mask]
    shadowed = float(np.mean(ref.sum(2) == 0.0))
    out["vacuum"] = {"mean_rel": float(rel.mean()), "max_rel": float(rel.max()),
                     "p99_rel": float(np.percentile(rel, 99)), "black_pixels_ours": shadowed,
                     "black_pixels_mitsuba": float(np.mean(img.sum(2) == 0.0)),
                     "mean_ratio": float(img.mean() / ref.mean())}
    how = "1 spp at the pixel centres" if vectorised else "mi.render 64 spp"
    print(f"check 2, surfaces in vacuum with the plate ({how}): relative difference mean {rel.mean():.1e}, "
          f"99th percentile {np.percentile(rel, 99):.1e}, max {rel.max():.1e}"
          f"{'' if vectorised else ' (pixel averages differ at edges)'}; mean ratio {out['vacuum']['mean_ratio']:.6f}")

    # 3. air-light only: black walls, no plate
    air = raytrace.load(off_axis(box_room(w, h, reflectance=(0.0, 0.0, 0.0))))
    m = Mitsuba(mi_mod, dr, air)
    spp = 1024 if quick else 8192
    ref = raytrace.render(air, method="quadrature", spp=1 if vectorised else 64).array
    img = m.render(spp, 2)
    r, se, n = ratio(img, ref)
    flips = {"as is": mre(img, ref), "left-right flipped": mre(img, ref[:, ::-1]),
             "upside down": mre(img, ref[::-1])}
    pix = {f"({x},{y})": [float(img[y, x, 0]), float(ref[y, x, 0])] for x, y in ((0, 0), (w - 1, 0), (0, h - 1),
                                                                                (w // 2, h // 2), (w - 1, h - 1))}
    out["airlight"] = {"spp": spp, "ratio": r, "se": se, "pixels": n, "mre": flips, "pixels_mitsuba_ours": pix}
    print(f"check 3, air-light only (black walls, {spp} spp): Mitsuba/ours {r:.5f} +- {se:.5f}; mean rel. error "
          f"{flips['as is']:.3f} as is, {flips['left-right flipped']:.3f} against the left-right flipped reference, "
          f"{flips['upside down']:.3f} upside down; red at pixels (x,y) Mitsuba/ours: "
          + ", ".join(f"{k} {a:.4g}/{b:.4g}" for k, (a, b) in pix.items()))

    # 4. the film: mi.render with the box filter against our stratified pixel average
    full = raytrace.load(off_axis(box_room(w, h)))
    m = Mitsuba(mi_mod, dr, full)
    spp = 1024 if quick else 4096
    ref_avg = raytrace.render(full, method="quadrature", spp=256).array
    ref_ctr = raytrace.render(full, method="quadrature", spp=1).array
    img = m.film(spp, 3)
    r, se, n = ratio(img, ref_avg)
    out["film"] = {"spp": spp, "ratio_vs_pixel_average": r, "se": se,
                   "mre_vs_pixel_average": mre(img, ref_avg), "mre_vs_pixel_centre": mre(img, ref_ctr),
                   "mre_centre_vs_average_ours": mre(ref_ctr, ref_avg)}
    print(f"check 4, mi.render (box filter, {spp} spp) against our 16x16-stratified quadrature: Mitsuba/ours {r:.5f} "
          f"+- {se:.5f}; mean rel. error {out['film']['mre_vs_pixel_average']:.4f} against the pixel average, "
          f"{out['film']['mre_vs_pixel_centre']:.4f} against the pixel centres (ours centre vs average: "
          f"{out['film']['mre_centre_vs_average_ours']:.4f})")
    return out


# ----------------------------------------------------------------------------------------- benchmark

def bench_scene(mi_mod, dr, index, name, scene, shadows, quick, vectorised):
    import raytrace
    from raytrace.rendering.renderer import prepare

    prep = prepare(scene)
    t0 = time.perf_counter()
    m = Mitsuba(mi_mod, dr, scene)
    build_s = time.perf_counter() - t0
    W, H = scene.camera.width, scene.camera.height

    def ours(method, seed=0, **params):
        t = time.perf_counter()
        img = raytrace.render(None, method=method, spp=1, seed=seed, prepared=prep, volumetric_shadows=shadows,
                              **params)
        return time.perf_counter() - t, img

    ours("quadrature")
    t_ref, ref_img = ours("quadrature")
    ref = ref_img.array
    # with scalar_rgb Mitsuba goes through its film: compare it with our pixel average (8 x 8 stratified)
    mitsuba_ref = ref if vectorised else raytrace.render(None, method="quadrature", spp=64, prepared=prep,
                                                         volumetric_shadows=shadows).array
    ladder = [4, 16, 64, 256] if quick else [4, 16, 64, 256, 1024, 4096]
    mc_ladder = [1, 4, 16, 64] if quick else [1, 4, 16, 64, 256, 1024]
    rounds = 2 if quick else 3
    film_spp = 64 if quick else 256
    configs = [("mitsuba", {"spp": s}) for s in ladder] + [("analytic", {"precision": p}) for p in TARGETS] + \
              [("montecarlo", {"samples": s}) for s in mc_ladder]
    if vectorised:
        configs.append(("mitsuba film", {"spp": film_spp}))  # the same samples through mi.render: its time
    t0 = time.perf_counter()
    m.render(4, 0)  # compile Mitsuba's kernels
    if vectorised:
        m.film(4, 0)
    compile_s = time.perf_counter() - t0
    for method in ("analytic", "montecarlo"):
        ours(method)
    runs = {i: [] for i in range(len(configs))}
    top = np.zeros_like(ref)
    for rnd in range(rounds):
        order = list(range(len(configs)))
        if rnd % 2:
            order.reverse()
        for i in order:
            method, params = configs[i]
            seed = 100000 * index + 1000 * rnd + i + 1
            if method.startswith("mitsuba"):
                t = time.perf_counter()
                img = m.film(params["spp"], seed) if method == "mitsuba film" else m.render(params["spp"], seed)
                sec = time.perf_counter() - t
                err = mre(img, mitsuba_ref) if method == "mitsuba" else float("nan")
                if method == "mitsuba" and params["spp"] == ladder[-1]:
                    top += img / rounds
            else:
                sec, res = ours(method, seed=seed, **params)
                err = mre(res.array, ref)
            runs[i].append((sec, err))
    rows = []
    for i, (method, params) in enumerate(configs):
        secs, errs = zip(*runs[i])
        rows.append({"renderer": method, "params": params, "seconds": float(np.median(secs)),
                     "error": float(np.median(errs)), "runs": [list(x) for x in runs[i]]})
    bias, se, npx = ratio(top, mitsuba_ref)
    exact, shortened = epsilon_prediction(prep, m.shadow_epsilon)
    a, b = shortened.sum(axis=2), exact.sum(axis=2)
    mask = ref.sum(axis=2) > 1e-3 * ref.sum(axis=2).max()
    predicted = float(np.mean(a[mask] / b[mask]))
    curves = {}
    for r in ("mitsuba", "analytic", "montecarlo"):
        pts = [(next(iter(row["params"].values())), row["seconds"], row["error"]) for row in rows
               if row["renderer"] == r]
        if r == "analytic":  # the coarser precision first
            pts.reverse()
        curves[r] = {f"{E:g}": time_to_error(pts, E, extrapolate=(r != "analytic")) for E in TARGETS}
    summary = {}
    for r in ("analytic", "montecarlo"):
        summary[r] = {}
        for E in TARGETS:
            tm, to = curves["mitsuba"][f"{E:g}"][0], curves[r][f"{E:g}"][0]
            summary[r][f"{E:g}"] = (tm / to) if (tm and to) else None
    film = [row for row in rows if row["renderer"] == "mitsuba film"]
    same = [row for row in rows if row["renderer"] == "mitsuba" and row["params"]["spp"] == film_spp]
    return {"scene": name, "width": W, "height": H, "volumetric_shadows": shadows,
            "triangles": int(len(prep.reflectance)), "mitsuba_build_seconds": build_s,
            "mitsuba_compile_seconds": compile_s, "rounds": rounds,
            "reference": {"method": "quadrature", "seconds": t_ref, "mean": float(ref.mean())},
            "rows": rows, "time_to_error": curves, "mitsuba_over_ours_time": summary,
            "film_over_centres_time": (film[0]["seconds"] / same[0]["seconds"]) if film and same else None,
            "bias": {"spp": ladder[-1] * rounds, "ratio": bias, "se": se, "pixels": npx,
                     "shadow_epsilon": m.shadow_epsilon, "predicted_ratio": predicted,
                     "prediction_vs_reference_mre": mre(exact, ref)}}


def fmt_t(entry):
    t, how = entry
    return "not reached" if t is None else {"interp": "", "~": "~", "<=": "<= "}[how] + f"{t:.3g}"


def ratio_cell(res, r, E):
    """Mitsuba's time over ours at error E: >= when ours is an upper bound, ~ when either is extrapolated."""
    value = res["mitsuba_over_ours_time"][r][f"{E:g}"]
    if value is None:
        return "—"
    how_m, how_o = res["time_to_error"]["mitsuba"][f"{E:g}"][1], res["time_to_error"][r][f"{E:g}"][1]
    mark = ("~" if "~" in (how_m, how_o) else "") + (">= " if how_o == "<=" else "")
    return f"{mark}{value:.3g}"


def table(results, info):
    mach = info["machine"]
    where = "Mitsuba at our pixel centres" if info["vectorised"] else "Mitsuba through its film (box filter)"
    lines = [f"Mitsuba {info['mitsuba']} ({info['variant_note']}) vs raytrace {mach['raytrace_commit']} on "
             f"{mach['cpu']}, {mach['usable_cores']} cores, Python {mach['python']}, {mach['date']}; "
             f"{'quick' if info['quick'] else 'full'} run, {where}; errors: mean relative error against our "
             "quadrature (pixels above 1e-3 of the max); time to an error: log-log interpolation on each ladder "
             "(~ extrapolated, <= already reached at the cheapest setting, so Mitsuba ÷ ours >= that); "
             "medians of interleaved rounds",
             "",
             "| scene | renderer | runs: setting, seconds, mean rel. error | s to 1e-2 | s to 1e-3 "
             "| Mitsuba ÷ ours, time @1e-2 | @1e-3 | Mitsuba / ours (bias) |",
             "|---|---|---|---|---|---|---|---|"]
    short = {"spp": "spp", "precision": "p", "samples": "samples"}
    for res in results:
        scene = f"{res['scene']} {res['width']}x{res['height']}"
        b = res["bias"]
        for r in ("mitsuba", "analytic", "montecarlo"):
            cells = [f"{short[k]}={v:g}: {row['seconds']:.3g} s, {row['error']:.2g}"
                     for row in res["rows"] if row["renderer"] == r for k, v in row["params"].items()]
            t2, t3 = (fmt_t(res["time_to_error"][r][f"{E:g}"]) for E in TARGETS)
            if r == "mitsuba":
                ratios = ("", "")
                bias = (f"{b['ratio']:.5f} ± {b['se']:.5f} ({b['spp']} spp; shadow ε predicts "
                        f"{b['predicted_ratio']:.5f})")
            else:
                ratios, bias = tuple(ratio_cell(res, r, E) for E in TARGETS), ""
            lines.append(f"| {scene} | {r} | {'; '.join(cells)} | {t2} | {t3} | {ratios[0]} | {ratios[1]} | {bias} |")
        lines.append(f"| {scene} | quadrature (reference) | {res['reference']['seconds']:.3g} s | | | | | |")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller images and ladders (under 2 minutes)")
    ap.add_argument("--out", default=str(ROOT / "out" / "vs_mitsuba.json"), help="JSON results")
    ap.add_argument("--variant", choices=("auto", "scalar_rgb"), default="auto",
                    help="auto: llvm_ad_rgb if it works, else scalar_rgb")
    ap.add_argument("--no-checks", action="store_true", help="skip the convention checks")
    args = ap.parse_args()
    if importlib.util.find_spec("mitsuba") is None:
        print("vs_mitsuba: skipped, the mitsuba package is not installed (pip install -e '.[bench]' or "
              "pip install 'mitsuba>=3.5')")
        return 0
    start = time.perf_counter()
    assets = ROOT.parent / "shared" / "scenes"
    if not os.environ.get("RAYTRACE_ASSETS") and assets.is_dir():
        os.environ["RAYTRACE_ASSETS"] = str(assets)
    variant, note = choose_variant(args.variant)
    import drjit as dr
    import mitsuba as mi

    mi.set_variant(variant)
    print(f"Mitsuba {mi.__version__} (Dr.Jit {dr.__version__}), variant {variant}: {note}")
    vectorised = variant != "scalar_rgb"
    info = {"mitsuba": mi.__version__, "drjit": dr.__version__, "variant": variant, "variant_note": note,
            "vectorised": vectorised, "quick": args.quick, "machine": machine()}
    info["checks"] = {} if args.no_checks else checks(mi, dr, args.quick, vectorised)
    results = []
    for index, (name, scene, shadows) in enumerate(scenes(args.quick)):
        t = time.perf_counter()
        results.append(bench_scene(mi, dr, index, name, scene, shadows, args.quick, vectorised))
        b = results[-1]["bias"]
        print(f"{name}: {time.perf_counter() - t:.0f} s; Mitsuba/ours {b['ratio']:.5f} +- {b['se']:.5f} at "
              f"{b['spp']} spp, shadow epsilon predicts {b['predicted_ratio']:.5f} (the prediction's own error "
              f"{b['prediction_vs_reference_mre']:.1e}); film/centres time {results[-1]['film_over_centres_time']}")
    info["results"] = results
    info["total_seconds"] = time.perf_counter() - start
    print()
    print(table(results, info))
    print(f"\n(total {info['total_seconds']:.0f} s)")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(info, indent=1))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
