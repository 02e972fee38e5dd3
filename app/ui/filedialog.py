"""File dialogs: the desktop's native dialog through imgui-bundle's portable-file-dialogs when the
desktop has a dialog program (zenity or kdialog), else a small browser drawn with imgui (always
works, including under Xvfb). Both are non-blocking: the frame loop keeps running and the
callback gets the chosen path on the main thread.

``FileDialog(native=False)`` always uses the imgui browser (``scanlight view --no-native-dialogs``:
for desktops whose dialog program misbehaves, and for automated runs, where a desktop dialog
would wait for a person).
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from imgui_bundle import imgui


def native_available() -> bool:
    """Does the desktop have a dialog program portable-file-dialogs can drive?"""
    return bool(shutil.which("zenity") or shutil.which("kdialog"))


@dataclass
class _Request:
    title: str
    extensions: tuple[str, ...]
    callback: Callable[[str], None]
    save: bool
    default_name: str = ""


class FileDialog:
    POPUP = "Choose a file##scanlight-file-dialog"

    def __init__(self, native: bool | None = None):
        """``native``: True/False use or avoid the desktop's dialog; None uses it when found."""
        self.native = native
        self.request: _Request | None = None
        self.folder = Path.cwd()
        self.name = ""
        self._native = None
        self._open_popup = False

    @property
    def active(self) -> bool:
        return self.request is not None

    def open(self, title: str, extensions, callback, save: bool = False, default_name: str = ""):
        self.request = _Request(title, tuple(e.lower() for e in extensions), callback, save,
                                default_name)
        self.name = default_name
        if native_available() if self.native is None else self.native:
            from imgui_bundle import portable_file_dialogs as pfd
            filters = [title, " ".join(f"*{e}" for e in extensions) or "*"]
            start = str(self.folder / default_name)
            self._native = (pfd.save_file(title, start, filters) if save
                            else pfd.open_file(title, str(self.folder), filters))
        else:
            self._open_popup = True

    def _finish(self, path: str | None) -> None:
        req, self.request, self._native = self.request, None, None
        if path:
            self.folder = Path(path).parent
            req.callback(path)

    def draw(self) -> None:
        if self.request is None:
            return
        if self._native is not None:
            if self._native.ready(0):
                res = self._native.result()
                self._finish(res if isinstance(res, str) else (res[0] if res else None))
            return
        if self._open_popup:
            imgui.open_popup(self.POPUP)
            self._open_popup = False
        imgui.set_next_window_size((560, 420), imgui.Cond_.appearing)
        opened, _ = imgui.begin_popup_modal(self.POPUP)
        if not opened:
            return
        req = self.request
        imgui.text(req.title)
        changed, text = imgui.input_text("folder", str(self.folder))
        if changed and Path(text).is_dir():
            self.folder = Path(text)
        imgui.begin_child("entries", (0, -60), imgui.ChildFlags_.borders)
        if imgui.selectable("..", False)[0]:
            self.folder = self.folder.parent
        try:
            entries = sorted(self.folder.iterdir(), key=lambda p: (not p.is_dir(), p.name.lower()))
        except OSError as exc:
            entries = []
            imgui.text_colored((1, 0.4, 0.4, 1), f"cannot list folder: {exc}")
        for p in entries:
            if p.name.startswith("."):
                continue
            if p.is_dir():
                if imgui.selectable(p.name + "/", False)[0]:
                    self.folder = p
            elif not req.extensions or p.suffix.lower() in req.extensions:
                clicked, _ = imgui.selectable(p.name, p.name == self.name,
                                              imgui.SelectableFlags_.allow_double_click)
                if clicked:
                    self.name = p.name
                    if imgui.is_mouse_double_clicked(0):
                        imgui.close_current_popup()
                        imgui.end_popup()
                        self._finish(str(p))
                        return
        imgui.end_child()
        _, self.name = imgui.input_text("file name", self.name)
        ok = imgui.button("Save" if req.save else "Open")
        imgui.same_line()
        cancel = imgui.button("Cancel")
        if ok and self.name:
            imgui.close_current_popup()
            imgui.end_popup()
            self._finish(str(self.folder / self.name))
            return
        if cancel:
            imgui.close_current_popup()
            imgui.end_popup()
            self._finish(None)
            return
        imgui.end_popup()
