"""EXR alpha and layers: RGBA round trips, write_exr_layers / read_exr_layers (names, order,
channel naming as other tools see it), read_exr's choice of layer, bad input, and two readers
that are not OpenEXR's python module: OpenCV (when installed) and a minimal decoder below."""

from __future__ import annotations

import importlib.util
import os
import struct
import subprocess
import sys
import zlib

import numpy as np
import OpenEXR
import pytest

from app.errors import ScanlightError
from app.io.clean import HALF_MAX
from app.io.exr import read_exr, read_exr_layers, write_exr, write_exr_layers

RNG = np.random.default_rng(11)


def _rgba(h=5, w=7, scale=10.0):
    a = RNG.uniform(0, scale, (h, w, 4)).astype(np.float32)
    a[..., 3] = RNG.uniform(0, 1, (h, w))
    a[0, 0, 3], a[0, 1, 3] = 0.0, 1.0
    return a


def _layers(h=6, w=9):
    return {"beauty": _rgba(h, w), "asset": _rgba(h, w), "background": _rgba(h, w)[..., :3],
            "shadow": RNG.uniform(0, 1, (h, w)).astype(np.float32),
            "indirect": _rgba(h, w)}


def _channel_names(path) -> list[str]:
    with OpenEXR.File(str(path), header_only=True) as f:
        return [c.name for c in f.parts[0].header["channels"]]


def test_rgba_float_roundtrip_alpha_exact(tmp_path):
    a = _rgba()
    write_exr(tmp_path / "a.exr", a)
    assert _channel_names(tmp_path / "a.exr") == ["A", "B", "G", "R"]   # stored sorted by name
    back = read_exr_layers(tmp_path / "a.exr")
    assert list(back) == [""] and back[""].dtype == np.float32
    np.testing.assert_array_equal(back[""], a)
    np.testing.assert_array_equal(read_exr(tmp_path / "a.exr").rgb, a[..., :3])  # A ignored


def test_rgba_half_roundtrip_within_half_precision(tmp_path):
    a = _rgba()
    a[1, 1, 0] = 1e6                                    # clipped to HALF_MAX, not Inf
    write_exr(tmp_path / "h.exr", a, half=True)
    with OpenEXR.File(str(tmp_path / "h.exr"), separate_channels=True) as f:
        assert {c.pixels.dtype for c in f.parts[0].channels.values()} == {np.dtype(np.float16)}
    back = read_exr_layers(tmp_path / "h.exr")[""]
    np.testing.assert_array_equal(back, np.minimum(a, HALF_MAX).astype(np.float16)
                                  .astype(np.float32))
    np.testing.assert_allclose(back[..., 3], a[..., 3], atol=2.0 ** -11)   # alpha in [0, 1]


@pytest.mark.parametrize("half", [False, True])
def test_layers_roundtrip_names_order_and_channels(tmp_path, half):
    layers = _layers()
    p = tmp_path / "l.exr"
    write_exr_layers(p, layers, half=half)
    assert _channel_names(p) == sorted(
        ["beauty.R", "beauty.G", "beauty.B", "beauty.A", "asset.R", "asset.G", "asset.B",
         "asset.A", "background.R", "background.G", "background.B", "shadow.Y",
         "indirect.R", "indirect.G", "indirect.B", "indirect.A"])
    with OpenEXR.File(str(p), header_only=True) as f:
        assert f.parts[0].header["scanlightLayers"] == "beauty,asset,background,shadow,indirect"
        assert f.parts[0].header["compression"] == OpenEXR.ZIP_COMPRESSION
        assert len(f.parts) == 1
    back = read_exr_layers(p)
    assert list(back) == list(layers)                   # the order written, not sorted
    for name, a in layers.items():
        expect = a.astype(np.float16).astype(np.float32) if half else a
        assert back[name].dtype == np.float32 and back[name].shape == a.shape
        np.testing.assert_array_equal(back[name], expect)


def test_layers_without_order_attribute_come_back_sorted(tmp_path):
    y = np.ones((2, 3), np.float32)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    chans = {"b.R": y, "b.G": y, "b.B": 2 * y, "a.Y": 3 * y, "R": y, "G": y, "B": y,
             "Normal.X": y, "Normal.Y": y, "Normal.Z": y}      # a vector, not a grey layer
    with OpenEXR.File(header, chans) as f:
        f.write(str(tmp_path / "foreign.exr"))
    back = read_exr_layers(tmp_path / "foreign.exr")
    assert list(back) == ["", "a", "b"]
    assert back[""].shape == (2, 3, 3) and back["a"].shape == (2, 3)
    np.testing.assert_array_equal(back["b"][..., 2], 2 * y)


def test_read_exr_shows_beauty_and_says_so(tmp_path):
    layers = _layers()
    order = {"asset": layers["asset"], "beauty": layers["beauty"]}   # beauty not first
    write_exr_layers(tmp_path / "l.exr", order)
    img = read_exr(tmp_path / "l.exr")
    assert img.report["layer"] == "beauty"
    np.testing.assert_array_equal(img.rgb, layers["beauty"][..., :3])
    # no beauty: the first layer with R,G,B in the written order (a grey layer does not count)
    write_exr_layers(tmp_path / "n.exr", {"shadow": layers["shadow"], "zeta": layers["asset"],
                                          "alpha": layers["indirect"]})
    img = read_exr(tmp_path / "n.exr")
    assert img.report["layer"] == "zeta"
    np.testing.assert_array_equal(img.rgb, layers["asset"][..., :3])
    # plain channels are not a layer: no report entry
    write_exr(tmp_path / "p.exr", layers["beauty"])
    assert "layer" not in read_exr(tmp_path / "p.exr").report


def test_read_exr_refuses_file_without_colour_layer(tmp_path):
    write_exr_layers(tmp_path / "g.exr", {"shadow": np.ones((2, 2), np.float32)})
    with pytest.raises(ScanlightError, match=r"g\.exr: EXR has no R,G,B or Y channels"):
        read_exr(tmp_path / "g.exr")


@pytest.mark.parametrize("layers, match", [
    ({"": np.ones((2, 2, 3))}, "layer name"),
    ({"bad name": np.ones((2, 2, 3))}, "layer name"),
    ({"a.b": np.ones((2, 2, 3))}, "layer name"),
    ([("a", np.ones((2, 2, 3))), ("a", np.ones((2, 2, 3)))], "repeat"),
    ({}, "at least one"),
    ({"a": np.ones((2, 2, 3)), "b": np.ones((2, 3, 3))}, "'b' is 3x2, not 2x2"),
    ({"a": np.ones((2, 2, 3)), "b": np.full((2, 2, 4), np.nan)}, "NaN"),
    ({"a": np.ones((2, 2, 2))}, "non-empty"),
])
def test_write_exr_layers_refuses_bad_input(tmp_path, layers, match):
    with pytest.raises(ValueError, match=match):
        write_exr_layers(tmp_path / "x.exr", layers)
    assert not (tmp_path / "x.exr").exists()


def test_write_exr_rgba_refuses_nan(tmp_path):
    a = np.ones((2, 2, 4), np.float32)
    a[1, 1, 3] = np.inf
    with pytest.raises(ValueError, match="NaN or Inf"):
        write_exr(tmp_path / "n.exr", a)
    assert not (tmp_path / "n.exr").exists()


def test_truncated_layered_file_names_the_file(tmp_path):
    big = {k: np.repeat(np.repeat(v, 8, 0), 8, 1) for k, v in _layers().items()}
    write_exr_layers(tmp_path / "good.exr", big)
    data = (tmp_path / "good.exr").read_bytes()
    p = tmp_path / "cut.exr"
    p.write_bytes(data[: len(data) // 2])
    for reader in (read_exr_layers, read_exr):
        with pytest.raises(ScanlightError) as err:
            reader(p)
        assert str(p) in str(err.value) and "corrupt or truncated EXR" in str(err.value)


# -- readers other than OpenEXR's python module ------------------------------------------------
def _decode_scanline_exr(path) -> tuple[dict, dict]:
    """({attribute: raw bytes}, {channel: pixels}) of a single-part scanline EXR with no or ZIP
    compression, decoded from the OpenEXR file layout by hand (the format's specification)."""
    data = open(path, "rb").read()
    assert data[:4] == b"\x76\x2f\x31\x01" and data[4] == 2 and not data[5] & 0x16  # scanline
    pos, attrs = 8, {}
    while data[pos] != 0:
        name_end = data.index(b"\0", pos)
        type_end = data.index(b"\0", name_end + 1)
        (size,) = struct.unpack_from("<i", data, type_end + 1)
        attrs[data[pos:name_end].decode()] = data[type_end + 5: type_end + 5 + size]
        pos = type_end + 5 + size
    pos += 1
    chans, cl = [], attrs["channels"]
    while cl[0] != 0:
        end = cl.index(b"\0")
        ptype, _, xs, ys = struct.unpack_from("<iB3xii", cl, end + 1)
        assert (xs, ys) == (1, 1)
        chans.append((cl[:end].decode(), {1: np.float16, 2: np.float32}[ptype]))
        cl = cl[end + 17:]
    x0, y0, x1, y1 = struct.unpack("<iiii", attrs["dataWindow"])
    w, h = x1 - x0 + 1, y1 - y0 + 1
    lines = {0: 1, 3: 16}[attrs["compression"][0]]        # NO_COMPRESSION or ZIP
    n_chunks = -(-h // lines)
    offsets = struct.unpack_from(f"<{n_chunks}Q", data, pos)
    out = {name: np.zeros((h, w), dt) for name, dt in chans}
    for off in offsets:
        y, size = struct.unpack_from("<ii", data, off)
        n = min(lines, y1 + 1 - y)
        raw = data[off + 8: off + 8 + size]
        expect = n * w * sum(np.dtype(dt).itemsize for _, dt in chans)
        if size < expect:                                 # ZIP: zlib, then undo the predictor
            d = np.frombuffer(zlib.decompress(raw), np.uint8).astype(np.int64)
            d[1:] -= 128
            t = (np.cumsum(d) % 256).astype(np.uint8)     # t[i] = t[i-1] + d[i] - 128
            half = (len(t) + 1) // 2                      # ... and the byte interleaving
            raw = np.empty_like(t)
            raw[0::2], raw[1::2] = t[:half], t[half:]
            raw = raw.tobytes()
        assert len(raw) == expect
        at = 0
        for row in range(y - y0, y - y0 + n):
            for name, dt in chans:
                le = np.dtype(dt).newbyteorder("<")
                out[name][row] = np.frombuffer(raw[at: at + w * le.itemsize], le)
                at += w * le.itemsize
    return attrs, out


@pytest.mark.parametrize("half", [False, True])
def test_layered_file_decoded_by_hand(tmp_path, half):
    """The file as the format defines it (header, channel list, ZIP blocks), read without
    OpenEXR: channel names, the order attribute and every pixel as written."""
    layers = {k: np.repeat(v, 4, axis=0) for k, v in _layers(h=9).items()}   # 36 rows: 3 blocks
    write_exr_layers(tmp_path / "l.exr", layers, half=half)
    attrs, chans = _decode_scanline_exr(tmp_path / "l.exr")
    assert attrs["scanlightLayers"] == b"beauty,asset,background,shadow,indirect"
    assert attrs["compression"] == b"\x03"                # ZIP_COMPRESSION
    expect = {}
    for name, a in layers.items():
        if a.ndim == 2:
            expect[f"{name}.Y"] = a
        else:
            expect.update({f"{name}.{c}": a[..., i] for i, c in enumerate("RGBA"[:a.shape[2]])})
    assert sorted(chans) == sorted(expect)
    for name, a in expect.items():
        np.testing.assert_array_equal(chans[name].astype(np.float32),
                                      a.astype(np.float16 if half else np.float32))
    # and the RGBA file of write_exr the same way
    rgba = np.repeat(_rgba(h=5), 4, axis=0)             # 20 rows, ZIP-compressible
    write_exr(tmp_path / "a.exr", rgba, half=half)
    _, chans = _decode_scanline_exr(tmp_path / "a.exr")
    np.testing.assert_array_equal(np.stack([chans[c].astype(np.float32) for c in "RGBA"], -1),
                                  rgba.astype(np.float16 if half else np.float32))


_CV2_READ = """
import os, sys
os.environ["OPENCV_IO_ENABLE_OPENEXR"] = "1"      # must be set before cv2 is imported
import cv2, numpy as np
for src, dst in zip(sys.argv[1::2], sys.argv[2::2]):
    img = cv2.imread(src, cv2.IMREAD_UNCHANGED)
    if img is None:
        sys.exit(f"cv2 could not read {src}")
    np.save(dst, img)
"""


@pytest.mark.skipif(importlib.util.find_spec("cv2") is None,
                    reason="OpenCV (cv2) is not installed in this environment, and imageio "
                           "(not installed either) reads EXR only through a FreeImage download")
def test_opencv_reads_rgba_and_layered_beauty(tmp_path):
    """OpenCV's own EXR decoder: the RGBA file as BGRA. OpenCV reads only unprefixed R,G,B,A
    channels, so the layered file's beauty is checked after read_exr_layers -> write_exr."""
    rgba = _rgba()
    write_exr(tmp_path / "a.exr", rgba)
    layers = _layers()
    write_exr_layers(tmp_path / "l.exr", layers)
    write_exr(tmp_path / "b.exr", read_exr_layers(tmp_path / "l.exr")["beauty"])
    env = dict(os.environ, OPENCV_IO_ENABLE_OPENEXR="1")
    res = subprocess.run([sys.executable, "-c", _CV2_READ,
                          str(tmp_path / "a.exr"), str(tmp_path / "a.npy"),
                          str(tmp_path / "b.exr"), str(tmp_path / "b.npy")],
                         capture_output=True, text=True, env=env, timeout=120)
    if res.returncode != 0 and "could not read" in res.stderr:
        pytest.skip(f"this OpenCV build reads no EXR: {res.stderr.strip()}")
    assert res.returncode == 0, res.stderr
    for npy, expect in (("a.npy", rgba), ("b.npy", layers["beauty"])):
        got = np.load(tmp_path / npy)
        assert got.shape == expect.shape and got.dtype == np.float32
        np.testing.assert_array_equal(got, expect[..., [2, 1, 0, 3]])   # BGRA
