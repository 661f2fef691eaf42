"""The compile notice: one line when preparing a render (the kernels' compile) takes longer than
COMPILE_NOTICE seconds and one with the time when it is done; nothing when it is quick or when no
`notice` is given (library use); the command line says it above its progress bar (a terminal, no
--quiet). The slow compile is a fake: a sleep."""
from __future__ import annotations

import sys
import time
from pathlib import Path

import pytest

from raytrace import api
from raytrace.cli import main
from raytrace.rendering import renderer

from .conftest import box_room, to_toml

ROOT = Path(__file__).resolve().parents[1]
START = "compiling kernels (first use of this scene's kinds)..."


class Sleeping:
    """A compile that only sleeps `seconds`."""

    def __init__(self, seconds):
        self.seconds = seconds

    def work(self):
        time.sleep(self.seconds)
        return self.seconds


@pytest.fixture
def quick_notice(monkeypatch):
    monkeypatch.setattr(renderer, "COMPILE_NOTICE", 0.2)


def test_a_slow_compile_is_announced_then_timed(quick_notice):
    lines = []
    assert renderer.noticed(Sleeping(0.6).work, lines.append) == 0.6
    assert lines[0] == START and len(lines) == 2
    assert lines[1].startswith("compiled in ") and lines[1].endswith(" s")
    assert 0.6 <= float(lines[1].split()[2]) < 5.0


def test_a_quick_compile_says_nothing(quick_notice):
    lines = []
    renderer.noticed(Sleeping(0.0).work, lines.append)
    time.sleep(0.4)  # past the notice's time: the timer was cancelled
    assert lines == []


def test_without_a_hook_nothing_is_printed(quick_notice, capsys):
    renderer.noticed(Sleeping(0.4).work)
    assert capsys.readouterr() == ("", "")


def test_an_interrupted_compile_says_it_started_only(quick_notice):
    class Interrupted(Sleeping):
        def work(self):
            super().work()
            raise KeyboardInterrupt

    lines = []
    with pytest.raises(KeyboardInterrupt):
        renderer.noticed(Interrupted(0.4).work, lines.append)
    assert lines == [START]


@pytest.mark.parametrize("terminal, quiet", [(True, False), (True, True), (False, False)])
def test_the_command_line_prints_it_on_a_terminal_above_the_bar(tmp_path, quick_notice, monkeypatch, capsys,
                                                                  terminal, quiet):
    prepare = renderer.Threads.prepare

    def slow(self, prep, task):
        time.sleep(0.5)
        return prepare(self, prep, task)

    monkeypatch.setattr(renderer.Threads, "prepare", slow)
    monkeypatch.setattr(sys.stderr, "isatty", lambda: terminal)
    (tmp_path / "s.toml").write_text(to_toml(box_room()))
    assert main([str(tmp_path / "s.toml"), "--out", str(tmp_path / "a.exr")] + (["--quiet"] if quiet else [])) == 0
    lines = [line.rpartition("\r")[2] for line in capsys.readouterr().err.split("\n")]  # the bar's redraws cut
    said = [line for line in lines if "compil" in line]
    if terminal and not quiet:
        assert said[0] == START and said[1].startswith("compiled in ") and len(said) == 2
    else:
        assert said == []


def test_the_cubature_pilots_warm_up_is_announced_with_the_render_s(quick_notice, monkeypatch):
    """An area light's render compiles first in the cubature pilot's warm-up (before the tiles' own):
    one notice covers both."""
    warm_up = renderer.warm_up

    def slow(*args, **kwargs):
        time.sleep(0.3)  # the pilot's warm-up and the tiles': one notice, the time of both
        return warm_up(*args, **kwargs)

    monkeypatch.setattr(renderer, "warm_up", slow)
    lines = []
    api.render(str(ROOT / "tests/data/area_peers/occluded.toml"), "analytic", width=8, height=6, spp=1,
               threads=1, precision=1e-1, notice=lines.append)
    assert lines[0] == START and lines[1].startswith("compiled in ") and len(lines) == 2
    assert float(lines[1].split()[2]) >= 0.6
