"""HDR (and LDR) images in, OpenEXR out: every image becomes float32 linear RGB.

Readers return a ``LinearImage``: the pixels plus a report of what was repaired (negative, NaN and
+Inf pixels, see app.io.clean), so callers can show the user what the file really held. Radiance
``.hdr`` is refused with a clear message: no maintained reader is installed (imageio needs a
FreeImage download, Pillow cannot read it), and OpenEXR covers the same use.
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from app.color import srgb_to_linear
from app.errors import ScanlightError
from app.io.clean import HALF_MAX, clean_rgb, describe_counts
from app.io.files import atomic_output, require_file
from app.io.limits import MAX_IMAGE_PIXELS

log = logging.getLogger(__name__)

EXR_EXTENSIONS = (".exr",)
HDR_EXTENSIONS = (".hdr", ".pic")
LDR_EXTENSIONS = (".png", ".jpg", ".jpeg")
IMAGE_EXTENSIONS = EXR_EXTENSIONS + HDR_EXTENSIONS + LDR_EXTENSIONS


@dataclass
class LinearImage:
    """rgb: (H, W, 3) float32 linear radiance (finite, >= 0); hdr: False for sRGB-decoded LDR."""

    rgb: np.ndarray
    hdr: bool
    source: str | None = None
    report: dict = field(default_factory=dict)

    @property
    def shape(self) -> tuple[int, int]:
        return self.rgb.shape[:2]


def _finish(rgb: np.ndarray, hdr: bool, path: Path, report: dict) -> LinearImage:
    rgb, counts = clean_rgb(rgb, "pixels")
    report.update(counts)
    if any(counts.values()):
        msg = describe_counts(counts)
        report.setdefault("warnings", []).append(msg)
        log.warning("%s: %s", path, msg)
    return LinearImage(rgb, hdr, str(path), report)


def _pick_rgb(channels: dict, path: Path) -> np.ndarray:
    """(H, W, 3) from separately read EXR channels: R,G,B (A ignored), else Y as grey."""
    names = set(channels)
    if {"R", "G", "B"} <= names:
        planes = [channels[c].pixels for c in "RGB"]
    elif "Y" in names:
        if names & {"RY", "BY"}:
            raise ScanlightError(path, "luminance/chroma (YC) EXR images are not supported; "
                                       "save it as RGB")
        planes = [channels["Y"].pixels] * 3
    else:
        raise ScanlightError(path, f"EXR has no R,G,B or Y channels (found: "
                                   f"{', '.join(sorted(names)) or 'none'})")
    shapes = {p.shape for p in planes}
    if len(shapes) != 1 or len(next(iter(shapes))) != 2:
        raise ScanlightError(path, "EXR colour channels are subsampled or differ in size")
    return np.stack([np.asarray(p, dtype=np.float32) for p in planes], axis=-1)




def _check_pixels(p: Path, width: int, height: int) -> None:
    if width * height > MAX_IMAGE_PIXELS:
        raise ScanlightError(p, f"image of {width}x{height} pixels is larger than the limit of "
                                f"{MAX_IMAGE_PIXELS:,} pixels")


def read_exr(path) -> LinearImage:
    """An OpenEXR image: half or float; RGB, RGBA -> RGB, Y -> grey; the first part only."""
    p = require_file(path, "EXR image", EXR_EXTENSIONS)
    import OpenEXR

    try:   # the size first, from the header alone: nothing is allocated for a huge image
        with OpenEXR.File(str(p), header_only=True) as f:
            windows = [part.header["dataWindow"] for part in f.parts]
        # every part is decoded when the file is opened, so all of them count
        sizes = [(int(hi[0]) - int(lo[0]) + 1, int(hi[1]) - int(lo[1]) + 1) for lo, hi in windows]
        if len(sizes) == 1:
            _check_pixels(p, *sizes[0])
        elif sum(w * h for w, h in sizes) > MAX_IMAGE_PIXELS:
            raise ScanlightError(p, f"EXR of {len(sizes)} parts holds "
                                    f"{sum(w * h for w, h in sizes):,} pixels, more than the "
                                    f"limit of {MAX_IMAGE_PIXELS:,}")
    except ScanlightError:
        raise
    except Exception as exc:  # OpenEXR raises RuntimeError/ValueError for corrupt files
        raise ScanlightError(p, f"corrupt or truncated EXR ({exc})") from None
    try:
        with OpenEXR.File(str(p), separate_channels=True) as f:
            n_parts = len(f.parts)
            if n_parts == 0:
                raise ValueError("file has no readable parts")
            rgb = _pick_rgb(f.parts[0].channels, p)
    except ScanlightError:
        raise
    except Exception as exc:  # OpenEXR raises RuntimeError/ValueError for corrupt files
        raise ScanlightError(p, f"corrupt or truncated EXR ({exc})") from None
    if rgb.size == 0:
        raise ScanlightError(p, "EXR image has no pixels")
    report = {"parts": n_parts} if n_parts > 1 else {}
    return _finish(rgb, True, p, report)


def write_exr(path, rgb, half: bool = False) -> None:
    """Write (H, W, 3) linear RGB (or (H, W) as Y) atomically, ZIP-compressed.

    half=True stores float16; values are first clipped to +-65504 so no Inf is written.
    Non-finite input is a programming error (ValueError): files we write never hold NaN/Inf.
    """
    import OpenEXR

    a = np.asarray(rgb, dtype=np.float32)
    if not (a.ndim == 2 or (a.ndim == 3 and a.shape[2] == 3)) or a.size == 0:
        raise ValueError(f"write_exr needs a non-empty (H, W, 3) or (H, W) array, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError("write_exr: image holds NaN or Inf")
    if half:
        a = np.clip(a, -HALF_MAX, HALF_MAX).astype(np.float16)
    channels = {"Y": np.ascontiguousarray(a)} if a.ndim == 2 else {"RGB": np.ascontiguousarray(a)}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with atomic_output(path) as tmp:
        with OpenEXR.File(header, channels) as f:
            f.write(str(tmp))


def read_hdr(path) -> LinearImage:
    """Radiance RGBE images are not supported: say so, and how to get an EXR instead."""
    p = require_file(path, "Radiance HDR image", HDR_EXTENSIONS)
    raise ScanlightError(p, "Radiance .hdr images are not supported (no maintained reader is "
                            "installed); convert it to OpenEXR (.exr), e.g. with "
                            "'oiiotool in.hdr -o out.exr' or GIMP")


def read_ldr(path) -> LinearImage:
    """An 8-bit (or 16-bit grey) PNG/JPEG, decoded from sRGB to linear; alpha is dropped."""
    p = require_file(path, "image", LDR_EXTENSIONS)
    from PIL import Image, UnidentifiedImageError

    try:
        with warnings.catch_warnings():
            # Pillow's own bomb check warns above 89 Mpixel and fails above twice that, on
            # open: ours (MAX_IMAGE_PIXELS, from the header) is the one that applies
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(p) as im:
                _check_pixels(p, *im.size)      # from the header, before decoding
                im.load()
                if im.mode.startswith("I;16") or im.mode == "I":
                    v = np.asarray(im, dtype=np.float32) / 65535.0
                    enc = np.repeat(np.clip(v, 0.0, 1.0)[..., None], 3, axis=-1)
                else:
                    enc = np.asarray(im.convert("RGB"), dtype=np.float32) / 255.0
    except Image.DecompressionBombError:
        raise ScanlightError(p, f"image too large: more than the limit of "
                                f"{MAX_IMAGE_PIXELS:,} pixels (a decompression bomb?)") from None
    except (OSError, UnidentifiedImageError, SyntaxError, ValueError) as exc:
        raise ScanlightError(p, f"corrupt or truncated image ({exc})") from None
    return _finish(srgb_to_linear(enc), False, p, {})


def read_image(path) -> LinearImage:
    """Any supported image by extension: EXR (HDR), Radiance .hdr (refused), PNG/JPEG (LDR)."""
    ext = Path(path).suffix.lower()
    if ext in EXR_EXTENSIONS:
        return read_exr(path)
    if ext in HDR_EXTENSIONS:
        return read_hdr(path)
    if ext in LDR_EXTENSIONS:
        return read_ldr(path)
    require_file(path, "image", IMAGE_EXTENSIONS)  # raises: unsupported extension
    raise AssertionError("unreachable")
