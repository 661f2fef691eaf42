"""Ctrl-C during a progressive render: the exit line names the checkpoint (the resume hint) only
when one is on disk, i.e. once a pass of this run or of an earlier one has written it."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

import raytrace.rendering.progressive
from raytrace.cli import main

from .conftest import box_room, to_toml

RENDER = raytrace.rendering.progressive.render  # one pass, unpatched


def _interrupt_pass(monkeypatch, after: int):
    """Let `after` passes render, then raise KeyboardInterrupt in the next one, as Ctrl-C does."""
    calls = []

    def interrupted(*args, **kwargs):
        calls.append(1)
        if len(calls) > after:
            raise KeyboardInterrupt
        return RENDER(*args, **kwargs)
    monkeypatch.setattr(raytrace.rendering.progressive, "render", interrupted)


@pytest.fixture
def argv(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(to_toml(box_room()))
    return [str(path), "--method", "montecarlo", "--samples", "1", "--passes", "3", "--width", "4", "--height", "3",
            "--threads", "1", "--out", str(tmp_path / "a.exr"), "--quiet"]


def test_before_the_first_pass_nothing_is_named(tmp_path, argv, capsys, monkeypatch):
    _interrupt_pass(monkeypatch, after=0)
    assert main(argv) == 130
    assert capsys.readouterr().err == f"interrupted: {argv[0]}; nothing was written\n"
    assert sorted(os.listdir(tmp_path)) == ["s.toml"]


def test_after_a_pass_the_checkpoint_written_is_named(tmp_path, argv, capsys, monkeypatch):
    _interrupt_pass(monkeypatch, after=1)
    assert main(argv) == 130
    ckpt = Path(str(tmp_path / "a.exr") + ".ckpt.npz")
    assert capsys.readouterr().err == (f"interrupted: {argv[0]}; the checkpoint {ckpt} keeps the finished passes, "
                                       "run the same command to resume\n")
    assert sorted(os.listdir(tmp_path)) == ["a.exr.ckpt.npz", "s.toml"]
    # resumed and interrupted again before its next pass: the earlier checkpoint is still there to name
    _interrupt_pass(monkeypatch, after=0)
    assert main(argv) == 130
    assert "the checkpoint" in capsys.readouterr().err and ckpt.is_file()


def test_a_checkpoint_folder_is_created_by_the_first_save_only(tmp_path, argv, capsys, monkeypatch):
    ckpt = tmp_path / "new" / "c.ckpt.npz"
    _interrupt_pass(monkeypatch, after=0)
    assert main(argv + ["--checkpoint", str(ckpt)]) == 130
    assert "nothing was written" in capsys.readouterr().err and not ckpt.parent.exists()
    _interrupt_pass(monkeypatch, after=1)
    assert main(argv + ["--checkpoint", str(ckpt)]) == 130
    assert f"the checkpoint {ckpt} keeps" in capsys.readouterr().err and ckpt.is_file()
