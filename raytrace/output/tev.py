"""Live display in the tev image viewer (`--display-server HOST:PORT`), as pbrt-v4's flag does.

tev (github.com/Tom94/tev, include/tev/Ipc.h and src/Ipc.cpp) listens on TCP for packets; each is
its total length in bytes (uint32, the four length bytes included), a type byte and fields in
little-endian order: booleans as one byte, strings UTF-8 ending in a NUL byte, int32 and int64
integers, float32 pixel data. Two packet types are sent here:

- CreateImage (type 4): grab focus, name, width, height (int32), channel count (int32), the channel
  names. tev replaces an open image of the same name by a black one of this size.
- UpdateImageV3 (type 6, tev 1.18 and later): grab focus, name, channel count, channel names, the
  tile's x, y, width, height (int32), one offset and one stride per channel (int64, in floats),
  then the floats: channel c of the tile's pixel p (row-major in the tile) is float
  `offset[c] + p * stride[c]`. Here R, G, B are interleaved: offsets 0, 1, 2 and strides 3.

CreateImage grabs focus, the updates do not (the user may switch images while it renders). No
CloseImage is sent: the finished image stays open in tev. A tile is split into several packets
so that none exceeds MAX_PACKET bytes, tev's initial receive buffer (it grows the buffer for longer
ones, but short packets keep every send short).

An unreachable server, a send that fails or takes longer than the timeout, and a server that goes
away mid-render all give ONE `DisplayWarning` (warnings.warn) and turn the display off; the render
goes on. A badly formed address is a UserError.
"""
from __future__ import annotations

import re
import socket
import struct
import threading
import warnings

import numpy as np

from ..errors import UserError

CREATE_IMAGE = 4
UPDATE_IMAGE_V3 = 6
CHANNELS = ("R", "G", "B")
MAX_PACKET = 1 << 20  # bytes: tev's initial receive buffer per connection
TIMEOUT = 1.0  # seconds allowed to connect, to send one packet and to close
EXAMPLE = "127.0.0.1:14158"  # tev's default address

_ADDRESS = re.compile(r"(?:\[(?P<v6>[0-9A-Fa-f:.]+(?:%[\w.-]+)?)\]|(?P<host>[^\s:\[\]]+)):(?P<port>[0-9]{1,5})")


class DisplayWarning(RuntimeWarning):
    """The live display stopped (or never started); the render itself goes on."""


def parse_address(text: str) -> tuple[str, int]:
    """`HOST:PORT` (an IPv6 host in brackets, `[::1]:14158`) as (host, port); UserError otherwise."""
    m = _ADDRESS.fullmatch(text)
    if not m or not 1 <= int(m["port"]) <= 65535:
        raise UserError(f"--display-server {text!r}: expected HOST:PORT with a port from 1 to 65535, e.g. "
                        f"--display-server {EXAMPLE} (tev's default; an IPv6 host goes in brackets: [::1]:14158)")
    return m["v6"] or m["host"], int(m["port"])


def _string(text: str) -> bytes:
    data = text.encode("utf-8")
    if b"\0" in data:
        raise ValueError(f"tev strings cannot contain NUL bytes: {text!r}")
    return data + b"\0"


def _packet(kind: int, body: bytes) -> bytes:
    """A packet: its total length (uint32, counting these 4 bytes), the type byte, the body."""
    return struct.pack("<IB", 5 + len(body), kind) + body


def _names() -> bytes:
    return struct.pack("<i", len(CHANNELS)) + b"".join(_string(c) for c in CHANNELS)


class TevDisplay:
    """A connection to tev showing one image; call it with each finished tile (the renderer's
    per-tile observer). Thread-safe: tiles may come from several threads."""

    def __init__(self, label: str, name: str, width: int, height: int, max_packet: int):
        if not (0 < width < 2**31 and 0 < height < 2**31):
            raise ValueError(f"image size {width}x{height} must be positive int32")
        self._sock, self._label, self.width, self.height = None, label, width, height
        self._lock = threading.Lock()
        self._prefix = _string(name) + _names()  # the fields before the tile's position
        header = 5 + 1 + len(self._prefix) + 16 + 2 * 8 * len(CHANNELS)
        self._pixels = (max_packet - header) // (4 * len(CHANNELS))  # pixels per packet
        if self._pixels < 1:
            raise ValueError(f"max_packet {max_packet} is too small for one pixel (needs {header + 12} bytes)")
        self._layout = struct.pack(f"<{2 * len(CHANNELS)}q", *range(len(CHANNELS)), *[len(CHANNELS)] * len(CHANNELS))

    @classmethod
    def open(cls, address: str, name: str, width: int, height: int, *, timeout: float = TIMEOUT,
             max_packet: int = MAX_PACKET) -> TevDisplay:
        """Connect to tev at `address` ("HOST:PORT") and create the black image `name` of
        width x height pixels (R, G, B) with focus. A badly formed address is a UserError; an
        unreachable server a DisplayWarning, and the object then ignores its tiles. `timeout`
        bounds the connection, each packet's send and the close."""
        host, port = parse_address(address)
        self = cls(f"display server {address} (tev)", name, width, height, max_packet)
        try:
            self._sock = socket.create_connection((host, port), timeout=timeout)
        except OSError as exc:
            warnings.warn(f"{self._label}: cannot connect ({_reason(exc)}); the render goes on without the live "
                          f"display (start tev first: tev --hostname {address})", DisplayWarning, stacklevel=2)
        body = struct.pack("<?", True) + _string(name) + struct.pack("<ii", width, height) + _names()
        self._send([_packet(CREATE_IMAGE, body)])
        return self

    @property
    def connected(self) -> bool:
        return self._sock is not None

    def __call__(self, y0: int, y1: int, x0: int, x1: int, block: np.ndarray) -> None:
        """Show the finished pixels rows y0:y1, columns x0:x1 (block: their (y1-y0, x1-x0, 3)
        linear radiance) in tev, as float32, in packets of at most max_packet bytes."""
        if not (0 <= y0 <= y1 <= self.height and 0 <= x0 <= x1 <= self.width):
            raise ValueError(f"tile rows {y0}:{y1}, columns {x0}:{x1} outside the {self.width}x{self.height} image")
        if np.shape(block) != (y1 - y0, x1 - x0, len(CHANNELS)):
            raise ValueError(f"tile block has shape {np.shape(block)}, expected {(y1 - y0, x1 - x0, len(CHANNELS))}")
        if self._sock is None or y0 == y1 or x0 == x1:
            return
        with np.errstate(over="ignore"):  # beyond float32's range is inf, as in the EXR
            data = np.asarray(block, dtype="<f4")
        self._send(self._update(data[r0 - y0:r1 - y0, c0 - x0:c1 - x0], c0, r0)
                   for r0, r1, c0, c1 in _pieces(y0, y1, x0, x1, self._pixels))

    def _update(self, data: np.ndarray, x: int, y: int) -> bytes:
        """An UpdateImageV3 packet of the interleaved float32 RGB `data` at column x, row y."""
        h, w, _ = data.shape
        body = (struct.pack("<?", False) + self._prefix + struct.pack("<iiii", x, y, w, h) + self._layout
                + np.ascontiguousarray(data).tobytes())
        return _packet(UPDATE_IMAGE_V3, body)

    def _send(self, packets) -> None:
        with self._lock:
            for packet in packets:
                if self._sock is None:
                    return
                try:
                    self._sock.sendall(packet)
                except OSError as exc:  # refused, reset, broken pipe, timeout
                    self._drop()
                    warnings.warn(f"{self._label}: stopped answering ({_reason(exc)}); the render goes on without "
                                  "the live display", DisplayWarning, stacklevel=3)

    def _drop(self) -> None:
        sock, self._sock = self._sock, None
        if sock is not None:
            sock.close()

    def close(self) -> None:
        """Finish the connection; the image stays open in tev. Waits (at most the timeout) until tev
        has read every packet, as tev's own clients do, then closes. Never warns."""
        with self._lock:
            sock = self._sock
            if sock is None:
                return
            try:
                sock.shutdown(socket.SHUT_WR)
                while sock.recv(4096):  # tev sends nothing; an empty read is its close
                    pass
            except OSError:
                pass
            self._drop()

    def __enter__(self) -> TevDisplay:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _pieces(y0: int, y1: int, x0: int, x1: int, pixels: int):
    """Sub-rectangles (r0, r1, c0, c1) covering rows y0:y1, columns x0:x1 once, each of at most
    `pixels` pixels: bands of whole rows, or pieces of single rows when a row is longer."""
    w = x1 - x0
    if w <= pixels:
        step = pixels // w
        for r in range(y0, y1, step):
            yield r, min(r + step, y1), x0, x1
    else:
        for r in range(y0, y1):
            for c in range(x0, x1, pixels):
                yield r, r + 1, c, min(c + pixels, x1)


def _reason(exc: OSError) -> str:
    if isinstance(exc, TimeoutError):
        return "no answer within the timeout"
    return exc.strerror or str(exc) or type(exc).__name__
