"""How long Ctrl-C takes to stop `render.py render SCENE`, per bundled scene and the built-in default.

    RAYTRACE_ASSETS=../shared/scenes python benchmarks/interrupt.py [SCENE ...] [--delay 1.0]

Each scene ("(default)": the built-in default scene) is rendered by the command line with its progress
bar on a pseudo-terminal; once the bar shows a tile finished (the kernels are compiled, the tiles
running) and `--delay` seconds more have passed, the process gets SIGINT and the seconds until it has
exited are printed, with its exit status (130 expected) and whether its output folder is still empty
(nothing half-written). A render that ends before the signal (or saves its image as it arrives) is
listed as finished first.
"""
import argparse
import fcntl
import os
import pty
import signal
import struct
import subprocess
import sys
import tempfile
import termios
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = "(default)"  # the built-in default scene: render.py render without a scene
SCENES = [DEFAULT] + sorted(p.stem for p in (ROOT / "scenes").glob("*.toml"))
STARTUP_LIMIT = 600.0  # seconds to wait for the first finished tile (loading and compiling included)


def _default_sigint():
    """In the render's process before it starts: SIGINT's default action, as a terminal's Ctrl-C finds it
    (a benchmark started in the background of a shell without job control inherits SIGINT ignored, and
    Python then keeps it ignored: the render would run on)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def interrupt(scene: str, delay: float) -> tuple[float, int, list[str]] | None:
    """(seconds from SIGINT to exit, exit status, files left in the output folder), or None when
    the render finished first."""
    out = Path(tempfile.mkdtemp(prefix="interrupt-"))
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 120, 0, 0))  # else 0 columns: no bar
    named = [] if scene == DEFAULT else [scene]
    proc = subprocess.Popen([sys.executable, str(ROOT / "render.py"), "render", *named, "--out", str(out / "a.exr")],
                            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=slave, cwd=ROOT,
                            preexec_fn=_default_sigint)
    os.close(slave)
    shown = threading.Event()

    def drain():  # read the bar so the child never blocks on it; a percentage: a tile has finished
        seen = b""
        while True:
            try:
                chunk = os.read(master, 4096)
            except OSError:
                return
            if not chunk:
                return
            if b"%|" in seen + chunk:  # the tail before it too: a mark split over two reads
                shown.set()
            seen = (seen + chunk)[-200:]

    threading.Thread(target=drain, daemon=True).start()
    deadline = time.monotonic() + STARTUP_LIMIT
    while not shown.is_set() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    if proc.poll() == 0:
        return None
    if not shown.is_set():
        raise SystemExit(f"{scene}: no tile finished (status {proc.poll()}) within {STARTUP_LIMIT:g} s")
    time.sleep(delay)
    if proc.poll() is not None:
        return None
    start = time.perf_counter()
    proc.send_signal(signal.SIGINT)
    status = proc.wait()
    seconds = time.perf_counter() - start
    os.close(master)
    left = sorted(os.listdir(out))
    if status != 130 and "a.exr" in left:  # the signal came after the render, while it saved or exited
        return None
    return seconds, status, left


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scenes", nargs="*", default=SCENES)
    p.add_argument("--delay", type=float, default=1.0, help="seconds after the first finished tile")
    args = p.parse_args()
    print(f"{'scene':<20} {'exit after SIGINT':>18}  status  files left")
    for scene in args.scenes:
        got = interrupt(scene, args.delay)
        if got is None:
            print(f"{scene:<20} {'finished first':>18}", flush=True)
            continue
        seconds, status, left = got
        print(f"{scene:<20} {seconds:>16.2f} s  {status:>6}  {', '.join(left) or 'none'}", flush=True)


if __name__ == "__main__":
    main()
