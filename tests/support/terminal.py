"""Reading what a program drew on a pseudo-terminal (the progress-bar tests)."""

from __future__ import annotations

import os
import select


def read_terminal(fd, quiet_s: float = 0.5) -> str:
    """Everything the terminal ``fd`` (a pty's master) holds, read until it stays quiet for
    ``quiet_s`` or its other end closes: a terminal hands output over in pieces."""
    out = b""
    while select.select([fd], [], [], quiet_s)[0]:
        try:
            chunk = os.read(fd, 65536)
        except OSError:                 # the other end closed
            break
        if not chunk:
            break
        out += chunk
    return out.decode(errors="replace")
