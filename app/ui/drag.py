"""Who owns a mouse drag, the panels or the view: decided once imgui has seen the press.

imgui says whether it wants the mouse (``io.want_capture_mouse``) only in ``new_frame``, from the
pointer position and button state it has been handed by then. Events arrive between frames, so
when the pointer leaves a panel and presses in the viewport within one frame (a quick hand, or a
long refinement frame), the flag read at the press is the one computed over the panel: the view
used to ignore that whole drag, or the part of it that arrived before the frame. The decision is
therefore deferred: a press opens a pending drag whose motion is kept, and the first frame in
which imgui holds that button down (after ``new_frame`` and the gizmo's own test of the frame)
settles it; the kept motion is then replayed into the view, or dropped when the UI owns it. The
view lags the hand by at most that one frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

# Frames a press may stay undecided (imgui's trickle queue hands one button change per frame;
# a few queued clicks ahead of this press could delay it), after which the flags of that frame
# decide.
MAX_PENDING_FRAMES = 4


@dataclass(frozen=True)
class Motion:
    """One drag event as it arrived: the pointer position (window pixels) and the modifier and
    button state of that moment."""
    x: float
    y: float
    alt: bool = False
    ctrl: bool = False
    shift: bool = False
    left: bool = True
    middle: bool = False
    right: bool = False


@dataclass(frozen=True)
class Step:
    """What the view applies: the pointer's travel since the last applied position."""
    dx: float
    dy: float
    motion: Motion


@dataclass
class DragOwner:
    """The state of the mouse drag: none, pending (pressed, not yet decided), the view's, or the
    UI's. The view's travel is measured from absolute positions (press, motions, release), so a
    motion event dropped or handed over before its press still leaves the view where the hand
    went."""
    button: int | None = None        # the imgui button of the pending or current drag
    pending: bool = False
    view_owns: bool = False
    released: bool = False
    frames_waited: int = 0
    last: tuple[float, float] = (0.0, 0.0)
    held: Motion | None = None       # the buttons and modifiers of the latest event
    kept: list[Motion] = field(default_factory=list)

    @property
    def dragging(self) -> bool:
        """The view is being dragged (or may be: a pending press counts as interaction)."""
        return self.view_owns or self.pending

    def press(self, button: int, at: Motion) -> None:
        self.button, self.pending, self.view_owns, self.released = button, True, False, False
        self.frames_waited, self.kept = 0, []
        self.last, self.held = (at.x, at.y), at

    def _steps(self, motions) -> list[Step]:
        out = []
        for m in motions:
            dx, dy = m.x - self.last[0], m.y - self.last[1]
            self.last = (m.x, m.y)
            if dx or dy:
                out.append(Step(dx, dy, m))
        return out

    def motion(self, m: Motion) -> list[Step]:
        """The view's steps for ``m`` now (none while pending: kept for ``settle``)."""
        self.held = m
        if self.pending:
            self.kept.append(m)
            return []
        return self._steps([m]) if self.view_owns else []

    def release(self, x: float, y: float) -> list[Step]:
        """The last stretch up to the release position (with the buttons and modifiers of the
        drag, not those after the release), then the drag ends."""
        if self.held is None:
            return []
        m = replace(self.held, x=float(x), y=float(y))
        if self.pending:
            self.kept.append(m)
            self.released = True     # settled later; the kept motion still belongs somewhere
            return []
        steps = self._steps([m]) if self.view_owns else []
        self.view_owns, self.button = False, None
        return steps

    def settle(self, button_seen_down: bool, ui_wants_mouse: bool) -> list[Step]:
        """Call once per frame after imgui's ``new_frame`` and the gizmo: decides a pending drag
        when imgui has seen its press (or waited long enough) and returns the steps to apply to
        the view (none when the UI owns the drag or nothing is pending)."""
        if not self.pending:
            return []
        self.frames_waited += 1
        if not button_seen_down and self.frames_waited < MAX_PENDING_FRAMES:
            return []
        self.pending = False
        self.view_owns = not ui_wants_mouse
        kept, self.kept = self.kept, []
        steps = self._steps(kept) if self.view_owns else []
        if self.released:
            self.view_owns, self.button = False, None
        return steps
