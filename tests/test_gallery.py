"""`render.py gallery`: each named bundled scene as its `render` preview at --width with the camera's
aspect, a scene whose mesh is missing skipped with one note, bad input refused before any render."""
from __future__ import annotations

import numpy as np
import pytest
from PIL import Image as Picture

import raytrace
from raytrace.cli import main
from raytrace.gallery import GalleryNote
from raytrace.output import film


def test_gallery_writes_the_preview_and_skips_a_scene_without_its_mesh(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("RAYTRACE_ASSETS", str(tmp_path / "no_meshes_here"))
    out = tmp_path / "gallery"  # created by the command
    with pytest.warns(GalleryNote) as caught:  # one `warning:` line on the command line
        assert main(["gallery", "--out", str(out), "--width", "24", "--threads", "1", "ocean", "sibenik"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert sorted(p.name for p in out.iterdir()) == ["ocean.png"]
    skipped = [str(w.message) for w in caught if str(w.message).startswith("gallery: skipped sibenik: ")]
    assert len(skipped) == 1 and "sibenik/sibenik.obj" in skipped[0] and "RAYTRACE_ASSETS" in skipped[0]
    assert not any(": note: " in line for line in lines)  # the water (a medium inside a shape) takes shadows
    assert any(line.startswith("gallery: ocean: 24x15, method analytic, 1 spp, ") for line in lines)  # 320x200
    assert lines[-1] == f"wrote 1 image to {out}"
    with Picture.open(out / "ocean.png") as picture:
        written = np.asarray(picture.convert("RGB"))
    expected = film.tonemap(raytrace.render("ocean", width=24, height=15, threads=1).array)
    np.testing.assert_array_equal(written, expected)  # exactly the preview `render --png` writes


def test_a_bad_out_is_one_line_and_exit_2(tmp_path, capsys):
    taken = tmp_path / "a_file"
    taken.write_text("")
    assert main(["gallery", "--out", str(taken), "--width", "24", "box_room"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err == [f"error: --out {taken}: exists and is not a folder; choose a folder path"]


def test_every_name_is_checked_before_the_first_render(tmp_path, capsys):
    out = tmp_path / "gallery"
    assert main(["gallery", "--out", str(out), "--width", "24", "box_room", "box_rom"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("error: gallery: box_rom: not a bundled scene; did you mean \"box_room\"?")
    assert not out.exists() or not any(out.iterdir())
