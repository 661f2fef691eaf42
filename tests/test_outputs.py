"""Output safety of `render` and `Image.save`: every output path checked before rendering, the EXR and
the PNG written together (both or neither), Ctrl-C stops the tiles promptly and exits 130 with one
line, one summary line (--stats adds the method's statistics)."""
from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import raytrace
import raytrace.api
from raytrace.cli import main
from raytrace.options import RenderOptions
from raytrace.output import film
from raytrace.rendering import renderer

from .conftest import box_room, to_toml

REPO = Path(__file__).resolve().parents[1]


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


@pytest.mark.parametrize("png, message", [("s.toml/a.png", r"s\.toml is a file, not a folder"),
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
    # interrupted before the first pass finished: there is no checkpoint to name
    assert err == f"interrupted: {scene}; nothing was written\n", err
    assert sorted(os.listdir(tmp_path)) == ["s.toml"]


def test_one_summary_line_and_the_statistics_with_stats(tmp_path, scene, capsys):
    args = [scene, "--width", "4", "--height", "3", "--out", str(tmp_path / "a.exr"), "--method", "analytic"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1 and out.startswith("s: 4x3, ") and "method analytic" in out
    assert main(args + ["--stats"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) > 2 and lines[1].startswith("  ") and any("evaluations" in line for line in lines[1:])


def test_an_exception_in_the_consumer_stops_the_tiles(monkeypatch):
    """The progress callback raising closes the tile stream: the tiles running finish, no other
    starts (a pool shut down while something still holds its result iterator runs all 48)."""
    monkeypatch.setattr(renderer, "RAYS_PER_TILE", 16)  # 64 x 48 pixels: 24 tiles of 128 pixels
    started, tile = [], renderer.render_tile

    def slow_tile(prep, task, t):
        started.append(t)
        time.sleep(0.02)
        return tile(prep, task, t)

    def progress(done, total):
        raise RuntimeError("the consumer failed")

    monkeypatch.setattr(renderer, "render_tile", slow_tile)
    prep = renderer.prepare(raytrace.load(box_room()))
    threads = 2
    with pytest.raises(RuntimeError, match="the consumer failed"):
        renderer.render(prep, "analytic", {}, RenderOptions(width=64, height=48, threads=threads, progress=progress))
    assert 1 <= len(started) <= 1 + 2 * threads, len(started)  # the first tile, then those in flight


class ByteCounter:
    """A display server (--display-server) that only counts the bytes it receives: the blocks of
    rows that are final, after a CreateImage packet of a few bytes."""

    def __init__(self):
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.listener.settimeout(300)
        self.address = f"127.0.0.1:{self.listener.getsockname()[1]}"
        self.received = 0
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self):
        conn, _ = self.listener.accept()
        with conn, self.listener:
            while chunk := conn.recv(1 << 16):
                self.received += len(chunk)


def _interrupt(cmd, ready, limit=300.0):
    """Run `cmd`, send SIGINT once `ready()` holds; (return code, stderr, seconds from the signal to the exit)."""
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        start = time.monotonic()
        while not ready():
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() - start < limit, "the render never got under way"
            time.sleep(0.02)
        signalled = time.monotonic()
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
        return proc.returncode, err, time.monotonic() - signalled
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


# 2048 x 1024 at 4 spp on two threads: 512 tiles of about 0.1 s each, half a minute of rendering left
BIG = ["--width", "2048", "--height", "1024", "--spp", "4", "--threads", "2"]


def test_ctrl_c_stops_a_render_within_two_seconds(tmp_path, scene):
    server = ByteCounter()
    out = tmp_path / "a.exr"
    code, err, seconds = _interrupt([sys.executable, str(REPO / "render.py"), "render", scene, *BIG, "--quiet",
                                     "--method", "analytic", "--out", str(out), "--display-server", server.address],
                                    lambda: server.received > 4 * 2048 * 2 * 12)  # four tiles shown
    assert code == 130 and err == f"interrupted: {scene}; nothing was written\n", err
    assert seconds < 2.0, seconds
    assert sorted(os.listdir(tmp_path)) == ["s.toml"]


def test_ctrl_c_stops_a_progressive_render_within_two_seconds_with_the_resume_hint(tmp_path, scene):
    out = tmp_path / "a.exr"
    ckpt = Path(str(out) + ".ckpt.npz")
    code, err, seconds = _interrupt([sys.executable, str(REPO / "render.py"), "render", scene, "--quiet",
                                     "--width", "512", "--height", "512", "--threads", "2", "--method", "montecarlo",
                                     "--samples", "1", "--passes", "100", "--out", str(out)], ckpt.exists)
    assert code == 130, err
    assert err == (f"interrupted: {scene}; the checkpoint {ckpt} keeps the finished passes, run the same command "
                   "to resume\n")
    assert seconds < 2.0, seconds
    with np.load(ckpt) as z:
        assert 1 <= int(z["passes"]) < 100
    assert sorted(os.listdir(tmp_path)) == ["a.exr.ckpt.npz", "s.toml"]


def test_a_render_on_a_terminal_shows_its_bar_and_finishes(tmp_path, scene):
    """With stderr a terminal the progress bar is shown and the render completes (the bar, which has
    no truth value before its total is known, is tested against None)."""
    import fcntl
    import pty
    import struct
    import termios

    leader, follower = pty.openpty()
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 80, 0, 0))  # 80 columns for the bar
    out = tmp_path / "a.exr"
    proc = subprocess.Popen([sys.executable, str(REPO / "render.py"), "render", scene, "--width", "8", "--height", "6",
                             "--out", str(out)], stdout=subprocess.PIPE, stderr=follower, text=True)
    os.close(follower)
    shown = []

    def drain():
        while True:
            try:
                chunk = os.read(leader, 4096)
            except OSError:  # EIO: the child closed the terminal
                return
            if not chunk:
                return
            shown.append(chunk)

    reader = threading.Thread(target=drain, daemon=True)
    reader.start()
    stdout, _ = proc.communicate(timeout=600)
    reader.join(10)
    os.close(leader)
    terminal = b"".join(shown).decode(errors="replace")
    assert proc.returncode == 0, terminal
    assert stdout.startswith("s: 8x6, 1 spp") and out.is_file()
    assert "render" in terminal and "tile" in terminal, terminal  # tqdm's bar: "render: ... tile/s"


def test_concurrent_writers_of_a_pair_leave_one_writers_pair(tmp_path, monkeypatch):
    """Writer "slow" pauses between its two renames; writer "fast" writes the same pair meanwhile.
    Unlocked, the EXR would be fast's and the PNG slow's; under the lock fast waits, and its pair wins."""
    exr, png = tmp_path / "a.exr", tmp_path / "a.png"
    (tmp_path / ".a.exr.lock").write_text("")  # a crashed writer's: flock holds no lock for it
    replace, renamed = os.replace, threading.Event()

    def slow_replace(src, dst):
        replace(src, dst)
        if threading.current_thread().name == "slow" and str(dst).endswith(".exr"):
            renamed.set()
            time.sleep(0.3)

    def writer(name):
        def write(tmp):
            Path(tmp).write_text(name)
        film.write_together([(exr, write), (png, write)])

    monkeypatch.setattr(os, "replace", slow_replace)
    slow = threading.Thread(target=writer, args=("slow",), name="slow")
    slow.start()
    assert renamed.wait(10)
    fast = threading.Thread(target=writer, args=("fast",), name="fast")
    fast.start()
    slow.join(10)
    fast.join(10)
    assert (exr.read_text(), png.read_text()) == ("fast", "fast")
    assert sorted(os.listdir(tmp_path)) == ["a.exr", "a.png"]  # the lock file removed
