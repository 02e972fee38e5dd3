"""Display: exposure, tone mapper, which cloud colours, field of view, splat size, gizmos."""

from __future__ import annotations

from app.ui import widgets

KEYS = ("view.exposure", "view.tonemap", "view.cloud", "view.fov_y", "view.splat_scale",
        "view.show_cameras", "view.show_gizmo", "view.fly_speed")


def draw(ui) -> None:
    widgets.group(ui.session.settings, KEYS)
