"""The render modes, a closed list (pbrt-v4's ``Create(name, params)`` over its variants): one
class per name of app.params.RENDER_MODES, imported directly. The interface they implement is
app/pbgi/modebase.py.

    mode = create_mode("hybrid", ctx, RenderParams(mode="hybrid"))

Adding a mode: a ``RenderMode`` subclass in its own module, its name in RENDER_MODES (the table's
choices for ``pbgi.mode``) and here.
"""

from __future__ import annotations

from app.errors import ScanlightError
from app.params import RENDER_MODES
from app.pbgi.classic import ClassicMode
from app.pbgi.envmap import EnvmapMode
from app.pbgi.hybrid import HybridMode
from app.pbgi.mipmapped import MipmappedMode
from app.pbgi.modebase import RenderMode, RenderParams

MODES: dict[str, type[RenderMode]] = {
    "classic": ClassicMode,
    "mipmapped": MipmappedMode,
    "hybrid": HybridMode,
    "envmap": EnvmapMode,
}
assert tuple(MODES) == RENDER_MODES, "app.params.RENDER_MODES and MODES name the same modes"
assert all(cls.name == name for name, cls in MODES.items())


def create_mode(name: str, ctx, params: RenderParams, defines: dict | None = None) -> RenderMode:
    """A new mode object ``name`` for ``params`` (checked); ``defines`` go to its walks'
    programs (RenderMode)."""
    cls = MODES.get(name)
    if cls is None:
        raise ScanlightError(None, f"unknown render mode {name!r} (known: {', '.join(MODES)})")
    return cls(ctx, params.validated(), defines=defines)
