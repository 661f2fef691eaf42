"""The thread pool (renderer.Threads): Ctrl-C and a tile's error return at once, without waiting
for the tiles in flight, and nothing is written."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import threading
import time

import numpy as np
import pytest

import raytrace
from raytrace.options import RenderOptions
from raytrace.rendering import renderer

from .conftest import ROOT, box_room, to_toml

SLOW = 120.0  # seconds a stuck tile sleeps: far longer than any exit the tests allow


def test_ctrl_c_exits_without_waiting_for_a_long_tile(tmp_path):
    """The command line gets SIGINT while a tile runs for minutes: it exits with 130 within seconds
    (a pool that joined its threads would wait SLOW), with nothing on disk."""
    (tmp_path / "s.toml").write_text(to_toml(box_room()))
    child = textwrap.dedent(f"""
        import sys, time
        from raytrace.rendering import renderer
        from raytrace.cli import run

        def stuck(prep, task, tile):
            print("started", flush=True)
            time.sleep({SLOW})

        renderer.render_tile = stuck
        sys.argv[1:] = [{str(tmp_path / 's.toml')!r}, "--out", {str(tmp_path / 'out' / 'a.exr')!r}, "--threads", "2"]
        sys.exit(run())
    """)
    proc = subprocess.Popen([sys.executable, "-c", child], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert proc.stdout.readline() == "started\n"
    start = time.perf_counter()
    proc.send_signal(signal.SIGINT)
    status = proc.wait(timeout=SLOW / 2)
    seconds = time.perf_counter() - start
    assert status == 130, proc.stderr.read()
    assert seconds < 10.0, seconds
    assert "interrupted" in proc.stderr.read()
    assert sorted(os.listdir(tmp_path)) == ["s.toml"]


def test_a_tiles_error_is_raised_without_waiting_for_the_others(monkeypatch):
    tile = renderer.render_tile

    def one_fails_one_sticks(prep, task, t):
        if t.pixels.start == 0:
            time.sleep(SLOW)
        if t.pixels.start == 1:
            raise ValueError("tile 1 failed")
        return tile(prep, task, t)

    prep = renderer.prepare(raytrace.load(box_room()))
    monkeypatch.setattr(renderer, "render_tile", one_fails_one_sticks)
    start = time.perf_counter()
    with pytest.raises(ValueError, match="tile 1 failed"):
        renderer.render(prep, "analytic", {}, RenderOptions(width=64, height=32, threads=2))  # 16 tiles
    assert time.perf_counter() - start < SLOW / 4


def test_more_threads_than_tiles():
    prep = renderer.prepare(raytrace.load(box_room()))
    one = renderer.render(prep, "analytic", {}, RenderOptions(width=2, height=1, threads=1))
    many = renderer.render(prep, "analytic", {}, RenderOptions(width=2, height=1, threads=7))
    assert one.image.tobytes() == many.image.tobytes()


def test_ctrl_c_inside_a_kernel_call_is_an_interrupt(monkeypatch, capsys):
    """numba turns Ctrl-C that arrives while a cached kernel's constants are unpickled into a
    SystemError caused by the KeyboardInterrupt: the command line still exits 130 ("interrupted");
    any other SystemError is raised."""
    from raytrace import cli

    def interrupted_in_numba(args):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as exc:
            raise SystemError("<function _numba_unpickle> returned a result with an exception set") from exc

    monkeypatch.setattr(cli, "cmd_describe", interrupted_in_numba)
    assert cli.main(["describe", "box_room"]) == 130
    assert "interrupted" in capsys.readouterr().err

    def broken(args):
        raise SystemError("not an interrupt")

    monkeypatch.setattr(cli, "cmd_describe", broken)
    with pytest.raises(SystemError, match="not an interrupt"):
        cli.main(["describe", "box_room"])


@pytest.mark.parametrize("pixels, samples", [(slice(3, 37, 5), slice(0, 4)), (slice(0, 40), slice(2, 3)),
                                             (slice(7, 8, 128), slice(1, 4)), (slice(5, 5, 3), slice(0, 2))])
def test_tile_keys_are_numpys(pixels, samples):
    """renderer._tile_keys (a tile's pixel rows, columns and sample keys in one GIL-free pass) against the NumPy
    expressions it replaced, for a block away from the image's corner of an image wide enough that the keys
    pass 2^32; a slice without a step and an empty tile."""
    x0, x1, row, width, spp = 3, 11, 5, 1 << 30, 4
    q = np.arange(pixels.stop)[pixels]
    ys, xs = row + q // (x1 - x0), x0 + q % (x1 - x0)
    keys = ((ys * width + xs)[:, None].astype(np.uint64) * np.uint64(spp)
            + np.arange(samples.start, samples.stop, dtype=np.uint64)).ravel()
    r = range(pixels.stop)[pixels]
    got = (np.empty(len(r), np.int64), np.empty(len(r), np.int64),
           np.empty(len(r) * (samples.stop - samples.start), np.uint64))
    renderer._tile_keys(r.start, r.step, row, x0, x1 - x0, width, spp, samples.start, *got)
    for a, b in zip(got, (ys, xs, keys)):
        assert a.dtype == b.dtype and np.array_equal(a, b)


def test_a_tile_of_whole_rows_is_the_renders():
    """A tile whose pixels are a slice without a step (benchmarks/scaling.py's rows) gives the rendered
    row's sums."""
    prep, options = renderer.prepare(raytrace.load(box_room())), RenderOptions(width=8, height=6, spp=2, threads=1)
    image = renderer.render(prep, "analytic", {}, options).image
    params = renderer.check(prep, "analytic", {}, options, "test")
    task = renderer.Task("analytic", params, options.seed, options.shadows, (0, 0, 8, 6))
    rad = renderer.render_tile(prep, task, renderer.Tile(slice(2, 3), slice(0, 8), slice(0, 2)))[0]
    assert np.array_equal(rad / 2, image[2])


def test_a_memo_built_inside_another_memo_does_not_wait_for_itself():
    """Prepared.memo builds under the scene's lock; a build that memos its parts (the sun's faces memo the
    shape's planes) must not deadlock on it (fails with a plain Lock after 10 s)."""
    prep = renderer.prepare(raytrace.load(box_room()))
    out = {}
    nested = threading.Thread(target=lambda: out.update(v=prep.memo("outer", lambda: prep.memo("inner", lambda: 7))),
                              daemon=True)  # a deadlocked thread must not keep pytest alive
    nested.start()
    nested.join(timeout=10)
    assert not nested.is_alive() and out["v"] == 7 and prep.memo("inner", lambda: 0) == 7
