"""How much memory a render of a given size needs, checked before any input loads.

A render's peak memory grows with its pixels: the G-buffer and the receivers' records, Mesa's
framebuffers, the float images of the composite, the anti-aliasing samples and the outputs. On
Linux an allocation past the machine's memory does not raise MemoryError: the kernel's
out-of-memory killer ends the process without a line (exit 137, after minutes of work). So
``render``, ``turntable`` and ``view --size`` (a window's frames are renders of its size) refuse
an image whose pixels alone would need more than the memory available now, with the same
``out of memory (...)`` line as a MemoryError (app/errors.py: refusal), before loading anything.

The estimate is the image's share only (``BASE_BYTES`` + ``BYTES_PER_PIXEL`` per pixel), so it
never refuses what fits; a large cloud or asset adds its own. Measured peak resident memory of
``render --background`` (the demo's 20k-point cloud, 2026-11-27): 0.46 GB at 512 x 512, 0.95 GB
at 1024 x 1024, 2.89 GB at 2048 x 2048 - 0.3 GB and 620 bytes per pixel (an 8192 x 8192
render would need 42 GB; it ran the 24 GB machine out of memory).
"""

from __future__ import annotations

import resource

from app.errors import ScanlightError

BASE_BYTES = 300_000_000
BYTES_PER_PIXEL = 600        # a little under the measured 620: the check must not over-refuse


def available_bytes() -> int | None:
    """Memory this process can still get: the kernel's MemAvailable, or the address-space
    limit if lower; None where neither can be read (then nothing is refused)."""
    found = []
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    found.append(int(line.split()[1]) * 1024)
                    break
    except (OSError, ValueError, IndexError):
        pass
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft != resource.RLIM_INFINITY:
        found.append(int(soft))
    return min(found) if found else None


def render_bytes(width: int, height: int) -> int:
    """The estimated peak memory of a render of width x height pixels (module docstring)."""
    return BASE_BYTES + BYTES_PER_PIXEL * int(width) * int(height)


def check_render_memory(width: int, height: int) -> None:
    """Refuse (exit 3, one line) a width x height render that cannot fit in memory."""
    need, have = render_bytes(width, height), available_bytes()
    if have is not None and need > have:
        raise ScanlightError(None, f"out of memory (a {width}x{height} render needs about "
                                   f"{need / 1e9:.1f} GB; {have / 1e9:.1f} GB is available): "
                                   "give a smaller --size")
