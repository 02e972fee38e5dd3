"""The one place that creates the OpenGL 4.3+ context, headless (EGL) or from a window.

Every renderer takes its context from :func:`get_context`, so the same code draws into the
viewer window and offscreen in tests and in the CLI.
"""

from __future__ import annotations

import os
import threading

import moderngl

from app.errors import ScanlightError

GL_REQUIRE = 430
_lock = threading.Lock()
_ctx: moderngl.Context | None = None
_anchor_fbo = None  # keeps a bound framebuffer alive for standalone contexts


def set_window_context(ctx: moderngl.Context) -> None:
    """Adopt the context of a moderngl-window window (called by the viewer at start-up)."""
    global _ctx
    with _lock:
        _ctx = ctx


def get_context() -> moderngl.Context:
    """The shared context; creates a headless EGL one on first use when no window set one."""
    global _ctx, _anchor_fbo
    with _lock:
        if _ctx is not None:
            return _ctx
        try:
            ctx = moderngl.create_standalone_context(backend="egl", require=GL_REQUIRE)
        except Exception as exc:  # no EGL / too old a driver: say what to install
            raise ScanlightError(None, f"cannot create a headless OpenGL {GL_REQUIRE // 100}."
                                       f"{GL_REQUIRE % 100 // 10} context via EGL ({exc}); "
                                       "install Mesa's EGL (libegl1, libgl1-mesa-dri)") from None
        # A standalone EGL context has no default framebuffer: draws and transform feedback
        # fail with GL_INVALID_FRAMEBUFFER_OPERATION (silent zeros) until one is bound.
        _anchor_fbo = ctx.simple_framebuffer((1, 1))
        _anchor_fbo.use()
        _ctx = ctx
        return ctx


def bind_anchor() -> None:
    """Re-bind the 1x1 framebuffer after a pass that used its own (headless only)."""
    if _anchor_fbo is not None:
        _anchor_fbo.use()


def renderer_name() -> str:
    ctx = get_context()
    return f"{ctx.info['GL_RENDERER']} (GL {ctx.version_code})"


# GL_RENDERER names of the CPU rasterisers Mesa ships (llvmpipe, softpipe, the old swrast).
SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast", "software rasterizer")


def is_software_renderer(renderer: str) -> bool:
    """Whether a GL_RENDERER string names a CPU rasteriser: the lobe walk picks its variant by
    it, because what is cheap on one (a per-invocation table in private memory) is dear on a GPU
    (app/pbgi/lobe.py: LobeWalkTuning)."""
    name = renderer.lower()
    return any(s in name for s in SOFTWARE_RENDERERS)


def is_headless_display() -> bool:
    return not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY")
