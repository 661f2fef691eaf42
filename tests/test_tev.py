"""The tev live-display client against a stand-in tev on the loopback.

The stand-in decodes packets from tev's IPC protocol as tev's sources define it (include/tev/Ipc.h,
src/Ipc.cpp: uint32 length counting itself, type byte, one-byte booleans, NUL-terminated strings,
little-endian int32/int64, float32 data at offset + pixel * stride per channel), written here
without the client's encoder; two packets are also checked byte for byte against hand-assembled
hex.
"""
from __future__ import annotations

import socket
import struct
import threading
import time
import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from raytrace.errors import UserError
from raytrace.output.tev import DisplayWarning, TevDisplay, parse_address

TEV_RECEIVE_BUFFER = 1024 * 1024  # tev's initial per-connection buffer (src/Ipc.cpp, SocketConnection)


class Reader:
    """Fields of one packet body, read in order."""

    def __init__(self, data: bytes):
        self.data, self.at = data, 0

    def take(self, fmt: str):
        values = struct.unpack_from("<" + fmt, self.data, self.at)
        self.at += struct.calcsize("<" + fmt)
        return values if len(values) > 1 else values[0]

    def string(self) -> str:
        end = self.data.index(b"\0", self.at)
        text, self.at = self.data[self.at:end].decode("utf-8"), end + 1
        return text

    def rest(self) -> bytes:
        return self.data[self.at:]


def decode(packet: bytes) -> dict:
    """One packet (length prefix included) as a dict; only CreateImage (4) and UpdateImageV3 (6)."""
    r = Reader(packet)
    assert r.take("I") == len(packet)
    kind = r.take("B")
    focus = r.take("B")
    assert focus in (0, 1)
    name = r.string()
    if kind == 4:
        width, height, n = r.take("iii")
        out = dict(type="create", focus=focus, name=name, width=width, height=height,
                   channels=[r.string() for _ in range(n)])
        assert r.rest() == b""
        return out
    assert kind == 6, kind
    n = r.take("i")
    channels = [r.string() for _ in range(n)]
    x, y, w, h = r.take("iiii")
    offsets = [r.take("q") for _ in range(n)]
    strides = [r.take("q") for _ in range(n)]
    floats = np.frombuffer(r.rest(), dtype="<f4")
    assert len(floats) == max(o + (w * h - 1) * s + 1 for o, s in zip(offsets, strides))
    planes = [floats[o::s][:w * h].reshape(h, w) for o, s in zip(offsets, strides)]
    return dict(type="update", focus=focus, name=name, channels=channels, x=x, y=y, w=w, h=h,
                data=dict(zip(channels, planes)), size=len(packet))


class StandIn:
    """A tev on the loopback: accepts one client and records its raw packets until the client
    closes, or until `close_after` packets, when it hangs up (then `hung_up` is set). It starts
    reading `delay` seconds after the client connects."""

    def __init__(self, close_after: int | None = None, host: str = "127.0.0.1", delay: float = 0.0):
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        self.listener = socket.create_server((host, 0), family=family)
        if delay:
            self.listener.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 65536)
        self.listener.settimeout(5)
        port = self.listener.getsockname()[1]
        self.address = f"[{host}]:{port}" if ":" in host else f"{host}:{port}"
        self.close_after, self.delay, self.raw, self.hung_up = close_after, delay, [], threading.Event()
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _exactly(self, conn, n: int) -> bytes | None:
        data = b""
        while len(data) < n:
            chunk = conn.recv(n - len(data))
            if not chunk:
                assert data == b"", "the client closed mid-packet"
                return None
            data += chunk
        return data

    def _serve(self):
        conn, _ = self.listener.accept()
        with conn, self.listener:
            conn.settimeout(5)
            time.sleep(self.delay)  # a busy tev: the client's socket buffers fill
            while self.close_after is None or len(self.raw) < self.close_after:
                head = self._exactly(conn, 4)
                if head is None:
                    return
                self.raw.append(head + self._exactly(conn, struct.unpack("<I", head)[0] - 4))
        self.hung_up.set()

    def packets(self) -> list[dict]:
        self.thread.join(5)
        assert not self.thread.is_alive()
        return [decode(p) for p in self.raw]


def gradient(width: int, height: int) -> np.ndarray:
    """A float64 image whose every pixel and channel differ; most values are not float32 numbers."""
    y, x = np.mgrid[0:height, 0:width].astype(float)
    return np.stack([x + 1000.0 * y + 0.1, -(x * y + 1.0) / 7.0, 2.0 ** ((x - y) / 8.0) * 1e-3], axis=-1)


def assemble(packets: list[dict], width: int, height: int):
    """The image painted by the update packets, and how often each pixel was painted."""
    image, count = np.full((height, width, 3), np.nan, np.float32), np.zeros((height, width), int)
    for p in packets:
        assert p["type"] == "update" and p["focus"] == 0 and p["channels"] == ["R", "G", "B"]
        assert 0 <= p["x"] and p["x"] + p["w"] <= width and 0 <= p["y"] and p["y"] + p["h"] <= height
        box = np.s_[p["y"]:p["y"] + p["h"], p["x"]:p["x"] + p["w"]]
        image[box] = np.stack([p["data"][c] for c in "RGB"], axis=-1)
        count[box] += 1
    return image, count


def test_create_image_and_every_pixel_once():
    """CreateImage first (name, size, R G B, focus), then updates that paint each pixel of a
    gradient once with its float32 value; tiles of several shapes."""
    width, height = 37, 23
    img = gradient(width, height)
    tiles = [(0, 5, 0, 37), (5, 6, 0, 37), (6, 20, 0, 10), (6, 20, 10, 37), (20, 23, 0, 1), (20, 23, 1, 37)]
    server = StandIn()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        display = TevDisplay.open(server.address, "gradient é", width, height)
        for y0, y1, x0, x1 in tiles[::-1]:
            display(y0, y1, x0, x1, img[y0:y1, x0:x1])
        display.close()
    create, *updates = server.packets()
    assert create == dict(type="create", focus=1, name="gradient é", width=width, height=height,
                          channels=["R", "G", "B"])
    assert {p["name"] for p in updates} == {"gradient é"}
    image, count = assemble(updates, width, height)
    assert (count == 1).all()
    np.testing.assert_array_equal(image, img.astype(np.float32))


def test_tiles_from_several_threads():
    """The renderer's threads call the display at once while tev is busy: their packets (1.6 MB in
    all, far more than the two 64 kB socket buffers hold) still arrive whole, each pixel once.
    Unserialised sends interleaved here in 8 runs of 8 (timing-dependent, so not guaranteed)."""
    width, height, rows = 512, 256, 32
    img = gradient(width, height)
    server = StandIn(delay=0.05)
    display = TevDisplay.open(server.address, "threads", width, height)
    display._sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 65536)  # the client side of the small buffers
    with ThreadPoolExecutor(4) as pool:
        list(pool.map(lambda y: display(y, y + rows, 0, width, img[y:y + rows]), range(0, height, rows)))
    display.close()
    image, count = assemble(server.packets()[1:], width, height)
    assert (count == 1).all()
    np.testing.assert_array_equal(image, img.astype(np.float32))


@pytest.mark.parametrize("max_packet, pieces", [(200, "pieces of rows"), (1000, "bands of rows")])
def test_packets_stay_under_the_limit(max_packet, pieces):
    """A tile longer than the packet limit is split; each pixel still arrives once."""
    width, height = 37, 9
    img = gradient(width, height)
    server = StandIn()
    display = TevDisplay.open(server.address, "grad", width, height, max_packet=max_packet)
    display(0, height, 0, width, img)
    display.close()
    updates = server.packets()[1:]
    assert max(p["size"] for p in updates) <= max_packet
    if pieces == "pieces of rows":
        assert all(p["h"] == 1 for p in updates) and len(updates) > height
    else:
        assert all(p["w"] == width for p in updates) and 1 < len(updates) < height
    image, count = assemble(updates, width, height)
    assert (count == 1).all()
    np.testing.assert_array_equal(image, img.astype(np.float32))


def test_a_tile_beyond_tevs_receive_buffer_is_split():
    """A 400x300 tile (1.44 MB of floats) arrives in packets that fit tev's 1 MiB buffer."""
    width, height = 400, 300
    img = gradient(width, height)
    server = StandIn()
    display = TevDisplay.open(server.address, "big", width, height)
    display(0, height, 0, width, img)
    display.close()
    updates = server.packets()[1:]
    assert len(updates) >= 2 and max(p["size"] for p in updates) <= TEV_RECEIVE_BUFFER
    image, count = assemble(updates, width, height)
    assert (count == 1).all()
    np.testing.assert_array_equal(image, img.astype(np.float32))


def test_bytes_on_the_wire():
    """CreateImage and UpdateImageV3 byte for byte, assembled by hand from tev's field order:
    image "a" 2 wide, 3 tall; the pixel at column 1, row 2 is (1, -2, 0.1) (0.1 rounds to the
    float32 0x3dcccccd, stored least significant byte first)."""
    server = StandIn()
    display = TevDisplay.open(server.address, "a", 2, 3)
    display(2, 3, 1, 2, np.array([[[1.0, -2.0, 0.1]]]))
    display.close()
    server.packets()
    names = "5200" "4700" "4200"
    assert server.raw[0].hex() == ("1a000000" "04" "01" "6100" "02000000" "03000000" "03000000" + names)
    assert server.raw[1].hex() == ("5e000000" "06" "00" "6100" "03000000" + names
                                   + "01000000" "02000000" "01000000" "01000000"
                                   + "0000000000000000" "0100000000000000" "0200000000000000"
                                   + "0300000000000000" * 3
                                   + "0000803f" "000000c0" "cdcccc3d")


def test_ipv6_address_in_brackets():
    server = StandIn(host="::1")
    display = TevDisplay.open(server.address, "v6", 2, 1)
    display(0, 1, 0, 2, np.ones((1, 2, 3)))
    display.close()
    create, update = server.packets()
    assert (create["width"], create["height"], update["w"]) == (2, 1, 2)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_unreachable_server_is_one_warning():
    address = f"127.0.0.1:{free_port()}"
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        display = TevDisplay.open(address, "x", 4, 4, timeout=0.2)
        for y in range(4):
            display(y, y + 1, 0, 4, np.zeros((1, 4, 3)))
        display.close()
    assert time.perf_counter() - start < 0.5
    assert [w.category for w in caught] == [DisplayWarning]
    assert address in str(caught[0].message) and "tev --hostname" in str(caught[0].message)
    assert not display.connected


def test_server_gone_mid_render_is_one_warning():
    """tev quits after CreateImage and one tile; the remaining tiles give one warning, no error."""
    width, height = 64, 40
    img = gradient(width, height)
    server = StandIn(close_after=2)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        display = TevDisplay.open(server.address, "gone", width, height, timeout=0.2)
        display(0, 1, 0, width, img[:1])
        assert server.hung_up.wait(2)
        for y in range(1, height):
            display(y, y + 1, 0, width, img[y:y + 1])
        display.close()
    assert [w.category for w in caught] == [DisplayWarning]
    assert "stopped answering" in str(caught[0].message)
    assert not display.connected and len(server.packets()) == 2


def test_server_that_stops_reading_blocks_a_send_at_most_the_timeout():
    """A tev that accepts but never reads: once the socket buffers fill, a send waits the timeout,
    warns once and the display is off."""
    listener = socket.create_server(("127.0.0.1", 0))
    listener.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    address = f"127.0.0.1:{listener.getsockname()[1]}"
    img = np.zeros((512, 512, 3))
    with listener, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        display = TevDisplay.open(address, "stuck", 512, 512, timeout=0.2)
        start = time.perf_counter()
        for _ in range(8):  # 8 x 3 MB, more than loopback buffers hold
            display(0, 512, 0, 512, img)
        elapsed = time.perf_counter() - start
        display.close()
    assert [w.category for w in caught] == [DisplayWarning]
    assert "no answer within the timeout" in str(caught[0].message)
    assert elapsed < 0.6


@pytest.mark.parametrize("text, expected", [("127.0.0.1:14158", ("127.0.0.1", 14158)),
                                            ("tev-host.local:1", ("tev-host.local", 1)),
                                            ("[::1]:14158", ("::1", 14158)),
                                            ("[fe80::1%eth0]:65535", ("fe80::1%eth0", 65535))])
def test_addresses(text, expected):
    assert parse_address(text) == expected


@pytest.mark.parametrize("text", ["localhost", "localhost:", ":14158", "::1:14158", "[::1]14158", "host:0",
                                  "host:65536", "host:port", " 127.0.0.1:14158", "a b:1", "[::1:14158"])
def test_bad_address_is_a_user_error(text):
    with pytest.raises(UserError, match=r"^--display-server .*HOST:PORT.*127\.0\.0\.1:14158"):
        TevDisplay.open(text, "x", 1, 1)


def test_tile_outside_the_image_is_refused():
    server = StandIn()
    display = TevDisplay.open(server.address, "x", 4, 4)
    with pytest.raises(ValueError, match="outside"):
        display(3, 5, 0, 4, np.zeros((2, 4, 3)))
    with pytest.raises(ValueError, match="shape"):
        display(0, 1, 0, 4, np.zeros((1, 3, 3)))
    display.close()
    assert len(server.packets()) == 1
