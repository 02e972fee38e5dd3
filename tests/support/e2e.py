"""Drive a real `scanlight view` window from a test: start it under the test's X display with
the observing hook (tests/ui/e2e_probe.py), find widgets by label in the rectangles it reports,
and act through the X server (tests/support/xinput.py)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PROBE = ROOT / "tests" / "ui" / "e2e_probe.py"


class ViewerProcess:
    def __init__(self, out: Path, config: Path, args=(), size=(1280, 800), cwd: Path | None = None):
        from tests.support.xinput import XInput
        self.out = Path(out)
        self.out.mkdir(parents=True, exist_ok=True)
        for stale in ("state.json", "request.json"):
            (self.out / stale).unlink(missing_ok=True)
        self.size = size
        env = dict(os.environ, SCANLIGHT_CONFIG=str(config), PYTHONPATH=str(ROOT))
        cmd = [sys.executable, "-m", "app", "view", *args, "--size", f"{size[0]}x{size[1]}",
               "--script", str(PROBE), "--script-arg", f"out={self.out}", "--no-native-dialogs"]
        self.log = open(self.out / "viewer.log", "w")
        self.proc = subprocess.Popen(cmd, cwd=cwd or self.out, env=env, stdout=self.log,
                                     stderr=subprocess.STDOUT)
        self.requests = 0
        self.x = XInput()
        self.wait(lambda s: s["frame"] >= 3, 120, "the first frames")
        origin = None
        for _ in range(100):
            origin = self.x.window_origin("Scanlight")
            if origin is not None:
                break
            time.sleep(0.1)
        assert origin is not None, "the viewer's X window was not found"
        self.x.origin = origin

    # -- observing -------------------------------------------------------------------------------
    def state(self) -> dict:
        for _ in range(50):
            try:
                return json.loads((self.out / "state.json").read_text())
            except (OSError, ValueError):
                time.sleep(0.05)
        raise AssertionError("the probe wrote no state")

    def wait(self, pred, timeout: float, what: str) -> dict:
        end = time.monotonic() + timeout
        last = None
        while time.monotonic() < end:
            if self.proc.poll() is not None:
                raise AssertionError(f"the viewer exited ({self.proc.returncode}) while waiting "
                                     f"for {what}:\n{self.log_text()[-3000:]}")
            try:
                last = json.loads((self.out / "state.json").read_text())
            except (OSError, ValueError):
                time.sleep(0.05)
                continue
            if pred(last):
                return last
            time.sleep(0.05)
        raise AssertionError(f"timed out after {timeout} s waiting for {what}; last state: "
                             f"{json.dumps({k: v for k, v in (last or {}).items() if k != 'rects'})[:3000]}")

    def frames(self, n: int = 3, timeout: float = 60) -> dict:
        """Wait until ``n`` more frames were drawn (imgui needs a frame or two per event)."""
        f0 = self.state()["frame"]
        return self.wait(lambda s: s["frame"] >= f0 + n, timeout, f"{n} frames")

    def log_text(self) -> str:
        if not self.log.closed:
            self.log.flush()
        return (self.out / "viewer.log").read_text(errors="replace")

    def rect(self, label: str, fresh: bool = True) -> list[float]:
        """The last rectangle of the widget labelled ``label`` (the exact imgui label, or its
        visible part before '##'); ``fresh``: drawn within the last few frames."""
        s = self.state()
        hits = [(k, r) for k, r in s["rects"].items() if k == label or k.split("##")[0] == label]
        if fresh:
            hits = [(k, r) for k, r in hits if r[4] >= s["frame"] - 5]
        assert hits, f"no widget labelled {label!r} on screen (frame {s['frame']})"
        exact = [h for h in hits if h[0] == label]
        return (exact or hits)[0][1]

    def visible(self, label: str) -> bool:
        try:
            self.rect(label)
            return True
        except AssertionError:
            return False

    def centre(self, label: str) -> tuple[float, float]:
        x0, y0, x1, y1 = self.rect(label)[:4]
        return (x0 + x1) / 2, (y0 + y1) / 2

    # -- acting ----------------------------------------------------------------------------------
    def show(self, label: str, panel_x: float = 150) -> list[float]:
        """Scroll the panel column with the wheel until ``label`` is fully inside the window;
        its rectangle."""
        for _ in range(40):
            r = self.rect(label)
            if r[1] >= 0 and r[3] <= self.size[1] - 4:
                return r
            self.x.scroll(panel_x, self.size[1] / 2, -1 if r[3] > self.size[1] - 4 else 1)
            self.frames(2)
        raise AssertionError(f"could not scroll {label!r} into view: {self.rect(label)}")

    def click(self, label: str, **kw) -> None:
        """Hover ``label``, wait until its rectangle is steady (the panel may still be
        settling from the last click), then click it."""
        self.show(label)
        for _ in range(10):
            before = self.centre(label)
            self.x.move(*before, 0.05)
            self.frames(3)
            if self.centre(label) == before:
                break
        kw.setdefault("settle_s", 0.1)
        self.x.click(*self.centre(label), **kw)
        self.frames(3)

    def shot(self, name: str, timeout: float = 120) -> Path:
        self.requests += 1
        rid = self.requests
        tmp = self.out / "request.tmp"
        tmp.write_text(json.dumps({"id": rid, "shot": name}))
        tmp.replace(self.out / "request.json")
        self.wait(lambda s: rid in s["done"], timeout, f"screenshot {name}")
        return self.out / f"{name}.png"

    def close(self, timeout: float = 60) -> int:
        """Close the window as a window manager's close button does."""
        self.x.close_window("Scanlight")
        try:
            return self.proc.wait(timeout)
        finally:
            self.x.close()
            self.log.close()

    def kill(self) -> None:
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait(30)
        self.x.close()
        self.log.close()

    def stop(self) -> None:
        """Teardown after a failure: never leave a window running."""
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(30)
        if not self.log.closed:
            self.log.close()
