"""Shader loading: one .glsl file per program in ``shaders/``, ``#include``, injected defines,
and compile/link errors that name the shader file and line.

A program file holds every stage behind guards (``#ifdef VERTEX_SHADER`` ...) as in
moderngl-window; compute shaders are a file of their own. ``#include "lib/x.glsl"`` is resolved
relative to the shaders folder; ``gen/...`` includes are generated from Python (e.g. the BSH node
layout), so a number lives in one place.
"""

from __future__ import annotations

import importlib
import re
from functools import lru_cache
from pathlib import Path

import moderngl

from app.errors import ScanlightError

GLSL_VERSION = "#version 430 core"
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$')
_ERROR_LOC = re.compile(r"(\d+):(\d+)\((\d+)\)")  # Mesa: "source:line(column)"

# Generated includes: name -> "module:function" returning GLSL text. The records and numbers
# Python and GLSL share are declared in those modules (app/render/gpu_records.py: the helper).
GENERATED_INCLUDES = {
    "gen/node_layout.glsl": "app.pbgi.layout:glsl_header",
    "gen/bindings.glsl": "app.pbgi.gpu_layout:bindings_glsl",
    "gen/receivers.glsl": "app.pbgi.gpu_layout:receivers_glsl",
    "gen/gbuffer.glsl": "app.pbgi.gpu_layout:gbuffer_glsl",
    "gen/materials.glsl": "app.pbgi.gpu_layout:materials_glsl",
    "gen/walk_state.glsl": "app.pbgi.gpu_layout:walk_state_glsl",
    "gen/pair_streams.glsl": "app.pbgi.gpu_layout:pair_streams_glsl",
    "gen/mip.glsl": "app.pbgi.gpu_layout:mip_glsl",
    "gen/microbuffer.glsl": "app.pbgi.gpu_layout:microbuffer_glsl",
    "gen/bsh_textures.glsl": "app.pbgi.gpu_layout:bsh_textures_glsl",
    "gen/share_rows.glsl": "app.pbgi.gpu_layout:share_rows_glsl",
    "gen/block_of.glsl": "app.pbgi.gpu_layout:block_of_glsl",
    "gen/frames.glsl": "app.pbgi.gpu_layout:frames_glsl",
    "gen/gather_output.glsl": "app.pbgi.gpu_layout:gather_output_glsl",
    "gen/viewer_texels.glsl": "app.render.gpu_layout:texels_glsl",
    "gen/splat.glsl": "app.render.gpu_layout:splat_glsl",
    "gen/splat_resolve.glsl": "app.render.gpu_layout:splat_resolve_glsl",
    "gen/viewer_gbuffer.glsl": "app.render.gpu_layout:gbuffer_glsl",
    "gen/viewer_composite.glsl": "app.render.gpu_layout:composite_glsl",
    "gen/joint_bilateral.glsl": "app.pbgi.upsample:weights_glsl",
    "gen/gi_upsample.glsl": "app.pbgi.upsample:upsample_glsl",
    "gen/tonemap.glsl": "app.render.tonemap:glsl_header",
}


@lru_cache(maxsize=1)
def shaders_dir() -> Path:
    """The shaders folder: inside the installed package (wheel) or beside it (source tree)."""
    here = Path(__file__).resolve().parent.parent  # app/
    for cand in (here / "shaders", here.parent / "shaders"):
        if cand.is_dir():
            return cand
    raise ScanlightError(None, f"shaders folder not found next to {here}; reinstall scanlight")


def _read_include(name: str) -> str:
    if name in GENERATED_INCLUDES:
        mod, fn = GENERATED_INCLUDES[name].split(":")
        return getattr(importlib.import_module(mod), fn)()
    path = shaders_dir() / name
    if not path.is_file():
        raise ScanlightError(path, "shader include not found")
    return path.read_text()


# Each file gets its own block of line numbers (file k starts at line k * LINE_STRIDE + 1):
# Mesa does not reliably report the source-string number of '#line N S', but it does report
# the line, so the line alone tells which file an error is in.
LINE_STRIDE = 100000


class _Source:
    """Expands includes, keeping a table file index -> file name for error messages."""

    def __init__(self):
        self.files: list[str] = []

    def expand(self, name: str, text: str, stack: tuple = ()) -> str:
        if name in stack:
            raise ScanlightError(name, "recursive #include: " + " -> ".join(stack + (name,)))
        idx = len(self.files)
        self.files.append(name)
        out = [f"#line {idx * LINE_STRIDE + 1}"]
        for lineno, line in enumerate(text.splitlines(), start=1):
            m = _INCLUDE.match(line)
            if m:
                inc = m.group(1)
                out.append(self.expand(inc, _read_include(inc), stack + (name,)))
                out.append(f"#line {idx * LINE_STRIDE + lineno + 1}")
            elif line.strip().startswith("#version"):
                out.append("")  # the loader writes the version line itself
            else:
                out.append(line)
        return "\n".join(out)

    def describe(self, message: str) -> str:
        def repl(m):
            _, line, col = (int(g) for g in m.groups())
            src, line = divmod(line, LINE_STRIDE)
            fname = self.files[src] if src < len(self.files) else f"source {src}"
            return f"{fname}:{line}:{col}"
        return _ERROR_LOC.sub(repl, message)


def _defines_text(defines: dict | None) -> str:
    lines = []
    for key, val in (defines or {}).items():
        if isinstance(val, bool):
            val = int(val)
        lines.append(f"#define {key} {val}")
    return "\n".join(lines)


def _program_path(name) -> Path:
    """A program in shaders/ by name, or any .glsl file by path (the tests' own programs);
    includes always come from shaders/."""
    return name if isinstance(name, Path) else shaders_dir() / name


def build_source(name, stage: str | None, defines: dict | None = None) -> tuple[str, _Source]:
    path = _program_path(name)
    if not path.is_file():
        raise ScanlightError(path, "shader file not found")
    src = _Source()
    head = [GLSL_VERSION]
    if stage:
        head.append(f"#define {stage}")
    head.append(_defines_text(defines))
    body = src.expand(str(name), path.read_text())
    return "\n".join(head) + "\n" + body + "\n", src


def _compile_error(name: str, src_map: _Source, exc: Exception) -> ScanlightError:
    msg = src_map.describe(str(exc))
    lines = [ln.strip() for ln in msg.splitlines() if "error" in ln.lower() and ":" in ln]
    first = lines[0] if lines else " ".join(msg.split())[:300]
    return ScanlightError(_program_path(name), f"shader compile/link failed: {first}")


def load_program(ctx: moderngl.Context, name: str, defines: dict | None = None,
                 stages=("VERTEX_SHADER", "FRAGMENT_SHADER"), **kwargs) -> moderngl.Program:
    """A vertex/fragment (optionally geometry) program from one guarded .glsl file."""
    keys = {"VERTEX_SHADER": "vertex_shader", "FRAGMENT_SHADER": "fragment_shader",
            "GEOMETRY_SHADER": "geometry_shader"}
    sources, maps = {}, []
    for stage in stages:
        text, smap = build_source(name, stage, defines)
        sources[keys[stage]] = text
        maps.append(smap)
    try:
        return ctx.program(**sources, **kwargs)
    except Exception as exc:
        raise _compile_error(name, maps[0], exc) from None


def load_compute(ctx: moderngl.Context, name: str, defines: dict | None = None) -> moderngl.ComputeShader:
    text, smap = build_source(name, "COMPUTE_SHADER", defines)
    try:
        return ctx.compute_shader(text)
    except Exception as exc:
        raise _compile_error(name, smap, exc) from None
