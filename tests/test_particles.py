"""Seed 003's particle layer ([medium.particles], raytrace/media/particles.py): zero density is the
exact air-light bit for bit, images do not depend on the thread count, the density term follows
the seed's normal CDF (eq. 2) over the cells, and bad input is one line with exit status 2."""
from __future__ import annotations

import copy
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import integrate, stats

import raytrace
from raytrace.cli import main
from raytrace.media.particles import _cell_density

REPO = Path(__file__).resolve().parents[1]

ROOM = {"camera": {"position": [-2.0, 1.2, 2.5], "look_at": [0.3, 1.0, -0.5], "width": 40, "height": 30, "spp": 2},
        "shape": [{"primitive": "box", "min": [-3.0, 0.0, -2.0], "max": [3.0, 3.0, 3.0], "reflectance": 0.3},
                  {"primitive": "box", "min": [0.0, 0.0, -1.0], "max": [0.8, 0.6, -0.2]}],
        "light": [{"type": "spot", "position": [1.5, 2.9, -1.5], "look_at": [0.4, 0.0, -0.6], "intensity": 40.0,
                   "cone_angle": 20.0, "falloff_start": 15.0},
                  {"position": [-2.0, 2.5, 2.0], "intensity": 2.0}],
        "medium": {"sigma_a": 0.02, "sigma_s": [0.1, 0.12, 0.15]},
        "render": {"volumetric_shadows": True}}


def _room(**particles):
    room = copy.deepcopy(ROOM)
    room["medium"]["particles"] = {"cell": 0.05, "step": 0.1, "seed": 7, **particles}
    return room


@pytest.mark.parametrize("method", ["analytic", "quadrature"])
def test_zero_density_is_the_exact_airlight_bit_for_bit(method):
    exact = raytrace.render(ROOM, method=method).array
    zero = raytrace.render(_room(density=0.0), method=method).array
    assert np.array_equal(zero, exact)
    dusty = raytrace.render(_room(), method=method).array  # and the layer does act
    assert np.all(dusty >= exact) and (dusty - exact).max() > 1e-3 * exact.max()


def test_images_do_not_depend_on_the_thread_count():
    one = raytrace.render(_room(), threads=1).array
    two = raytrace.render(_room(), threads=2).array
    assert np.array_equal(one, two)
    other = raytrace.render(_room(seed=8), threads=2).array  # the seed does pick other particles
    assert not np.array_equal(one, other)


@pytest.mark.parametrize("density, mu, sigma", [(1.0, 0.5, 0.5), (0.7, 0.9, 0.05), (1.0, 0.2, 0.3)])
def test_the_density_term_follows_the_normal_cdf(density, mu, sigma):
    """Over many cells, d = density * cdf(x | mu, sigma) with x uniform on [0, 1): its mean is
    density * int_0^1 Phi((x - mu) / sigma) dx and P(d <= y) = clip(mu + sigma Phi^-1(y / density), 0, 1)."""
    n, cell = 40_000, 0.1
    idx = np.arange(n)
    pts = (np.stack([idx % 40, (idx // 40) % 40, idx // 1600], axis=1) - 20 + 0.5) * cell
    d = np.array([_cell_density(x, y, z, cell, density, mu, sigma, 11) for x, y, z in pts])
    mean, _ = integrate.quad(lambda x: stats.norm.cdf(x, mu, sigma), 0.0, 1.0, epsabs=1e-12)
    spread = np.std(d) / math.sqrt(n)
    assert abs(d.mean() - density * mean) < 4.0 * spread + 1e-15
    ks = stats.kstest(d, lambda y: np.clip(mu + sigma * stats.norm.ppf(np.clip(y / density, 0, 1)), 0.0, 1.0))
    assert ks.pvalue > 1e-3
    # the same cell always has the same density, wherever in the cell it is asked
    assert _cell_density(*(pts[5] + 0.4 * cell), cell, density, mu, sigma, 11) == d[5]


SCENE = """\
[camera]
position = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
width = 4
height = 3

[[light]]
type = "spot"
position = [0.0, 2.0, 0.0]
look_at = [0.0, 0.0, 0.0]
intensity = 10.0

[medium]
sigma_s = 0.1

[medium.particles]
"""


@pytest.mark.parametrize("extra, key, fix", [
    ("dencity = 0.5", "medium.particles.dencity", 'did you mean "density"?'),
    ("sigma = 0.0", "medium.particles.sigma", "greater than 0"),
    ("density = 1.5", "medium.particles.density", "[0, 1]"),
    ("step = -0.1", "medium.particles.step", "greater than 0"),
    ("beta = 0.01\nc2 = 0.03", "medium.particles.beta", "either beta or c1 and c2"),
    ("seed = 1.5", "medium.particles.seed", "whole number"),
    ("reflectance = 2", "medium.particles.reflectance", "[0, 1]"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, extra, key, fix):
    scene = tmp_path / "bad.toml"
    scene.write_text(SCENE + extra + "\n")
    out = tmp_path / "img.exr"
    assert main(["render", str(scene), "--out", str(out), "--quiet"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and str(scene) in lines[0] and key in lines[0] and fix in lines[0], lines
    assert not out.exists()


def test_bad_input_from_the_command_line_has_no_traceback(tmp_path):
    scene = tmp_path / "bad.toml"
    scene.write_text(SCENE + "offset = -1\n")
    proc = subprocess.run([sys.executable, str(REPO / "render.py"), "render", str(scene), "--out",
                           str(tmp_path / "img.exr"), "--quiet"], capture_output=True, text=True, cwd=REPO)
    assert proc.returncode == 2 and "medium.particles.offset" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and not (tmp_path / "img.exr").exists()


def test_particles_need_a_scattering_medium():
    room = _room()
    room["medium"]["sigma_s"] = 0.0
    with pytest.raises(raytrace.UserError, match=r"medium\.particles: .*sigma_s > 0"):
        raytrace.render(room)
