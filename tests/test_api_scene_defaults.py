"""A scene's [render] parameter that the chosen method does not read is ignored with one note
(api.SceneDefaultNote), whether the method is the table's own or another, and whether the key comes
from the file or from --set render.KEY (which edits the scene); only a parameter given explicitly
(an API keyword, a command-line flag) that the method does not read is refused."""
from __future__ import annotations

import warnings

import pytest

import raytrace
from raytrace.api import SceneDefaultNote
from raytrace.cli import main
from raytrace.output.film import read_exr

from .conftest import box_room, to_toml

OWN = {"method": "analytic", "rtol": 1e-4}  # quadrature's rtol beside the table's own method


def test_an_unread_parameter_of_the_tables_own_method_is_ignored_with_one_note():
    with pytest.warns(SceneDefaultNote, match=r"^scene: \[render\] rtol = 0\.0001: not read by method analytic; "
                                              r"ignored$") as caught:
        img = raytrace.render(box_room(render=OWN), width=4, height=3, threads=1)
    assert len(caught) == 1 and img.method == "analytic" and "rtol" not in img.params
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the same image as without the key, and no note without it
        plain = raytrace.render(box_room(render={"method": "analytic"}), width=4, height=3, threads=1)
    assert (img.array == plain.array).all()


def test_the_same_parameter_given_as_a_keyword_is_refused():
    with pytest.raises(raytrace.UserError, match=r"rtol=0\.0001 \(--rtol on the command line\): method analytic "
                                                 r"does not read this parameter; it is a parameter of quadrature"):
        raytrace.render(box_room(render={"method": "analytic"}), rtol=1e-4)


def test_the_cli_renders_a_scene_with_the_note(tmp_path, capsys):
    path, out = tmp_path / "s.toml", tmp_path / "a.exr"
    path.write_text(to_toml(box_room(render=OWN)))
    with pytest.warns(SceneDefaultNote, match=r"s\.toml: \[render\] rtol = 0\.0001: not read by method analytic"):
        assert main(["render", str(path), "--out", str(out), "--quiet"]) == 0
    assert out.is_file() and "rtol" not in read_exr(out)[1]["params"]


def test_set_render_key_edits_the_scene_so_it_is_a_note_too(tmp_path):
    out = tmp_path / "a.exr"
    note = r"box_room\.toml: \[render\] rtol = 0\.0001: not read by method analytic"
    with pytest.warns(SceneDefaultNote, match=note):
        assert main(["render", "box_room", "--set", "render.rtol=1e-4", "--width", "4", "--height", "3",
                     "--threads", "1", "--out", str(out), "--quiet"]) == 0
    assert out.is_file()


def test_the_flag_stays_an_error(tmp_path, capsys):
    out = tmp_path / "a.exr"
    assert main(["render", "box_room", "--rtol", "1e-4", "--width", "4", "--height", "3", "--out", str(out),
                 "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "(--rtol on the command line): method analytic does not read" in err
    assert "choose --method quadrature" in err and not out.exists()
