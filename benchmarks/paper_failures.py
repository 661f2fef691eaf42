"""Where the paper's own evaluations fail, measured: the Fig. 2 series at large rho, and the Taylor
anisotropic variant (eqs. 14-19) on ordinary rays.

    python benchmarks/paper_failures.py

Table 1: I0(-H, va, vb) from the paper's series alone (`expint.i01_series`, precision 1e-12,
unlimited iterations) and from the scaled-E1 form the renderer switches to, both against mpmath
at 30 digits, for intervals whose far end has rho = H sqrt(1 + v^2) as given.
Table 2: the default scene's camera rays (1 spp, 2 lights) in Rayleigh and Henyey-Greenstein
media: the relative error per evaluation of `analytic --anisotropic taylor --terms N` and of the
default (`--anisotropic exact`) against `quadrature` at rtol 1e-12, and the fraction of
evaluations whose v-interval leaves the Taylor series' radius of convergence.
"""
import dataclasses
import math
import sys
from pathlib import Path

import mpmath as mp
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from raytrace.camera import generate_rays  # noqa: E402
from raytrace.default_scene import DEFAULT_TOML  # noqa: E402
from raytrace.methods import get_method, resolve_params  # noqa: E402
from raytrace.methods.analytic import ST_EVALS, ST_TAYLOR_OUT  # noqa: E402
from raytrace.media.expint import i01_series, i0i1_stable  # noqa: E402
from raytrace.media.phase import HG, RAYLEIGH  # noqa: E402
from raytrace.rendering.renderer import prepare  # noqa: E402
from raytrace.scene.format import scene_from_text  # noqa: E402
from raytrace.segments import unshadowed_airlight  # noqa: E402


def i0_mpmath(H, va, vb):
    mp.mp.dps = 30
    f = lambda v: mp.exp(-H * v) / (1 + v * v)  # noqa: E731
    return float(mp.quad(f, [va, 1, vb]) if va < 1 < vb else mp.quad(f, [va, vb]))


def series_table():
    print("| rho at the far end | H | v interval | I0 (mpmath) | paper's series: rel. error | scaled E1: rel. error |")
    print("|---|---|---|---|---|---|")
    H = 2.0
    for rho in (4.0, 8.0, 12.0, 16.0, 24.0, 30.0, 40.0):
        vb = math.sqrt((rho / H) ** 2 - 1.0)
        va = 0.5 * vb
        ref = i0_mpmath(H, va, vb)
        ser = i01_series(-H, va, vb, 1e-12, 100000)[0]
        stab = i0i1_stable(H, va, vb)[0]
        err_ser = abs(ser - ref) / ref if np.isfinite(ser) else float("inf")
        print(f"| {rho:g} | {H:g} | [{va:.3g}, {vb:.3g}] | {ref:.3e} | {err_ser:.1e} | {abs(stab - ref) / ref:.1e} |")


def taylor_table():
    scene = scene_from_text(DEFAULT_TOML, "default scene",
                            overrides=["camera.width=96", "camera.height=64", "camera.spp=1"])
    prep = prepare(scene)
    o, d = generate_rays(scene.camera)
    t, _ = prep.accel.first_hit(o, d)
    rays = (o, d, t, np.arange(len(o), dtype=np.uint64), 0, prep.accel.scale)
    analytic = get_method("analytic")
    print("\n| phase | variant | negative results | median rel. error | max rel. error | out of Taylor range |")
    print("|---|---|---|---|---|---|")
    for label, code, g in [("rayleigh", RAYLEIGH, 0.0), ("hg g=0.5", HG, 0.5), ("hg g=-0.5", HG, -0.5)]:
        medium = dataclasses.replace(scene.medium, phase=code, g=g)
        q = get_method("quadrature")
        ref = unshadowed_airlight(q, medium, prep.lights, resolve_params(q, {"rtol": 1e-12}, ""), *rays)[0]
        variants = [("taylor", 3), ("taylor", 6), ("exact", 6)]
        for mode, terms in variants:
            p = resolve_params(analytic, {"anisotropic": mode, "terms": terms, "precision": 1e-6}, "")
            val, stats, _ = unshadowed_airlight(analytic, medium, prep.lights, p, *rays)
            rel = np.abs(val - ref) / ref
            name = f"taylor, {terms} terms" if mode == "taylor" else "exact (default), precision 1e-6"
            out = f"{stats[ST_TAYLOR_OUT] / stats[ST_EVALS]:.0%}" if mode == "taylor" else "-"
            print(f"| {label} | {name} | {np.mean(val < 0):.0%} | {np.median(rel):.1e} | {rel.max():.1e} | {out} |")


if __name__ == "__main__":
    series_table()
    taylor_table()
