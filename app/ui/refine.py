"""Progressive refinement of the relit asset, so the UI never waits for a whole GI frame.

The GI render runs on the main thread (it needs the GL context) and on a CPU rasteriser one
full-resolution frame can take seconds. So the layer is built in two steps, each inside a per-frame
time budget:

1. *Preview* (every time the view, a material or a PBGI setting changes): the gather runs on a
   camera of ``preview_scale`` (default 1/4) times the resolution, only over the asset's screen
   rectangle. The compositor (shaders/viewer_composite.glsl) upsamples it with joint bilateral
   weights guided by a full-resolution G-buffer of the asset (normal and depth, rasterised every
   frame), as Ritschel et al. 2009 Section 2.4 do, so the silhouette is sharp at once and colours
   do not bleed across depth edges. One render call cannot be interrupted, so the scale is
   chosen *before* rendering from the measured cost per pixel (about one frame budget, never
   below 1/16; 1/16 for the very first one) and adapted after it: slow previews lower it,
   fast ones climb back to the setting.
2. *Tiles* (only once nothing has changed for a frame): the layer is re-rendered at full layer
   resolution in strips of square cells, centre rows first. The cell side (8..256 px) and the
   strip length come from the measured cost per pixel so each frame stays near the budget (at
   least one cell per frame, so refinement always advances). Cells not yet rendered keep
   showing the upsampled preview. On a CPU rasteriser the cost keeps cells at 8-32 px; on a GPU
   a pixel costs 2-4 us and cells grow to 64-128 px: a 64 px cell (4096 receivers) neither
   fills a GPU nor pays for a render call's set-up (the orbit measured with caps of 64 to 512
   px: README, "On a GPU, a third session"). ``progress`` tells the UI how far it got,
   ``status_words`` says it in words with the time left.

The time left: the GI render is only part of a frame (the room, the composite, imgui and the
window's own waiting take the rest), so the estimate comes from the wall-clock time between the
frames that ran tiles, not from the render times: ``wall * (1 - p) / p`` for the fraction ``p``
of cells done in ``wall`` seconds, where ``wall`` adds up, for each frame that ran tiles, the
time since the end of the previous frame's GI step. Frames in which the tiles wait (the user is
interacting) do not count. The total ``wall / p`` is smoothed (the centre rows, on the asset,
cost more than the edges), and the words round it coarsely so that they do not flicker from
frame to frame. Until 5% of the cells and half a second of wall time are in, the overlay says
it is estimating.

Slicing: one render call cannot be interrupted and costs a fixed set-up (several ms) plus its
pixels, and the cost per pixel varies over the asset. So a cell is sized to about half a frame
budget (rounded down to a power of two) and a frame starts another run of cells only when the
predicted cost still fits the budget; the window then draws imgui (and sees the user's input)
at least every budget or so, instead of after a run that overshot it several times.

3. *Passes* (``pbgi.idle_passes``, only while nothing changes): once the layer is complete the
   tiles run again with pass index 1, 2, ... (app/pbgi/gbuffer.py: pass_jitter moves each
   pixel's sample inside the pixel, the passes' samples centred on it together - the engine
   tells the renderer how many passes there are; app/pbgi/lobe.py rotates the glossy lobes'
   micro-buffers),
   and each texel shows the mean radiance of the passes that saw the asset there: edges and
   mirror images are anti-aliased and the lobes' noise averages out. The compositor's
   silhouette comes from its own full-resolution G-buffer, so the mean is kept unpremultiplied.

   A tile is a render call of its own, but each is told the layer it belongs to (``rect``): the
   renderer rasterises the layer's G-buffer once per pass, Hybrid chooses its far-field blocks
   over the whole layer and keeps a block's walk for the next tile that shares it, and a glossy
   receiver's lobe is seeded by its pixel in the image (app/pbgi/renderer.py: ``layer``). So
   the tiles of a pass add up to one render of the layer, and a tile's edge is nowhere in the
   picture - before, each tile chose its own blocks, which ended at its edges: in one pass the
   tile grid showed as lines (demo close-up 96 x 96, Hybrid M 16, cells of 16: the difference
   across / inside the cell edges 1.74 against 1.15 for one render; 256 x 256, M 24, cells of
   32: 1.83 against 1.34).

4. *Recolouring* (``recolour``): the render function may also return each texel's gather split
   by BRDF factor (app/pbgi/gather_parts.py: GATHER_PARTS records), which the layer keeps -
   summed over the passes that hit, with the set of materials each texel's passes saw. An edit
   of base colour, metallic, specular, sheen or clearcoat amount is then a recombination of
   those sums, done for the preview and every texel refined so far, and the refinement goes on
   where it was (its further tiles gather with the new material): the picture is as converged
   after the edit as before it. A texel whose passes saw the edited material and another one
   (a boundary between two materials) cannot be split again: the caller gathers anew.

The render function is injected (``render(camera, tile, pass_index, layer) -> (h, w, 4)
float32`` GI_TEXEL texels: radiance, and 1 on the asset, 0 off it; or a pair of those texels and
the tile's (h, w) GATHER_PARTS records; ``layer``: the rectangle a refinement tile belongs to,
None for the preview): the viewer passes the real PBGI renderer; tests check
the scheduling arithmetic with a fake clock (exact timings) and the tiling with the real
renderer.
"""

from __future__ import annotations

import math
import time

import numpy as np

from app.camera import Camera
from app.pbgi.gather_parts import PART_WORDS, material_ids, part_records, part_words
from app.pbgi.upsample import scaled_camera
from app.render.gpu_layout import GI_PENDING, GI_TEXEL

CELL = 32                 # tile granularity before the cost per pixel is known
MIN_CELL, MAX_CELL = 8, 256
MIN_PREVIEW_SCALE = 1 / 16
FIRST_PREVIEW_SCALE = 1 / 16  # before any cost per pixel is known: the cheapest
MIN_PREVIEW_ASSET_PX = 3  # ... but never fewer preview pixels across the asset's rectangle: a
                          # small window at a GI scale below 1 gave the first preview no pixel
                          # on the asset, and the asset vanished until the tiles came
ETA_MIN_FRACTION, ETA_MIN_S = 0.05, 0.5   # data needed before the time left is said
ETA_SMOOTHING = 0.3       # weight of each frame's estimate of the total refinement time
MAX_MATERIAL_BIT = 63     # material ids from here on share one bit: never recoloured


def gi_image(height: int, width: int) -> np.ndarray:
    """A zeroed (height, width, 4) float32 image of GI_TEXEL texels (status 0: background)."""
    return GI_TEXEL.flat(GI_TEXEL.zeros(height * width)).reshape(height, width, GI_TEXEL.words)


def material_bits(ids: np.ndarray, hit: np.ndarray) -> np.ndarray:
    """One bit per material id (ids from MAX_MATERIAL_BIT on share the last), 0 where no hit."""
    bits = np.left_shift(np.int64(1), np.minimum(ids, MAX_MATERIAL_BIT).astype(np.int64))
    return np.where(hit, bits, 0).astype(np.int64)


def _split(result):
    """A render function's result as (texels, GATHER_PARTS records or None)."""
    if isinstance(result, tuple):
        return result
    return result, None


def time_left_words(seconds: float | None) -> str:
    """ "about 6 s left", coarsely rounded so the overlay does not flicker: whole seconds below
    10 s, 5 s steps below 90 s, then minutes, then hours from 90 minutes."""
    if seconds is None:
        return "estimating the time left"
    if seconds < 1:
        return "less than 1 s left"
    if seconds < 9.5:
        return f"about {math.floor(seconds + 0.5)} s left"
    if seconds < 87.5:
        return f"about {5 * math.floor(seconds / 5 + 0.5)} s left"
    if seconds < 90 * 60:
        return f"about {max(2, math.floor(seconds / 60 + 0.5))} min left"
    return f"about {math.floor(seconds / 3600 + 0.5)} h left"


def screen_rect(cam: Camera, lo, hi, pad: int = 2) -> tuple[int, int, int, int] | None:
    """Pixel rectangle (x0, y0, w, h), row 0 at the top, covering the box lo..hi as seen by
    ``cam``; the whole image when the box reaches behind the eye; None when it is off screen."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])
    eye = (cam.view() @ np.c_[corners, np.ones(8)].T).T[:, :3]
    if (eye[:, 2] > -1e-6).any():
        return 0, 0, cam.width, cam.height
    t = 1.0 / math.tan(math.radians(cam.fov_y_deg) / 2)
    ndc_x = eye[:, 0] * t / cam.aspect / -eye[:, 2]
    ndc_y = eye[:, 1] * t / -eye[:, 2]
    px = (ndc_x + 1) / 2 * cam.width
    py = (1 - ndc_y) / 2 * cam.height
    x0 = max(int(math.floor(px.min())) - pad, 0)
    y0 = max(int(math.floor(py.min())) - pad, 0)
    x1 = min(int(math.ceil(px.max())) + pad, cam.width)
    y1 = min(int(math.ceil(py.max())) + pad, cam.height)
    if x1 <= x0 or y1 <= y0:
        return None
    return x0, y0, x1 - x0, y1 - y0


def strip_tiles(rect, cell: int = CELL) -> list[list[tuple[int, int, int, int]]]:
    """Cells of ``rect`` grouped by row band, bands ordered from the middle outwards."""
    x0, y0, w, h = rect
    bands = []
    for y in range(y0, y0 + h, cell):
        hh = min(cell, y0 + h - y)
        bands.append([(x, y, min(cell, x0 + w - x), hh) for x in range(x0, x0 + w, cell)])
    mid = (len(bands) - 1) / 2
    order = sorted(range(len(bands)), key=lambda i: (abs(i - mid), i))
    return [bands[i] for i in order]


class ProgressiveGI:
    """Two GI images the compositor blends, both (h, w, 4) float32 arrays of GI_TEXEL texels
    (app/render/gpu_layout.py: radiance, status), row 0 at the top:

    ``preview``: the whole preview camera (status 1 = asset, 0 = background);
    ``full``: the layer camera, status GI_PENDING where no tile has been rendered yet.
    ``preview_dirty`` / ``take_dirty()`` tell the viewer what to upload to the GPU.
    """

    def __init__(self, render, clock=time.perf_counter):
        self.render = render
        self.clock = clock
        self.preview = gi_image(1, 1)
        self.full: np.ndarray | None = None
        self.camera: Camera | None = None
        self.preview_camera: Camera | None = None
        self.rect = None
        self.preview_scale = 0.25
        self.effective_scale = 0.25
        self.shown_scale = 0.25        # the scale of the preview on screen
        self.ms_per_px: float | None = None
        self._bands: list[list] = []
        self._cells_total = 0
        self._cells_done = 0
        self._wall = 0.0                       # wall-clock seconds of the frames with tiles
        self._last_step_end: float | None = None  # clock after this refinement's last step
        self._total_s: float | None = None     # smoothed estimate of the whole refinement
        self._preview_pending = False
        self.preview_dirty = False
        self.full_reset = False
        self.dirty_rects: list[tuple[int, int, int, int]] = []
        self.last_preview_ms = 0.0
        self.passes = 1                        # passes to average (pbgi.idle_passes)
        self.pass_index = 0                    # the pass the tiles are running
        self._sum: np.ndarray | None = None    # radiance summed over the passes that hit
        self._hits: np.ndarray | None = None   # passes that hit the asset, per texel
        # the gather in parts (see recolour), over ``rect``: GATHER_PARTS words summed over the
        # passes that hit (their count is _hits, or 1 in pass 0) and the bits of the materials
        # they saw; the preview's
        self._parts: np.ndarray | None = None
        self._parts_mats: np.ndarray | None = None
        self._preview_parts: np.ndarray | None = None
        self._preview_mats: np.ndarray | None = None

    # -- state the UI shows ----------------------------------------------------------------------
    @property
    def progress(self) -> float:
        """Fraction of the whole refinement done, every pass counted."""
        if self._preview_pending:
            return 0.0
        if self._cells_total == 0:
            return 1.0
        return (self.pass_index + self._cells_done / self._cells_total) / self.passes

    @property
    def refining(self) -> bool:
        return (self._preview_pending or self._cells_done < self._cells_total
                or (self._cells_total > 0 and self.pass_index + 1 < self.passes))

    def seconds_left(self) -> float | None:
        """Wall-clock seconds the refinement still needs, or None while there is not enough to
        go on (see the module's docstring)."""
        if not self.refining or self._total_s is None:
            return None
        return max(self._total_s - self._wall, 0.0)

    def status_words(self) -> str:
        """What the GI is doing, in one short sentence for the overlay and the stats panel:
        "preview at 1/4 resolution" until the first tiles land, then "refining 40%, about 6 s
        left" (the percentage rounded down, so it never says 100% before the end), and
        "converged" when nothing is left to do (also when the asset is off screen)."""
        if not self.refining:
            return "converged"
        if self.progress == 0:
            return f"preview at 1/{1 / self.shown_scale:.0f} resolution"
        percent = int(100 * self.progress)
        if self.pass_index > 0:
            return (f"refining {percent}% (pass {self.pass_index + 1} of {self.passes}), "
                    f"{time_left_words(self.seconds_left())}")
        return f"refining {percent}%, {time_left_words(self.seconds_left())}"

    # -- control ---------------------------------------------------------------------------------
    def cell_size(self, budget_ms: float) -> int:
        """Square cells that cost at most about half a frame budget each (a power of two in
        MIN_CELL..MAX_CELL, rounded down)."""
        if not self.ms_per_px:
            return CELL
        side = math.sqrt(max(budget_ms, 1e-3) * 0.5 / self.ms_per_px)
        return int(min(max(2 ** math.floor(math.log2(max(side, 1.0))), MIN_CELL), MAX_CELL))

    def restart(self, camera: Camera, rect, preview_scale: float, budget_ms: float = 60.0,
                passes: int = 1) -> None:
        """New view/material/setting: everything must be gathered again, preview first, then
        ``passes`` jittered passes of tiles."""
        self.passes, self.pass_index = max(int(passes), 1), 0
        self._sum = self._hits = None
        self._parts = self._parts_mats = None
        self._preview_parts = self._preview_mats = None
        if rect is not None:
            rh, rw = rect[3], rect[2]
            self._parts = np.zeros((rh, rw, PART_WORDS), np.float32)
            self._parts_mats = np.zeros((rh, rw), np.int64)
        if preview_scale != self.preview_scale:
            self.preview_scale = self.effective_scale = float(preview_scale)
        same_size = self.full is not None and self.full.shape[:2] == (camera.height, camera.width)
        old_rect = self.rect
        self.camera, self.rect = camera, rect
        if same_size:  # only what the old and the new rectangle covered has to be re-sent
            if old_rect is not None:
                x, y, w, h = old_rect
                self.full[y:y + h, x:x + w] = 0.0
            self.dirty_rects = [r for r in (old_rect, rect) if r is not None]
        else:
            self.full = gi_image(camera.height, camera.width)
            self.full_reset = True
            self.dirty_rects = []
        self._bands = [] if rect is None else strip_tiles(rect, self.cell_size(budget_ms))
        self._cells_total = sum(len(b) for b in self._bands)
        self._cells_done = 0
        self._wall, self._last_step_end, self._total_s = 0.0, None, None
        self._preview_pending = rect is not None
        if rect is None:  # asset off screen: nothing to draw
            self.preview = gi_image(1, 1)
            self.preview_camera = scaled_camera(camera, 1 / max(camera.width, camera.height))
            self.preview_dirty = True
        else:
            x, y, w, h = rect
            self.full[y:y + h, x:x + w, GI_TEXEL.index("status")] = GI_PENDING

    def step(self, budget_ms: float, allow_tiles: bool = True) -> bool:
        """Do up to ``budget_ms`` of work; True when an image changed."""
        if self.camera is None:
            return False
        changed = False
        start = self.clock()
        if self._preview_pending:
            self._preview(budget_ms)
            changed = True
        anchor = None
        if allow_tiles and not self._bands and self._cells_total and \
                self.pass_index + 1 < self.passes:
            self._next_pass(budget_ms)
        while allow_tiles and self._bands:
            elapsed = (self.clock() - start) * 1e3
            if changed and elapsed + self._cell_ms() > budget_ms:
                break       # the next cell would overshoot: let the window draw and listen
            if anchor is None:  # this frame's share: since the end of the previous step
                anchor = self._last_step_end if self._last_step_end is not None else start
            self._tile(max(budget_ms - elapsed, budget_ms * 0.25))
            changed = True
        # A frame whose tiles waited (the user interacting) is not refinement time: only the
        # time up to a step that ran tiles counts.
        self._last_step_end = self.clock()
        if anchor is not None:
            self._wall += self._last_step_end - anchor
            self._estimate()
        return changed

    def _next_pass(self, budget_ms: float) -> None:
        """The layer is complete: run its tiles again, one pass further (see the docstring)."""
        x, y, w, h = self.rect
        if self._sum is None:            # pass 0's image, unpremultiplied by construction
            hit = self.full[y:y + h, x:x + w, GI_TEXEL.index("status")] > 0.5
            self._hits = hit.astype(np.float32)
            self._sum = self.full[y:y + h, x:x + w, :3] * self._hits[..., None]
        self.pass_index += 1
        self._bands = strip_tiles(self.rect, self.cell_size(budget_ms))
        self._cells_total = sum(len(b) for b in self._bands)
        self._cells_done = 0

    def _estimate(self) -> None:
        """Smooth the total wall time the refinement takes, from the rate so far."""
        p = self.progress
        if p < ETA_MIN_FRACTION or self._wall < ETA_MIN_S:
            return
        total = self._wall / p
        self._total_s = total if self._total_s is None else (
            self._total_s + ETA_SMOOTHING * (total - self._total_s))

    def _cell_ms(self) -> float:
        """Predicted cost of the next cell (0 before any cost is known)."""
        if not self.ms_per_px or not self._bands:
            return 0.0
        c = self._bands[0][0]
        return self.ms_per_px * c[2] * c[3]

    def finish(self) -> None:
        """Complete the refinement now (screenshots, offscreen runs)."""
        while self.refining:
            self.step(1e9)

    # -- work ------------------------------------------------------------------------------------
    def _preview(self, budget_ms: float) -> None:
        cam, rect = self.camera, self.rect
        s = self.effective_scale
        # Predict before rendering (one call cannot be interrupted): about one frame budget at
        # the measured cost per pixel; 1/16 until a cost has been measured.
        if self.ms_per_px:
            fit = math.sqrt(budget_ms / (self.ms_per_px * max(rect[2] * rect[3], 1)))
            s = min(s, max(MIN_PREVIEW_SCALE, fit))
        else:
            s = min(s, FIRST_PREVIEW_SCALE)
        s = max(s, min(1.0, MIN_PREVIEW_ASSET_PX / max(min(rect[2], rect[3]), 1)))
        small = scaled_camera(cam, s)
        sx, sy = small.width / cam.width, small.height / cam.height
        x0, y0 = int(math.floor(rect[0] * sx)), int(math.floor(rect[1] * sy))
        x1 = min(int(math.ceil((rect[0] + rect[2]) * sx)) + 1, small.width)
        y1 = min(int(math.ceil((rect[1] + rect[3]) * sy)) + 1, small.height)
        t0 = self.clock()
        lo, parts = _split(self.render(small, (x0, y0, x1 - x0, y1 - y0), 0, None))
        ms = (self.clock() - t0) * 1e3
        self.last_preview_ms = ms
        self.preview = gi_image(small.height, small.width)
        self.preview[y0:y1, x0:x1] = lo
        self._preview_parts = self._preview_mats = None
        if parts is not None:
            hit = lo[..., GI_TEXEL.index("status")] > 0.5
            self._preview_parts = np.zeros((small.height, small.width, PART_WORDS), np.float32)
            self._preview_parts[y0:y1, x0:x1] = part_words(parts)
            self._preview_mats = np.zeros((small.height, small.width), np.int64)
            self._preview_mats[y0:y1, x0:x1] = material_bits(material_ids(parts), hit)
        self.preview_camera = small
        self.shown_scale = s
        self.preview_dirty = True
        self._preview_pending = False
        # Adapt: keep the preview within the budget, climb back when it is cheap.
        self.effective_scale = s
        if ms > 1.5 * budget_ms:
            self.effective_scale = max(MIN_PREVIEW_SCALE, s * 0.7)
        elif ms < 0.3 * budget_ms:
            self.effective_scale = min(self.preview_scale, s / 0.7)
        if (x1 - x0) * (y1 - y0):
            self._learn(ms, lo)
        if self._cells_done == 0:  # now that the cost per pixel is known, size the cells
            self._bands = strip_tiles(rect, self.cell_size(budget_ms))
            self._cells_total = sum(len(b) for b in self._bands)

    def _learn(self, ms: float, img: np.ndarray) -> None:
        """Learn the cost per pixel from a render of ``img``'s pixels. Pixels off the asset cost
        almost nothing, so a render mostly off it (the corners of the asset's rectangle) would
        make the asset look cheap and the next strip overshoot. So the estimate rises at once
        and falls only by as much as the render was on the asset (nothing for a render off
        it, half-way for one at least a quarter on it): frames err on the short side."""
        npx = img.shape[0] * img.shape[1]
        if npx == 0:
            return
        per = ms / npx
        if self.ms_per_px is None or per > self.ms_per_px:
            self.ms_per_px = per
            return
        on_asset = float((img[..., GI_TEXEL.index("status")] > 0).mean())
        w = 0.5 * min(on_asset / 0.25, 1.0)
        self.ms_per_px = (1 - w) * self.ms_per_px + w * per

    def _tile(self, budget_ms: float) -> None:
        band = self._bands[0]
        cells = 1
        if self.ms_per_px:
            cell_px = band[0][2] * band[0][3]
            cells = max(1, int(budget_ms / (self.ms_per_px * cell_px)))
        run = band[:cells]
        x0, y0 = run[0][0], run[0][1]
        w = run[-1][0] + run[-1][2] - x0
        h = run[0][3]
        t0 = self.clock()
        img, parts = _split(self.render(self.camera, (x0, y0, w, h), self.pass_index,
                                           self.rect))
        self._learn((self.clock() - t0) * 1e3, img)
        self._keep_parts(img, parts, x0, y0)
        if self.pass_index == 0:
            self.full[y0:y0 + h, x0:x0 + w] = img
        else:                            # the mean over the passes that saw the asset
            rx, ry = x0 - self.rect[0], y0 - self.rect[1]
            hit = (img[..., GI_TEXEL.index("status")] > 0.5).astype(np.float32)
            sums = self._sum[ry:ry + h, rx:rx + w]
            hits = self._hits[ry:ry + h, rx:rx + w]
            sums += img[..., :3] * hit[..., None]
            hits += hit
            out = self.full[y0:y0 + h, x0:x0 + w]
            seen = hits > 0
            out[..., :3][seen] = sums[seen] / hits[seen][:, None]
            out[..., GI_TEXEL.index("status")][seen] = 1.0
        self.dirty_rects.append((x0, y0, w, h))
        del band[:cells]
        if not band:
            self._bands.pop(0)
        self._cells_done += len(run)

    # -- recolouring (see the module docstring) ---------------------------------------------------
    def _keep_parts(self, img: np.ndarray, parts, x0: int, y0: int) -> None:
        """Add a tile's parts to the layer's sums (the first pass replaces them); without parts
        the layer can no longer be recoloured."""
        if self._parts is None:
            return
        if parts is None:
            self._parts = self._parts_mats = None
            return
        h, w = img.shape[:2]
        rx, ry = x0 - self.rect[0], y0 - self.rect[1]
        hit = img[..., GI_TEXEL.index("status")] > 0.5
        words = part_words(parts)
        bits = material_bits(material_ids(parts), hit)
        sums = self._parts[ry:ry + h, rx:rx + w]
        mats = self._parts_mats[ry:ry + h, rx:rx + w]
        if self.pass_index == 0:
            sums[:] = words * hit[..., None]
            mats[:] = bits
        else:
            sums += words * hit[..., None]
            mats |= bits

    @property
    def recolourable(self) -> bool:
        """Does the layer hold its gather in parts (every render so far returned them)?"""
        return self._parts is not None and not self._preview_pending and (
            self._preview_mats is not None)

    def recolour(self, changed, radiance) -> bool:
        """Re-light the preview and every texel refined so far after an edit of the materials
        ``changed`` (ids) that recombining the parts can follow: ``radiance(records, id)`` gives
        the (n, 3) radiance of n GATHER_PARTS records of material ``id``. The refinement goes
        on where it was. False (nothing touched) when the layer holds no parts or a texel's
        passes saw a changed material and another one: then gather again."""
        if not self.recolourable:
            return False
        changed = {int(c) for c in changed}
        if any(c >= MAX_MATERIAL_BIT for c in changed):
            return False
        mask = np.int64(sum(1 << c for c in changed))
        for mats in (self._parts_mats, self._preview_mats):
            # a texel of a changed material whose passes saw another material too
            if (((mats & mask) != 0) & ((mats & (mats - 1)) != 0)).any():
                return False
        status = GI_TEXEL.index("status")
        for c in changed:
            bit = np.int64(1 << c)
            # the texels refined so far (the mean over their passes)
            sel = self._parts_mats == bit
            if sel.any():
                hits = self._hits[sel] if self._hits is not None else np.ones(int(sel.sum()),
                                                                             np.float32)
                mean = self._parts[sel] / hits[:, None]
                rad = radiance(part_records(mean), c)
                x, y, w, h = self.rect
                region = self.full[y:y + h, x:x + w]
                region[..., :3][sel] = rad
                region[..., status][sel] = 1.0
                if self._sum is not None:
                    self._sum[sel] = rad * hits[:, None]
            sel = self._preview_mats == bit
            if sel.any():
                rad = radiance(part_records(self._preview_parts[sel]), c)
                self.preview[..., :3][sel] = rad
        self.preview_dirty = True
        self.dirty_rects.append(tuple(self.rect))
        return True

    def take_dirty(self) -> tuple[bool, bool, list[tuple[int, int, int, int]]]:
        """(preview changed, full image reset, rectangles of ``full`` written since)."""
        out = (self.preview_dirty, self.full_reset, self.dirty_rects)
        self.preview_dirty, self.full_reset, self.dirty_rects = False, False, []
        return out
