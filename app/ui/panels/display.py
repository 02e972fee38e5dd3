"""Display: exposure, tone mapper, which cloud colours, field of view, splat size, gizmos."""

from __future__ import annotations

from app.ui import widgets


def draw(ui) -> None:
    widgets.panel_group(ui.session.settings, "view")
