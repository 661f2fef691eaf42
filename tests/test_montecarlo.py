"""Monte Carlo: unbiasedness of each sampling mode, a per-pixel Z-test against `quadrature`
(variance from the render itself, Šidák-corrected, as Mitsuba's render tests do), and exact
checkpoint/resume."""
import math
from dataclasses import replace

import numpy as np
import pytest
from scipy import stats

from raytrace.media.phase import HG, ISOTROPIC, RAYLEIGH
from raytrace.methods import montecarlo as mc, quadrature as q
from raytrace.methods.geometry import POINT_ROW
from raytrace.options import RenderOptions
from raytrace.rendering import progressive
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text

from .conftest import box_room, to_toml

GEOMETRIES = [(2.0, 0.5, 6.0, 0.08, ISOTROPIC, 0.0), (2.0, 0.05, math.inf, 0.3, RAYLEIGH, 0.0),
              (3.0, 1.0, 4.0, 1.0, HG, 0.6), (-1.0, 0.3, 5.0, 0.5, HG, -0.4)]


@pytest.mark.parametrize("mode", ["equiangular", "freepath", "mis"])
@pytest.mark.parametrize("xh,h,ell,kt,code,g", GEOMETRIES)
def test_each_sampling_mode_is_unbiased(mode, xh, h, ell, kt, code, g):
    ks = 0.7 * kt
    ref = q.airlight_one(xh, h, ell, kt, ks, code, g, POINT_ROW, 1e-12, q.N10, q.W10, q.N20, q.W20, np.zeros(3))
    n = 20000
    est = np.array([mc.estimate(xh, h, ell, kt, ks, code, g, POINT_ROW, mc.MODES[mode], 1, np.uint64(k), 0, np.uint64(7))[0]
                    for k in range(n)])
    se = est.std(ddof=1) / math.sqrt(n)
    assert abs(est.mean() - ref) < 4.5 * se, (est.mean(), ref, se)


def test_per_ray_variance_matches_the_spread_of_estimates():
    args = (2.0, 0.5, 6.0, 0.3, 0.2, ISOTROPIC, 0.0, POINT_ROW, mc.EQUIANGULAR, 8)
    res = np.array([mc.estimate(*args, np.uint64(k), 0, np.uint64(3)) for k in range(4000)])
    assert res[:, 1].mean() == pytest.approx(res[:, 0].var(ddof=1), rel=0.1)


def scene(**kw):
    s = box_room(camera={"position": [0.3, 0.2, 3.0], "look_at": [0.0, 0.0, -1.0], "fov": 70.0, "width": 16,
                         "height": 12, "spp": 4}, **kw)
    return prepare(scene_from_text(to_toml(s), "test"))


@pytest.mark.parametrize("mode", ["equiangular", "mis"])
def test_z_test_against_quadrature(mode):
    prep = scene(medium={"sigma_a": 0.05, "sigma_s": [0.2, 0.3, 0.4], "phase": {"type": "hg", "g": 0.5}})
    ref = render(prep, "quadrature", {"rtol": 1e-12}, RenderOptions(threads=1)).image
    res = render(prep, "montecarlo", {"samples": 16, "sampling": mode}, RenderOptions(seed=11, threads=1))
    var = np.maximum(res.variance, (1e-4 * ref) ** 2)  # variance floor: a relative s.d. of 1e-4
    z = (res.image - ref) / np.sqrt(var)
    n = z.size
    alpha = 0.01
    per_test = 1.0 - (1.0 - alpha) ** (1.0 / n)  # Šidák correction
    z_crit = stats.norm.isf(per_test / 2)
    pass_rate = np.mean(np.abs(z) < z_crit)
    assert pass_rate >= 0.9975, (pass_rate, np.abs(z).max())
    # and the errors look standard normal overall
    assert abs(z.mean()) < 4.0 / math.sqrt(n) + 0.05 and 0.7 < z.std() < 1.3


def test_result_does_not_depend_on_thread_count():
    prep = scene()
    a = render(prep, "montecarlo", {}, RenderOptions(seed=5, threads=1)).image
    b = render(prep, "montecarlo", {}, RenderOptions(seed=5, threads=2)).image
    assert np.array_equal(a, b)


def test_resumed_render_equals_uninterrupted(tmp_path, monkeypatch):
    prep = scene()
    once = RenderOptions(seed=3, passes=3, threads=1)
    full = progressive.render_progressive(prep, "montecarlo", {}, once)
    ckpt = tmp_path / "r.ckpt.npz"
    # interrupted during the second pass: the checkpoint keeps the first one
    real_render = progressive.render
    calls = {"n": 0}

    def flaky(*a, **k):
        calls["n"] += 1
        if calls["n"] == 2:
            raise KeyboardInterrupt
        return real_render(*a, **k)

    monkeypatch.setattr(progressive, "render", flaky)
    with pytest.raises(KeyboardInterrupt):
        progressive.render_progressive(prep, "montecarlo", {}, replace(once, checkpoint=ckpt))
    monkeypatch.setattr(progressive, "render", real_render)
    with np.load(ckpt) as z:
        assert int(z["passes"]) == 1
    resumed = progressive.render_progressive(prep, "montecarlo", {}, replace(once, checkpoint=ckpt))
    assert resumed.passes == 3
    assert np.array_equal(resumed.image, full.image)
    assert np.array_equal(resumed.variance, full.variance)
    # more passes of the same render continue from the checkpoint; a different seed is refused
    more = progressive.render_progressive(prep, "montecarlo", {}, replace(once, passes=4, checkpoint=ckpt))
    assert more.passes == 4
    from raytrace.errors import UserError
    with pytest.raises(UserError, match="different render"):
        progressive.render_progressive(prep, "montecarlo", {}, replace(once, seed=4, passes=4, checkpoint=ckpt))


def test_error_falls_as_one_over_sqrt_n():
    prep = scene()
    ref = render(prep, "quadrature", {"rtol": 1e-12}, RenderOptions(threads=1)).image
    errs = []
    ns = [1, 4, 16, 64]
    for n in ns:
        img = render(prep, "montecarlo", {"samples": n}, RenderOptions(seed=2, threads=1)).image
        errs.append(np.sqrt(np.mean((img - ref) ** 2)))
    slope = np.polyfit(np.log(ns), np.log(errs), 1)[0]
    assert -0.62 < slope < -0.38, (slope, errs)


def test_target_error_and_time_budget_stop_the_passes(tmp_path):
    prep = scene()
    base = RenderOptions(seed=1, threads=1)
    one = progressive.render_progressive(prep, "montecarlo", {"samples": 2}, replace(base, passes=1))
    target = 0.5 * one.stats["estimated mean relative error"]
    res = progressive.render_progressive(prep, "montecarlo", {"samples": 2}, replace(base, target_error=target))
    assert res.stats["estimated mean relative error"] <= target
    assert 2 < res.passes < 10  # about four passes halve the error
    timed = progressive.render_progressive(prep, "montecarlo", {"samples": 2}, replace(base, time_budget=1e-9))
    assert timed.passes == 1  # the budget is checked after each pass


def test_cli_writes_variance_channels_and_refuses_progressive_deterministic_methods(tmp_path, capsys):
    import OpenEXR

    from raytrace.cli import main

    path = tmp_path / "s.toml"
    path.write_text(to_toml(box_room()))
    out = tmp_path / "mc.exr"
    assert main(["render", str(path), "--method", "montecarlo", "--passes", "2", "--out", str(out), "--quiet"]) == 0
    with OpenEXR.File(str(out), separate_channels=True) as f:
        assert {"R", "G", "B", "variance.R", "variance.G", "variance.B"} <= set(f.channels())
    assert (tmp_path / "mc.exr.ckpt.npz").is_file()
    assert main(["render", str(path), "--method", "analytic", "--passes", "2", "--out", str(tmp_path / "a.exr")]) == 2
    assert "stochastic" in capsys.readouterr().err


FOG = {"type": "height_fog", "sigma_a": 0.05, "sigma_s": 0.15, "up": [0.0, 1.0, 0.0], "scale_height": 2.0}
SPOT = {"type": "spot", "position": [0.5, 1.0, -1.0], "look_at": [0.0, -2.0, -1.0], "intensity": 10.0,
        "cone_angle": 40.0, "falloff_start": 30.0}
WATER = {"sigma_a": 0.2, "sigma_s": 0.3, "ior": 1.0}
CUBE = {"primitive": "box", "min": [-0.5, -0.5, -2.0], "max": [0.5, 0.5, -1.0]}


@pytest.mark.parametrize("a,b", [
    (box_room(medium=FOG), box_room(medium={**FOG, "scale_height": 3.0})),
    (box_room(medium=FOG), box_room(medium={**FOG, "profile": "linear"})),
    (box_room(light=[SPOT]), box_room(light=[{**SPOT, "falloff_start": 20.0}])),
    (box_room(medium={"sigma_a": 0.05, "sigma_s": 0.15, "phase": {"type": "hg", "g": 0.5}}),
     box_room(medium={"sigma_a": 0.05, "sigma_s": 0.15, "phase": {"type": "hg", "g": 0.6}})),
    (box_room(shape=box_room()["shape"] + [{**CUBE, "interior": WATER}]),
     box_room(shape=box_room()["shape"] + [{**CUBE, "interior": {**WATER, "sigma_s": 0.4}}])),
])
def test_a_checkpoint_knows_every_key_of_the_scene(a, b):
    """Scenes that differ in one medium, light or interior key get different fingerprints (a fog's
    scale height was once ignored, so a checkpoint of another fog would have been resumed)."""
    fp = [progressive.fingerprint(prepare(scene_from_text(to_toml(s), "s.toml")), "montecarlo", {}, 1) for s in (a, a, b)]
    assert fp[0] == fp[1] != fp[2]
