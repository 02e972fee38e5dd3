"""The GL textures that imgui panels show (photo thumbnail, cube-map preview), owned in one place.

``imgui.image(tex.glo, ...)`` does not draw: it queues a draw command that the imgui renderer
executes at the end of the frame, after every panel ran. A panel that released a texture in the
same frame in which it (or an earlier panel) had queued it - "Run expansion" dropped the photo
thumbnail right after drawing it - left a command naming an unregistered texture, and the
renderer raised ("Texture N is not registered") and closed the window. So textures are never
released where they are dropped: ``drop`` retires them, and the window calls ``end_frame`` after
imgui has rendered the frame; only then are the retired ones unregistered and freed. ``clear``
(a new session) retires everything the same way.
"""

from __future__ import annotations

import numpy as np


class PanelTextures:
    """Named RGBA8 textures registered with the imgui renderer; see the module docstring."""

    def __init__(self, ctx, renderer):
        self.ctx = ctx
        self.renderer = renderer          # anything with register_texture / remove_texture
        self._live: dict[str, object] = {}
        self._retired: list = []

    def get(self, name: str):
        return self._live.get(name)

    def set(self, name: str, rgb: np.ndarray):
        """Upload (H, W, 3) uint8 (top row first) as texture ``name``; the one it replaces is
        retired, not freed (it may be queued for this frame)."""
        h, w = rgb.shape[:2]
        rgba = np.concatenate([rgb, np.full((h, w, 1), 255, np.uint8)], axis=-1)
        tex = self.ctx.texture((w, h), 4, np.ascontiguousarray(rgba).tobytes())
        self.renderer.register_texture(tex)
        self.drop(name)
        self._live[name] = tex
        return tex

    def drop(self, name: str) -> None:
        """Forget texture ``name`` (re-made on next use); freed after the frame is rendered."""
        tex = self._live.pop(name, None)
        if tex is not None:
            self._retired.append(tex)

    def clear(self) -> None:
        for name in list(self._live):
            self.drop(name)

    def end_frame(self) -> None:
        """Free what was retired: call after the imgui renderer has drawn the frame."""
        retired, self._retired = self._retired, []
        for tex in retired:
            self.renderer.remove_texture(tex)
            tex.release()

    @property
    def retired(self) -> int:
        return len(self._retired)

    def release(self) -> None:
        self.clear()
        self.end_frame()
