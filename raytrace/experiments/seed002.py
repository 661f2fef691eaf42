"""The figures of the analytic note on single scattering in homogeneous slabs ("the note" below),
and the error of its separable approximation, measured.

The note plots, against the light's distance l from the entry point of the eye ray:
* Figs. 2, 3, 6, 7: the exponential part of eq. 7, ∫_0^s exp(-kt (x + k(x))) dx (no falloff, no
  phase function), next to the air-light's ∫_0^s exp(-kt (x + h(x))) dx (the light in the medium,
  eq. 8) and the distant-light limit (1 - exp(-kt (1 + c) s)) / (kt (1 + c)) of eq. 5;
* Figs. 4, 5, 8: the whole eq. 7 for a unit point light (isotropic, albedo 1) and its separable
  approximation (sec. 4.2), and the approximation's relative error.

Geometry (the note leaves it open; we fix it and say so): boundary z = 0 with outward normal n = +z,
the eye direction omega (from the entry point toward the eye) at cosine a = omega·n, the light at
l omega_l with b = omega_l·n on the opposite side of the normal (the mirror azimuth), c = a / b.
a = b = 1 is the note's coincidence case (light and eye on the normal: eq. 7 equals eq. 5's limit);
b = 0 (c = inf) puts the light in the plane (eq. 8). The sweep over (kt, s) measures where the
approximation fails: for each pair, the largest relative error over l and the smallest l beyond
which the error stays below 1 % and 10 %.

Everything numeric goes to CSV and a Markdown report; plots (PNG, matplotlib, the `plots` extra)
are optional.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from ..errors import UserError
from ..media import slab
from ..media.phase import ISOTROPIC

RTOL = 1e-11
L_GRID = np.logspace(-3, 3, 121)
QUICK_GRID = np.logspace(-3, 3, 13)  # `quick`: one point per half decade
MIRROR = math.pi  # azimuth between the eye and the light about the normal


def geometry(l, a, b, azimuth=MIRROR):
    """(x_h, h, H_L) of the light l omega_l for the eye ray entering along w = -omega (module docstring)."""
    omega = np.array([math.sqrt(max(0.0, 1.0 - a * a)), 0.0, a])
    sb = math.sqrt(max(0.0, 1.0 - b * b))
    omega_l = np.array([sb * math.cos(azimuth), sb * math.sin(azimuth), b])
    p = l * omega_l
    w = -omega
    return float(p @ w), float(max(np.linalg.norm(np.cross(p, w)), 0.0)), float(p[2])


def exponential_part(l, a, b, kt, s, airlight=False):
    """∫_0^s exp(-kt (x + k(x))) dx for the light at distance l; `airlight`: k = h (the light in the medium)."""
    xh, h, hl = geometry(l, a, b)
    return slab.exponential_part(xh, h, s, kt, 0.0, a, 0.0 if airlight else hl, RTOL, np.zeros(3))


def limit(a, b, kt, s):
    """Eq. 5's distant-light value of the exponential part (0 for c = inf)."""
    if b == 0.0:
        return 0.0
    return slab.slab_distant(kt, 1.0, 1.0, a / b, s)


def exact_and_approx(l, a, b, kt, s):
    """Eq. 7 for a unit point light (isotropic, albedo 1: ks = kt) and the note's approximation."""
    xh, h, hl = geometry(l, a, b)
    exact = slab.point_exact(xh, h, s, kt, kt, ISOTROPIC, 0.0, 0.0, a, hl, 0.0, RTOL, np.zeros(3))
    return exact, slab.point_approx(xh, h, s, kt, kt, ISOTROPIC, 0.0, a, b)


# the note's figures: (name, title, kt, s, [(label, a, b)] curves)
C_SET = [("c = 1", 0.7, 0.7), ("c = 2", 0.7, 0.35), ("c = 5", 0.7, 0.14), ("c = 10", 0.7, 0.07),
         ("c = inf", 0.7, 0.0)]
FIG_EXP = [
    ("fig2", "Fig. 2: s = 10, kt = 1, c = 1", 1.0, 10.0, [("c = 1 (0.7/0.7)", 0.7, 0.7), ("c = 1 (1/1)", 1.0, 1.0)]),
    ("fig3", "Fig. 3: s = 10, kt = 1, several c", 1.0, 10.0, C_SET),
    ("fig6", "Fig. 6: s = 10, kt = 1, c = 2", 1.0, 10.0, [("c = 2", 0.7, 0.35)]),
    ("fig7", "Fig. 7: s = 100, kt = 0.1, c = 1", 0.1, 100.0, [("c = 1", 0.7, 0.7)]),
]
FIG_APPROX = [("fig4", "Figs. 4-5: s = 0.5, c = 0.7/0.7", 0.5), ("fig8a", "Fig. 8: s = 0.1", 0.1),
              ("fig8b", "Fig. 8: s = 10", 10.0)]
KT_APPROX = (0.1, 1.0, 10.0)
SWEEP_KT = (0.1, 0.3, 1.0, 3.0, 10.0)
SWEEP_S = (0.1, 0.5, 1.0, 3.0, 10.0)


def stays_below(ls, err, tol):
    """The smallest l of the grid from which |err| <= tol for every larger l (inf if never)."""
    bad = np.nonzero(np.abs(err) > tol)[0]
    if len(bad) == 0:
        return float(ls[0])
    return float(ls[bad[-1] + 1]) if bad[-1] + 1 < len(ls) else math.inf


def compute(ls=L_GRID):
    """All curves: {figure: rows}, and the sweep rows."""
    curves = {}
    for name, _, kt, s, cs in FIG_EXP:
        rows = []
        for label, a, b in cs:
            lim = limit(a, b, kt, s)
            for l in ls:
                rows.append({"curve": label, "l": l, "eq7": exponential_part(l, a, b, kt, s),
                             "airlight": exponential_part(l, a, b, kt, s, airlight=True), "limit": lim})
        curves[name] = rows
    for name, _, s in FIG_APPROX:
        rows = []
        for kt in KT_APPROX:
            for l in ls:
                exact, approx = exact_and_approx(l, 0.7, 0.7, kt, s)
                rows.append({"curve": f"kt = {kt:g}", "l": l, "exact": exact, "approx": approx,
                             "rel_error": approx / exact - 1.0})
        curves[name] = rows
    sweep = []
    for kt in SWEEP_KT:
        for s in SWEEP_S:
            pairs = np.array([exact_and_approx(l, 0.7, 0.7, kt, s) for l in ls])
            err = pairs[:, 1] / pairs[:, 0] - 1.0
            sweep.append({"kt": kt, "s": s, "optical_thickness": kt * s,
                          "max_abs_rel_error": float(np.max(np.abs(err))),
                          "rel_error_at_l_0.01": float(np.interp(-2, np.log10(ls), err)),
                          "rel_error_at_l_0.1": float(np.interp(-1, np.log10(ls), err)),
                          "rel_error_at_l_1": float(np.interp(0, np.log10(ls), err)),
                          "l_below_10pct": stays_below(ls, err, 0.1), "l_below_1pct": stays_below(ls, err, 0.01)})
    return curves, sweep


def _write_csv(path: Path, rows):
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.12g}" if isinstance(v, float) else v) for k, v in r.items()})


def _plot(out: Path, curves):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    for name, title, kt, s, cs in FIG_EXP:
        fig, ax = plt.subplots(figsize=(6, 4))
        rows = curves[name]
        for label, _, _ in cs:
            r = [x for x in rows if x["curve"] == label]
            line, = ax.semilogx([x["l"] for x in r], [x["eq7"] for x in r], label=f"eq. 7, {label}")
            ax.axhline(r[0]["limit"], ls=":", color=line.get_color(), label=f"eq. 5 limit, {label}")
        r = [x for x in rows if x["curve"] == cs[-1][0]]  # Fig. 3: c = inf, where eq. 7 is the air-light
        ax.semilogx([x["l"] for x in r], [x["airlight"] for x in r], "k--", label=f"air-light (eq. 8), {cs[-1][0]}")
        ax.set(xlabel="light distance l", ylabel="∫ exp(-kt (x + k)) dx", title=title)
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(out / f"{name}.png", dpi=110)
        plt.close(fig)
        written.append(f"{name}.png")
    for name, title, s in FIG_APPROX:
        fig, (ax, ax2) = plt.subplots(1, 2, figsize=(10, 4))
        for kt in KT_APPROX:
            r = [x for x in curves[name] if x["curve"] == f"kt = {kt:g}"]
            ls = [x["l"] for x in r]
            line, = ax.loglog(ls, [x["exact"] for x in r], label=f"eq. 7, kt = {kt:g}")
            ax.loglog(ls, [x["approx"] for x in r], "--", color=line.get_color(), label=f"approx., kt = {kt:g}")
            ax2.semilogx(ls, [100 * x["rel_error"] for x in r], color=line.get_color(), label=f"kt = {kt:g}")
        ax.set(xlabel="light distance l", ylabel="radiance (I = 1, albedo 1)", title=title)
        ax2.set(xlabel="light distance l", ylabel="relative error of the approximation (%)", title=title)
        ax.legend(fontsize=7)
        ax2.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(out / f"{name}.png", dpi=110)
        plt.close(fig)
        written.append(f"{name}.png")
    return written


def _report(out: Path, curves, sweep, plots, ls):
    lines = ["# Single scattering in a homogeneous slab, measured", "",
             "The figures of the analytic note on single scattering in homogeneous slabs (its abstract opens "
             "\"An analytical approach toward visualization of participating media\"), recomputed, and the "
             "measured error of its separable point-light approximation.", "",
             "Generated by `python render.py seed002` (raytrace/experiments/seed002.py). Geometry: eye at cosine "
             "a = 0.7 to the normal, light at the mirror azimuth with cosine b (c = a / b); isotropic phase; "
             "for the approximation albedo 1 and a unit point light. All integrals adaptive to a relative 1e-11.", ""]
    lo, hi = float(ls[0]), float(ls[-1])
    lines += ["## The exponential part against the distant-light limit (Figs. 2, 3, 6, 7)", "",
              f"| figure | curve | eq. 7 at l = {lo:g} | at l = 1 | at l = {hi:g} | eq. 5 limit | air-light at l = {lo:g} "
              f"| at l = {hi:g} |", "|---|---|---|---|---|---|---|---|"]
    for name, _, _, _, cs in FIG_EXP:
        for label, _, _ in cs:
            r = [x for x in curves[name] if x["curve"] == label]
            one = min(r, key=lambda x: abs(math.log10(x["l"])))
            lines.append(f"| {name} | {label} | {r[0]['eq7']:.6g} | {one['eq7']:.6g} | {r[-1]['eq7']:.6g} | "
                         f"{r[0]['limit']:.6g} | {r[0]['airlight']:.6g} | {r[-1]['airlight']:.6g} |")
    lines += ["", "## Where the separable approximation fails (sweep over kt and s, c = 0.7/0.7)", "",
              f"Relative error approx / exact - 1 over l in [{lo:g}, {hi:g}] ({len(ls)} points, log-spaced); `l (10 %)`: the "
              "smallest l from which the error stays within 10 % (inf: never on the grid).", "",
              "| kt | s | kt s | max abs. error | error at l = 0.01 | at l = 0.1 | at l = 1 | l (10 %) | l (1 %) |",
              "|---|---|---|---|---|---|---|---|---|"]
    for r in sweep:
        lines.append(f"| {r['kt']:g} | {r['s']:g} | {r['optical_thickness']:g} | {r['max_abs_rel_error']:.3g} | "
                     f"{r['rel_error_at_l_0.01']:+.3g} | {r['rel_error_at_l_0.1']:+.3g} | {r['rel_error_at_l_1']:+.3g} | "
                     f"{r['l_below_10pct']:.3g} | {r['l_below_1pct']:.3g} |")
    lines += ["", "Files: " + ", ".join(["curves.csv", "sweep.csv"] + plots), ""]
    (out / "report.md").write_text("\n".join(lines))


def run(out: Path, plots: bool = True, ls=L_GRID):
    """Compute everything, then write curves.csv, sweep.csv, report.md and (with `plots`) the PNGs."""
    if plots:
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            raise UserError("seed002: the plots need matplotlib; pip install 'raytrace-media[plots]', or pass "
                            "--no-plots for the CSV files and the report alone") from None
    curves, sweep = compute(ls)
    out.mkdir(parents=True, exist_ok=True)
    rows = [{"figure": name, **r, **{k: "" for k in ("eq7", "airlight", "limit", "exact", "approx", "rel_error")
                                       if k not in r}} for name, rs in curves.items() for r in rs]
    keys = ["figure", "curve", "l", "eq7", "airlight", "limit", "exact", "approx", "rel_error"]
    _write_csv(out / "curves.csv", [{k: r[k] for k in keys} for r in rows])
    _write_csv(out / "sweep.csv", sweep)
    written = _plot(out, curves) if plots else []
    _report(out, curves, sweep, written, ls)
    return curves, sweep
