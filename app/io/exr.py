"""HDR (and LDR) images in, OpenEXR out: every image becomes float32 linear RGB.

Readers return a ``LinearImage``: the pixels plus a report of what was repaired (negative, NaN and
+Inf pixels, see app.io.clean), so callers can show the user what the file really held. Radiance
``.hdr`` is refused with a clear message: no maintained reader is installed (imageio needs a
FreeImage download, Pillow cannot read it), and OpenEXR covers the same use.

Renders carry their coverage: ``write_exr`` takes RGBA (channels R, G, B, A, premultiplied as
OpenEXR expects), and ``write_exr_layers`` writes compositing layers into one single-part file as
``<layer>.R/G/B[/A]`` (or ``<layer>.Y``), the channel naming Nuke, Blender and OpenEXR's own
tools group into layers. ``read_exr_layers`` reads them back; ``read_exr`` of such a file shows
its "beauty" layer (else the first RGB layer) and says which in ``report["layer"]``.
"""

from __future__ import annotations

import logging
import os
import re
import threading
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from app.color import srgb_to_linear
from app.errors import ScanlightError
from app.io.clean import HALF_MAX, clean_rgb, describe_counts
from app.io.files import WriteError, atomic_output, require_file
from app.io.limits import MAX_IMAGE_PIXELS

log = logging.getLogger(__name__)

EXR_EXTENSIONS = (".exr",)
HDR_EXTENSIONS = (".hdr", ".pic")
LDR_EXTENSIONS = (".png", ".jpg", ".jpeg")
IMAGE_EXTENSIONS = EXR_EXTENSIONS + HDR_EXTENSIONS + LDR_EXTENSIONS

# header attribute of write_exr_layers: the layers' order (channels are stored sorted by name)
LAYERS_ATTRIBUTE = "scanlightLayers"
_LAYER_NAME = re.compile(r"[A-Za-z0-9_]+")


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


def _pick_rgb(channels: dict, path: Path, layer_order=None) -> tuple[np.ndarray, str | None]:
    """(H, W, 3) from separately read EXR channels (name -> pixels): R,G,B (A ignored), else Y
    as grey; a file holding only layered channels gives its "beauty" layer, else the first layer
    with R,G,B (``layer_order``, else sorted), so our own --layers files open in the viewer. The
    second value names the layer used (None: the unprefixed channels)."""
    names = set(channels)
    layer = None
    if {"R", "G", "B"} <= names:
        planes = [channels[c] for c in "RGB"]
    elif "Y" in names:
        if names & {"RY", "BY"}:
            raise ScanlightError(path, "luminance/chroma (YC) EXR images are not supported; "
                                       "save it as RGB")
        planes = [channels["Y"]] * 3
    else:
        groups = _layer_groups(names)
        rgb_layers = [n for n in _ordered(groups, layer_order)
                      if n and {"R", "G", "B"} <= groups[n]]
        if not rgb_layers:
            raise ScanlightError(path, f"EXR has no R,G,B or Y channels (found: "
                                       f"{', '.join(sorted(names)) or 'none'})")
        layer = "beauty" if "beauty" in rgb_layers else rgb_layers[0]
        planes = [channels[f"{layer}.{c}"] for c in "RGB"]
    return _stack(planes, path), layer


def _stack(planes: list, path: Path) -> np.ndarray:
    shapes = {p.shape for p in planes}
    if len(shapes) != 1 or len(next(iter(shapes))) != 2:
        raise ScanlightError(path, "EXR colour channels are subsampled or differ in size")
    return np.stack([np.asarray(p, dtype=np.float32) for p in planes], axis=-1)


def _layer_groups(names) -> dict[str, set[str]]:
    """Channel names grouped by layer: "a.b.R" -> layer "a.b", channel "R"; "R" -> layer ""."""
    groups: dict[str, set[str]] = {}
    for name in names:
        layer, _, chan = name.rpartition(".")
        groups.setdefault(layer, set()).add(chan)
    return groups


def _ordered(groups: dict, layer_order) -> list[str]:
    """The layers in the order the file's attribute lists (its own names only), then the rest
    sorted: the channels themselves are stored sorted by name, so the order is lost without it."""
    first = [n for n in (layer_order or []) if n in groups]
    return first + sorted(n for n in groups if n not in first)


def _layer_order(header: dict) -> list[str] | None:
    value = header.get(LAYERS_ATTRIBUTE)
    return value.split(",") if isinstance(value, str) and value else None


def _check_pixels(p: Path, width: int, height: int) -> None:
    if width * height > MAX_IMAGE_PIXELS:
        raise ScanlightError(p, f"image of {width}x{height} pixels is larger than the limit of "
                                f"{MAX_IMAGE_PIXELS:,} pixels")


@contextmanager
def _library_output():
    """What the OpenEXR library prints while a file is read, collected into the list it yields:
    for a truncated file its core writes "(EXR_ERR_BAD_CHUNK_LEADER) ..." to file descriptor 2
    and its Python binding "Warning: Exception raised ..." to sys.stdout, where a command's
    results go - two lines besides our one. Only on the main thread (the command line): in a
    worker it would also swallow the other threads' output (descriptor 2 and sys.stdout are the
    process's, not the thread's; the main thread's progress lines would vanish into the error).
    So a command that works in a thread reads its images on the main thread first, as
    ``expand`` does (app.hdr.job.ExpandRequest.with_photo_read); a worker process reads them on
    its own main thread."""
    out: list[str] = []
    if threading.current_thread() is not threading.main_thread():
        yield out
        return
    import io
    import sys
    import tempfile
    sys.stderr.flush()
    saved_fd, saved_py = os.dup(2), (sys.stdout, sys.stderr)
    said = io.StringIO()
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        sys.stdout = sys.stderr = said
        try:
            yield out
        finally:
            sys.stdout, sys.stderr = saved_py
            os.dup2(saved_fd, 2)
            os.close(saved_fd)
            tmp.seek(0)
            out.append(tmp.read().decode(errors="replace") + " " + said.getvalue())


def _open_exr(p: Path):
    """(first part's channels: name -> 2-D pixels, its header, number of parts); the size is
    checked from the header alone first, so nothing is allocated for a huge image. What the
    library prints goes into the one-line error of a failed read, or one warning line."""
    err = None
    with _library_output() as said:
        try:
            result = _read_exr_parts(p)
        except ScanlightError as e:
            err = e
    text = " ".join("".join(said).split())[:300]
    if err is not None:
        if text:
            raise ScanlightError(err.path, f"{err.reason}; the OpenEXR library said: {text}")
        raise err
    if text:
        log.warning("%s: the OpenEXR library said: %s", p, text)
    return result


def _read_exr_parts(p: Path):
    import contextlib

    with contextlib.ExitStack() as stack:
        return _read_exr_named(p, _library_path(p, stack))


def _library_path(p: Path, stack) -> str:
    """A name OpenEXR can open for ``p``: its own, or - when it holds bytes that are not UTF-8,
    which the binding refuses ("pass a filesystem path as str") - the descriptor of the file
    opened here (/proc/self/fd/N, Linux), closed when ``stack`` closes."""
    name = str(p)
    try:
        name.encode("utf-8")
        return name
    except UnicodeEncodeError:
        fd = os.open(p, os.O_RDONLY)
        stack.callback(os.close, fd)
        return f"/proc/self/fd/{fd}"


def _read_exr_named(p: Path, name: str):
    import OpenEXR

    try:
        with OpenEXR.File(name, header_only=True) as f:
            windows = [part.header["dataWindow"] for part in f.parts]
        # every part is decoded when the file is opened, so all of them count
        sizes = [(int(hi[0]) - int(lo[0]) + 1, int(hi[1]) - int(lo[1]) + 1) for lo, hi in windows]
        if len(sizes) == 1:
            _check_pixels(p, *sizes[0])
        elif sum(w * h for w, h in sizes) > MAX_IMAGE_PIXELS:
            raise ScanlightError(p, f"EXR of {len(sizes)} parts holds "
                                    f"{sum(w * h for w, h in sizes):,} pixels, more than the "
                                    f"limit of {MAX_IMAGE_PIXELS:,}")
        with OpenEXR.File(name, separate_channels=True) as f:
            if len(f.parts) == 0:
                raise ValueError("file has no readable parts")
            # the pixel arrays, taken while the file is open (its channel dict empties on close)
            return ({name: ch.pixels for name, ch in f.parts[0].channels.items()},
                    dict(f.parts[0].header), len(f.parts))
    except ScanlightError:
        raise
    except Exception as exc:  # OpenEXR raises RuntimeError/ValueError for corrupt files
        raise ScanlightError(p, f"corrupt or truncated EXR ({exc})") from None


def read_exr(path) -> LinearImage:
    """An OpenEXR image: half or float; RGB, RGBA -> RGB, Y -> grey; the first part only.
    A file of layered channels only (write_exr_layers) gives its "beauty" layer, else the first
    layer with R,G,B; ``report["layer"]`` names it."""
    p = require_file(path, "EXR image", EXR_EXTENSIONS)
    channels, header, n_parts = _open_exr(p)
    rgb, layer = _pick_rgb(channels, p, _layer_order(header))
    if rgb.size == 0:
        raise ScanlightError(p, "EXR image has no pixels")
    report = {"parts": n_parts} if n_parts > 1 else {}
    if layer is not None:
        report["layer"] = layer
        log.info("%s: no plain R,G,B channels; showing layer %r", p, layer)
    return _finish(rgb, True, p, report)


def read_exr_layers(path) -> dict[str, np.ndarray]:
    """Every layer of an EXR's first part, float32 as stored (not repaired: a compositing layer's
    negative or alpha values are the caller's to judge): ``<layer>.R/G/B`` -> (H, W, 3), with
    ``<layer>.A`` -> (H, W, 4), ``<layer>.Y`` alone -> (H, W). Plain R,G,B(,A) or Y come back as
    layer "". Groups that are not colour (e.g. Blender's Normal.X/Y/Z, depth Z) are skipped.
    In the order written (the ``scanlightLayers`` attribute), else sorted by name."""
    p = require_file(path, "EXR image", EXR_EXTENSIONS)
    channels, header, _ = _open_exr(p)
    groups = _layer_groups(channels)
    out: dict[str, np.ndarray] = {}
    for layer in _ordered(groups, _layer_order(header)):
        chans = groups[layer]
        key = (lambda c: f"{layer}.{c}") if layer else (lambda c: c)
        if {"R", "G", "B"} <= chans:
            names = list("RGBA" if "A" in chans else "RGB")
            out[layer] = _stack([channels[key(c)] for c in names], p)
        elif "Y" in chans and not chans & {"X", "Z", "RY", "BY"}:   # not a vector, not YC
            out[layer] = _stack([channels[key("Y")]], p)[..., 0]
        else:
            log.debug("%s: channels %s of layer %r are not a colour layer; skipped", p,
                      sorted(chans), layer)
    if not out:
        raise ScanlightError(p, f"EXR has no R,G,B or Y channels in any layer (found: "
                                f"{', '.join(sorted(channels)) or 'none'})")
    if any(a.size == 0 for a in out.values()):
        raise ScanlightError(p, "EXR image has no pixels")
    return out


def _exr_pixels(image, half: bool, what: str) -> np.ndarray:
    """float32 (or clipped float16) (H, W), (H, W, 3) or (H, W, 4); ValueError otherwise."""
    a = np.asarray(image, dtype=np.float32)
    if not (a.ndim == 2 or (a.ndim == 3 and a.shape[2] in (3, 4))) or a.size == 0:
        raise ValueError(f"{what} needs a non-empty (H, W, 3), (H, W, 4) or (H, W) array, "
                         f"got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{what}: image holds NaN or Inf")
    if half:
        a = np.clip(a, -HALF_MAX, HALF_MAX).astype(np.float16)
    return np.ascontiguousarray(a)


def _write_channels(path, channels: dict, extra_header: dict | None = None) -> None:
    import OpenEXR

    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    header.update(extra_header or {})
    with atomic_output(path) as tmp:
        with OpenEXR.File(header, channels) as f:
            try:
                f.write(str(tmp))
            except RuntimeError as exc:     # "Failed to write pixel data ... No space left"
                raise WriteError(str(exc).split(". ", 1)[-1] or str(exc)) from None


def write_exr(path, image, half: bool = False) -> None:
    """Write (H, W, 3) linear RGB, (H, W, 4) RGBA (alpha = coverage, RGB premultiplied as
    OpenEXR expects) or (H, W) as Y, atomically, ZIP-compressed.

    half=True stores float16; values are first clipped to +-65504 so no Inf is written.
    Non-finite input is a programming error (ValueError): files we write never hold NaN/Inf.
    """
    a = _exr_pixels(image, half, "write_exr")
    _write_channels(path, {"Y" if a.ndim == 2 else "RGBA"[:a.shape[2]]: a})


def write_exr_layers(path, layers: dict, half: bool = False) -> None:
    """Write compositing layers into ONE single-part scanline EXR, atomically, ZIP-compressed.

    ``layers``: name -> (H, W, 3) / (H, W, 4) / (H, W) (a dict, or (name, image) pairs), all
    of one size, stored as channels ``<name>.R/G/B[/A]`` or ``<name>.Y``: the layer convention
    Nuke, Blender and OpenEXR's tools read, where a multi-part file would not open everywhere
    (nor in read_exr, which reads the first part). OpenEXR stores channels sorted by
    name, so the order given is kept in the ``scanlightLayers`` header attribute for
    read_exr_layers. Bad names (not [A-Za-z0-9_]+ or repeated), sizes or NaN/Inf are programming
    errors (ValueError), as in write_exr; half=True clips and rounds as there.
    """
    items = list(layers.items()) if hasattr(layers, "items") else list(layers)
    if not items:
        raise ValueError("write_exr_layers needs at least one layer")
    names = [name for name, _ in items]
    for name in names:
        if not isinstance(name, str) or not _LAYER_NAME.fullmatch(name):
            raise ValueError(f"write_exr_layers: layer name {name!r} is not [A-Za-z0-9_]+")
    if len(set(names)) != len(names):
        raise ValueError(f"write_exr_layers: layer names repeat ({', '.join(names)})")
    channels = {}
    size = None
    for name, image in items:
        a = _exr_pixels(image, half, f"write_exr_layers (layer {name!r})")
        if size is None:
            size = a.shape[:2]
        elif a.shape[:2] != size:
            raise ValueError(f"write_exr_layers: layer {name!r} is {a.shape[1]}x{a.shape[0]}, "
                             f"not {size[1]}x{size[0]} like the first")
        if a.ndim == 2:
            channels[f"{name}.Y"] = a
        else:
            for i, c in enumerate("RGBA"[:a.shape[2]]):
                channels[f"{name}.{c}"] = np.ascontiguousarray(a[..., i])
    _write_channels(path, channels, {LAYERS_ATTRIBUTE: ",".join(names)})


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
