"""Output safety of `render` and `Image.save`: every output path checked before rendering, the EXR and
the PNG written together (both or neither), Ctrl-C exits 130 with one line, one summary line (--stats
adds the method's statistics)."""
from __future__ import annotations

import os

import pytest

import raytrace
import raytrace.api
from raytrace import film
from raytrace.cli import main

from .conftest import box_room, to_toml


@pytest.fixture
def scene(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(to_toml(box_room()))
    return str(path)


def _no_render(monkeypatch):
    def render(*args, **kwargs):
        raise AssertionError("rendered although an output path is unusable")
    monkeypatch.setattr(raytrace.api, "render", render)


def _failing_png(monkeypatch):
    def png_writer(rgb8):
        def write(tmp):
            with open(tmp, "wb") as f:
                f.write(b"partial")
            raise OSError(28, "No space left on device")
        return write
    monkeypatch.setattr(film, "png_writer", png_writer)


@pytest.mark.parametrize("png, message", [("nope/a.png", "folder .*nope does not exist"),
                                          ("a.jpg", r"--png .*a\.jpg: must end in \.png")])
def test_an_unusable_png_path_is_refused_before_rendering(tmp_path, scene, capsys, monkeypatch, png, message):
    _no_render(monkeypatch)
    assert main([scene, "--out", str(tmp_path / "a.exr"), "--png", str(tmp_path / png)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    import re
    assert re.search(message, err), err
    assert sorted(os.listdir(tmp_path)) == ["s.toml"]


def test_a_png_that_fails_to_write_leaves_no_exr(tmp_path, scene, capsys, monkeypatch):
    _failing_png(monkeypatch)
    assert main([scene, "--width", "4", "--height", "3", "--out", str(tmp_path / "a.exr"),
                 "--png", str(tmp_path / "a.png"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "a.png: cannot write (No space left on device)" in err
    assert sorted(os.listdir(tmp_path)) == ["s.toml"]  # no EXR, no temporary file


def test_an_older_pair_is_untouched_by_a_failed_save(tmp_path, monkeypatch):
    img = raytrace.render(box_room(), width=4, height=3, threads=1)
    exr, png = tmp_path / "a.exr", tmp_path / "a.png"
    img.save(exr, png)
    before = exr.read_bytes(), png.read_bytes()
    _failing_png(monkeypatch)
    with pytest.raises(raytrace.UserError, match="No space left"):
        raytrace.render(box_room(), width=5, height=3, threads=1).save(exr, png)
    assert (exr.read_bytes(), png.read_bytes()) == before and sorted(os.listdir(tmp_path)) == ["a.exr", "a.png"]


@pytest.mark.parametrize("progressive", [False, True])
def test_ctrl_c_exits_130_with_one_line(tmp_path, scene, capsys, monkeypatch, progressive):
    def render(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr(raytrace.api, "render", render)
    extra = ["--method", "montecarlo", "--passes", "4"] if progressive else []
    assert main([scene, "--out", str(tmp_path / "a.exr"), *extra]) == 130
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"interrupted: {scene}; ")
    assert ("a.exr.ckpt.npz keeps the finished passes, run the same command to resume" in err) == progressive
    assert sorted(os.listdir(tmp_path)) == ["s.toml"]


def test_one_summary_line_and_the_statistics_with_stats(tmp_path, scene, capsys):
    args = [scene, "--width", "4", "--height", "3", "--out", str(tmp_path / "a.exr"), "--method", "analytic"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1 and out.startswith("s: 4x3, ") and "method analytic" in out
    assert main(args + ["--stats"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) > 2 and lines[1].startswith("  ") and any("evaluations" in line for line in lines[1:])
