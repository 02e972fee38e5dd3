"""Classic PBGI (paper Section 5.2): one depth-first BSH walk per receiver finds its cut and
rasterises it into the receiver's micro-buffer (shaders/pbgi_classic.glsl).

``ClassicCut`` is the reference cut finder (app/pbgi/modebase.py): the other modes reuse the
micro-buffer, the node layout and the gather and differ only in how they find the same cut (the
far-field sharing also runs two of these walks, split by SHARE_SPLIT). The walk is split across
dispatches with a per-receiver resume index because llvmpipe silently ends every loop of an
invocation after 65,535 iterations in total; the host dispatches until no receiver has work left
and reports per receiver whether its walk completed.
"""

from __future__ import annotations

import numpy as np

from app.pbgi.gpu_layout import (CLASSIC_STATE, LOOP_LIMIT, SSBO, WALK_CUT_SHORT, WORKGROUP,
                                 dispatch_groups)
from app.pbgi.microbuffer import entries, omega_horizon, omega_micro, set_frame_uniforms
from app.pbgi.modebase import Batch, CutFigures, CutFinder, MicroBufferMode, RenderParams
from app.render.programs import load_compute


class ClassicCut(CutFinder):
    """Depth-first cut finder. Budgets per dispatch and receiver: ``steps`` node visits,
    ``list_cap`` accepted nodes and ``splat_budget`` micro-buffer entry tests, together below
    LOOP_LIMIT (checked). ``stop_factor`` = 4 is Section 5.3's 4 Omega; nodes straddling the
    receiver's horizon stop there too, but never above microbuffer.HORIZON_OMEGA
    (``omega_horizon``). ``workgroup``: the walk's local size (CUT_WORKGROUP in
    pbgi_classic.glsl; Hybrid's block walk takes a smaller one, app/pbgi/farfield.py:
    FAR_WORKGROUP)."""

    clears_microbuffers = False       # the walk writes only the entries its nodes cover

    def __init__(self, ctx, steps: int = 16384, splat_budget: int = 32768, list_cap: int = 256,
                 stop_factor: float = 4.0, max_rounds: int = 100000,
                 defines: dict | None = None, workgroup: int = WORKGROUP):
        if steps + splat_budget + list_cap >= LOOP_LIMIT:
            raise ValueError("steps + splat_budget must stay below llvmpipe's loop limit")
        self.ctx = ctx
        self.workgroup = int(workgroup)
        self.prog = load_compute(ctx, "pbgi_classic.glsl",
                                 defines={"LIST_CAP": int(list_cap), **(defines or {}),
                                          **({} if self.workgroup == WORKGROUP
                                             else {"CUT_WORKGROUP": self.workgroup})})
        self.steps, self.splat_budget = int(steps), int(splat_budget)
        self.stop_factor = float(stop_factor)
        self.max_rounds = int(max_rounds)
        self.state = None
        self.counter = ctx.buffer(reserve=4)

    def bytes_per_receiver(self, m: int) -> int:
        """Per-receiver memory besides the micro-buffer: the resume state (CLASSIC_STATE)."""
        return CLASSIC_STATE.nbytes

    def reserve_bytes(self, budget_bytes: float) -> int:
        return 0

    def _state(self, count: int):
        need = CLASSIC_STATE.nbytes * count
        if self.state is None or self.state.size < need:
            if self.state is not None:
                self.state.release()
            self.state = self.ctx.buffer(reserve=need)
        self.state.clear(size=need)      # next node 0 (the root), nothing visited
        return self.state

    def fill(self, batch: Batch, share=None) -> CutFigures:
        """Fill the micro-buffers (already emptied) of the batch's receivers. ``share``: the
        per-row (centre, D) buffer of a walk compiled with SHARE_SPLIT (app/pbgi/farfield.py)."""
        first, count, m, nodes = batch.first, batch.count, batch.m, batch.nodes
        node_count = nodes.count
        if self.splat_budget < entries(m):
            raise ValueError("splat budget must cover one whole micro-buffer")
        state = self._state(count)
        batch.receivers.bind_to_storage_buffer(SSBO.RECEIVERS)
        state.bind_to_storage_buffer(SSBO.WALK_STATE)
        self.counter.bind_to_storage_buffer(SSBO.COUNTERS)
        if share is not None:
            share.bind_to_storage_buffer(SSBO.SHARE)
        nodes.use()
        batch.microbuffers.bind()
        prog = self.prog
        prog["u_first"] = first
        prog["u_count"] = count
        prog["u_m"] = m
        prog["u_omega_stop"] = self.stop_factor * omega_micro(m)
        prog["u_omega_horizon"] = omega_horizon(m, self.stop_factor)
        prog["u_steps"] = self.steps
        prog["u_splat_budget"] = self.splat_budget
        if "u_inv_cell_area" in prog:
            prog["u_inv_cell_area"] = 1.0 / max(batch.cell_size, 1e-9) ** 2
        prog["u_node_count"] = node_count
        set_frame_uniforms(prog, batch.seed_tile, batch.pass_index,   # SHARE_SPLIT: the pass,
                           batch.turned_frames)           # and the pixels of rows alone
        nodes.set_uniforms(prog)
        groups = dispatch_groups(count, self.workgroup)
        rounds, remaining = 0, count
        while remaining and rounds < self.max_rounds:
            self.counter.write(b"\0\0\0\0")
            prog.run(groups)
            self.ctx.memory_barrier()
            remaining = int(np.frombuffer(self.counter.read(), np.uint32)[0])
            rounds += 1
        st = CLASSIC_STATE.view(state.read(size=CLASSIC_STATE.nbytes * count))
        done = st["next"] >= node_count
        return CutFigures(visited=st["visited"].astype(np.int64), done=done,
                          tests=st["tests"].astype(np.int64), rounds=rounds,
                          cut_short=int(((st["flags"] & WALK_CUT_SHORT) != 0).sum()),
                          nbytes=self.state.size)

    def release(self) -> None:
        for b in (self.state, self.counter):
            if b is not None:
                b.release()
        self.state = self.counter = None


class ClassicMode(MicroBufferMode):
    """Classic PBGI: every receiver walks the whole tree."""

    name = "classic"

    def __init__(self, ctx, params: RenderParams, defines: dict | None = None):
        self.stop_factor = float(params.stop_factor)
        super().__init__(ctx, params, ClassicCut(ctx, stop_factor=self.stop_factor,
                                                 defines=defines))

    def fits(self, params: RenderParams) -> bool:
        return float(params.stop_factor) == self.stop_factor
