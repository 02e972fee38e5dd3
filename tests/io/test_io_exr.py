"""Images: OpenEXR read/write, the real panoramas' negative pixels, LDR decoding, bad files."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import OpenEXR
import pytest

from app.color import srgb_to_linear
from app.errors import ScanlightError
from app.io.clean import HALF_MAX
from app.io.exr import read_exr, read_image, write_exr
from app.io.images import write_png

DATA = Path(__file__).resolve().parents[3] / "shared" / "data"
PANORAMAS = ["apartment.exr", "studio.exr", "warehouse.exr", "city.exr"]
needs_data = pytest.mark.skipif(not DATA.is_dir(), reason="../shared/data not present")


def _raw_rgb(path) -> np.ndarray:
    """Pixels as stored, read straight through OpenEXR (independent of read_exr)."""
    with OpenEXR.File(str(path), separate_channels=True) as f:
        ch = f.parts[0].channels
        return np.stack([ch[c].pixels.astype(np.float32) for c in "RGB"], axis=-1)


def _write_raw(path, channels: dict) -> None:
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, channels) as f:
        f.write(str(path))


@needs_data
@pytest.mark.parametrize("name", PANORAMAS)
def test_real_panorama_negative_pixels_clamped_and_counted(name):
    raw = _raw_rgb(DATA / name)
    img = read_exr(DATA / name)
    negative = (raw < 0).any(axis=-1)
    assert negative.sum() > 0  # the README promises ringing in every panorama
    assert img.report["clamped_negative_pixels"] == int(negative.sum())
    assert img.rgb.shape == raw.shape and img.rgb.dtype == np.float32 and img.hdr
    assert np.all(np.isfinite(img.rgb)) and img.rgb.min() == 0.0
    np.testing.assert_array_equal(img.rgb, np.maximum(raw, 0.0))
    assert "negative" in img.report["warnings"][0]


@needs_data
def test_studio_bright_values_preserved():
    img = read_exr(DATA / "studio.exr")
    assert img.rgb.max() == pytest.approx(3730.0)  # README: up to 3730; nothing clipped to 1


def test_float_roundtrip_exact(tmp_path):
    rgb = np.random.default_rng(1).uniform(0, 5000, (7, 9, 3)).astype(np.float32)
    write_exr(tmp_path / "a.exr", rgb)
    img = read_image(tmp_path / "a.exr")
    np.testing.assert_array_equal(img.rgb, rgb)
    assert img.report["clamped_negative_pixels"] == 0


def test_half_roundtrip_rounds_like_float16_and_clips_to_half_max(tmp_path):
    rgb = np.random.default_rng(2).uniform(0, 100, (5, 6, 3)).astype(np.float32)
    rgb[0, 0] = 1e6  # beyond half range: must become 65504, not Inf
    write_exr(tmp_path / "h.exr", rgb, half=True)
    with OpenEXR.File(str(tmp_path / "h.exr")) as f:
        assert f.channels()["RGB"].pixels.dtype == np.float16
    img = read_exr(tmp_path / "h.exr")
    expect = np.minimum(rgb, HALF_MAX).astype(np.float16).astype(np.float32)
    np.testing.assert_array_equal(img.rgb, expect)
    assert img.report["clamped_inf_pixels"] == 0


def test_y_channel_is_grey_and_rgba_drops_alpha(tmp_path):
    y = np.arange(12, dtype=np.float32).reshape(3, 4)
    _write_raw(tmp_path / "y.exr", {"Y": y})
    np.testing.assert_array_equal(read_exr(tmp_path / "y.exr").rgb, np.repeat(y[..., None], 3, -1))
    rgba = np.random.default_rng(3).random((3, 4, 4)).astype(np.float16)
    _write_raw(tmp_path / "a.exr", {"RGBA": rgba})
    np.testing.assert_array_equal(read_exr(tmp_path / "a.exr").rgb, rgba[..., :3].astype(np.float32))
    write_exr(tmp_path / "g.exr", y)  # write_exr of a 2-D array writes Y
    np.testing.assert_array_equal(read_exr(tmp_path / "g.exr").rgb[..., 1], y)


def test_nan_inf_negative_pixels_repaired_and_counted(tmp_path):
    rgb = np.ones((2, 3, 3), dtype=np.float32)
    rgb[0, 0, 0] = np.nan
    rgb[0, 1, 2] = np.inf
    rgb[1, 0, 1] = -2.0
    rgb[1, 1, :] = -np.inf  # negative, counted once
    _write_raw(tmp_path / "bad.exr", {"RGB": rgb})
    img = read_exr(tmp_path / "bad.exr")
    assert (img.report["clamped_nan_pixels"], img.report["clamped_inf_pixels"],
            img.report["clamped_negative_pixels"]) == (1, 1, 2)
    assert img.rgb[0, 0, 0] == 0 and img.rgb[0, 1, 2] == HALF_MAX and img.rgb[1, 0, 1] == 0
    assert np.all(img.rgb[1, 1] == 0) and np.all(np.isfinite(img.rgb))
    assert img.rgb[1, 2, 0] == 1.0  # untouched pixels stay


def test_write_exr_refuses_nan(tmp_path):
    with pytest.raises(ValueError):
        write_exr(tmp_path / "n.exr", np.full((2, 2, 3), np.nan, dtype=np.float32))
    assert not (tmp_path / "n.exr").exists()


def test_write_is_atomic(tmp_path, monkeypatch):
    target = tmp_path / "keep.exr"
    write_exr(target, np.ones((2, 2, 3), np.float32))
    before = target.read_bytes()

    def boom(self, path):
        Path(path).write_bytes(b"half")
        raise RuntimeError("disk full")

    monkeypatch.setattr(OpenEXR.File, "write", boom)
    # the library's write error is one line naming the target (app/io/files.py write_failure)
    with pytest.raises(ScanlightError, match="keep.exr: could not be written: disk full"):
        write_exr(target, np.zeros((2, 2, 3), np.float32))
    assert target.read_bytes() == before
    assert os.listdir(tmp_path) == ["keep.exr"]  # no temporary left behind


def test_png_roundtrip_decodes_srgb(tmp_path):
    enc = np.arange(256, dtype=np.uint8).reshape(16, 16)
    rgb8 = np.stack([enc, enc[::-1], enc.T], axis=-1)
    write_png(tmp_path / "a.png", rgb8)
    img = read_image(tmp_path / "a.png")
    assert not img.hdr
    np.testing.assert_allclose(img.rgb, srgb_to_linear(rgb8 / 255.0), atol=1e-7)


def test_write_png_rejects_float():
    with pytest.raises(ValueError):
        write_png("/nonexistent/x.png", np.zeros((2, 2, 3), np.float32))


@pytest.mark.parametrize("case, expect", [
    ("missing", "not found"),
    ("empty", "empty"),
    ("truncated", "corrupt or truncated EXR"),
    ("garbage", "corrupt or truncated EXR"),
])
def test_bad_exr_files(tmp_path, case, expect):
    p = tmp_path / f"{case}.exr"
    good = tmp_path / "good.exr"
    write_exr(good, np.random.default_rng(4).random((64, 64, 3)).astype(np.float32))
    if case == "empty":
        p.write_bytes(b"")
    elif case == "truncated":
        p.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    elif case == "garbage":
        p.write_bytes(b"this is not an EXR file at all" * 10)
    with pytest.raises(ScanlightError) as err:
        read_image(p)
    assert str(p) in str(err.value) and expect in str(err.value)


def test_a_truncated_exr_is_one_line_with_the_library_s_own_words_folded_in(tmp_path, capfd):
    """The OpenEXR library printed its own two lines around ours (its core to stderr, its
    binding to stdout, where a command's results go); now they are part of our one line."""
    good = tmp_path / "good.exr"
    write_exr(good, np.random.default_rng(4).random((512, 256, 3)).astype(np.float32) + 1)
    p = tmp_path / "cut.exr"
    p.write_bytes(good.read_bytes()[: good.stat().st_size * 6 // 10])
    capfd.readouterr()
    with pytest.raises(ScanlightError) as err:
        read_image(p)
    out, errs = capfd.readouterr()
    assert out == "" and errs == ""
    text = str(err.value)
    assert "\n" not in text and "corrupt or truncated EXR" in text and "OpenEXR library" in text
    # a good file says nothing, and nothing is left redirected
    read_image(good)
    print("still here")
    assert capfd.readouterr().out == "still here\n"


def test_truncated_png(tmp_path):
    write_png(tmp_path / "a.png", np.zeros((64, 64, 3), np.uint8) + 7)
    data = (tmp_path / "a.png").read_bytes()
    (tmp_path / "t.png").write_bytes(data[: len(data) // 2])
    with pytest.raises(ScanlightError, match="t.png: corrupt or truncated image"):
        read_image(tmp_path / "t.png")


def test_radiance_hdr_says_unsupported(tmp_path):
    p = tmp_path / "room.hdr"
    p.write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 1\n\x80\x80\x80\x81")
    with pytest.raises(ScanlightError, match=r"room\.hdr: Radiance \.hdr images are not supported.*EXR"):
        read_image(p)


def test_unknown_image_extension(tmp_path):
    p = tmp_path / "a.tiff"
    p.write_bytes(b"II*\x00")
    with pytest.raises(ScanlightError, match=r"a\.tiff: unsupported image file extension"):
        read_image(p)
