"""The seed002 experiment (raytrace/experiments/seed002.py): its numbers against twins written in the
seed's own variables (h(x)^2 = x^2 + l^2 + 2 x l g, k(x) of eq. 6), its limits, and the command."""
import csv
import math
import sys

import numpy as np
import pytest
from scipy import integrate

from raytrace.cli import main
from raytrace.experiments import seed002


def seed_g(a, b):
    """g = omega . omega_l for the mirror azimuth."""
    return a * b - math.sqrt(1 - a * a) * math.sqrt(1 - b * b)


def twin_exponential(l, a, b, kt, s):
    """The seed's eq. 7 exponential part, in its variables (eq. 6 for k)."""
    g = seed_g(a, b)

    def f(x):
        h = math.sqrt(x * x + l * l + 2 * x * l * g)
        return math.exp(-kt * (x + x * a * h / (l * b + x * a)))
    return integrate.quad(f, 0.0, s, epsabs=0.0, epsrel=1e-13, limit=400)[0]


def twin_eq7(l, a, b, kt, s):
    """Eq. 7 with the point light's falloff I0 / h^2, isotropic, albedo 1 (sigma_s = sigma_t)."""
    g = seed_g(a, b)

    def f(x):
        h2 = x * x + l * l + 2 * x * l * g
        return kt / (4 * math.pi) * math.exp(-kt * (x + x * a * math.sqrt(h2) / (l * b + x * a))) / h2
    return integrate.quad(f, 0.0, s, epsabs=0.0, epsrel=1e-13, limit=400)[0]


@pytest.mark.parametrize("l,a,b,kt,s", [(0.01, 0.7, 0.7, 1.0, 10.0), (1.0, 0.7, 0.35, 1.0, 10.0),
                                        (30.0, 0.7, 0.07, 0.1, 100.0), (0.2, 0.7, 0.7, 10.0, 0.5)])
def test_curves_against_the_seed_variables(l, a, b, kt, s):
    assert seed002.exponential_part(l, a, b, kt, s) == pytest.approx(twin_exponential(l, a, b, kt, s), rel=1e-9)
    exact, approx = seed002.exact_and_approx(l, a, b, kt, s)
    assert exact == pytest.approx(twin_eq7(l, a, b, kt, s), rel=1e-9)
    # the seed's approximation, from its sec. 4.2 formula
    g, c = seed_g(a, b), a / b
    r = math.sqrt(1 - g * g)
    inv = (math.atan((s + l * g) / (l * r)) - math.atan(g / r)) / (l * r)
    assert approx == pytest.approx(kt / (4 * math.pi) * (1 - math.exp(-kt * (1 + c) * s)) / (kt * (1 + c) * s) * inv,
                                   rel=1e-12)


def test_limits_the_seed_states():
    """Coincidence (a = b = 1): eq. 7 is eq. 5's limit for every l; far lights: eq. 7 -> the limit and
    the air-light -> 0; c = inf: eq. 7 is the air-light (eq. 8)."""
    for l in (0.01, 1.0, 100.0):
        assert seed002.exponential_part(l, 1.0, 1.0, 1.0, 10.0) == pytest.approx(seed002.limit(1.0, 1.0, 1.0, 10.0),
                                                                                rel=1e-10)
        assert seed002.exponential_part(l, 0.7, 0.0, 1.0, 10.0) == pytest.approx(
            seed002.exponential_part(l, 0.7, 0.0, 1.0, 10.0, airlight=True), rel=1e-12)
    far = seed002.exponential_part(1e5, 0.7, 0.35, 1.0, 10.0)
    assert far == pytest.approx(seed002.limit(0.7, 0.35, 1.0, 10.0), rel=1e-3)
    assert seed002.exponential_part(1e3, 0.7, 0.35, 1.0, 10.0, airlight=True) < 1e-300


def test_command_writes_the_numbers_without_plots(tmp_path):
    out = tmp_path / "s"
    assert main(["seed002", "--quick", "--no-plots", "--out", str(out)]) == 0
    assert {p.name for p in out.iterdir()} == {"curves.csv", "sweep.csv", "report.md"}
    rows = list(csv.DictReader(open(out / "sweep.csv")))
    assert len(rows) == len(seed002.SWEEP_KT) * len(seed002.SWEEP_S)
    thin = next(r for r in rows if float(r["kt"]) == 0.1 and float(r["s"]) == 0.1)
    thick = next(r for r in rows if float(r["kt"]) == 10.0 and float(r["s"]) == 10.0)
    assert float(thin["max_abs_rel_error"]) < 0.01 < 0.9 < float(thick["max_abs_rel_error"])
    # a row of the curves recomputed by the twin
    row = next(r for r in csv.DictReader(open(out / "curves.csv")) if r["figure"] == "fig4" and r["curve"] == "kt = 1"
               and float(r["l"]) == pytest.approx(1.0))
    assert float(row["exact"]) == pytest.approx(twin_eq7(1.0, 0.7, 0.7, 1.0, 0.5), rel=1e-9)
    assert "Where the separable approximation fails" in (out / "report.md").read_text()


def test_plots_without_matplotlib_fail_in_one_line(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    out = tmp_path / "s"
    assert main(["seed002", "--quick", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--no-plots" in err and "raytrace-media[plots]" in err
    assert not out.exists() or not any(out.iterdir())


def test_plots_are_written(tmp_path):
    pytest.importorskip("matplotlib")
    seed002.run(tmp_path, plots=True, ls=np.logspace(-2, 2, 5))
    assert {"fig2.png", "fig3.png", "fig4.png", "fig8b.png"} <= {p.name for p in tmp_path.iterdir()}
