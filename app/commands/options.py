"""Command-line options generated from the parameter table (app/params.py).

Each command lists which parameters it exposes and under which flag; type, default, range,
unit and help come from the table, so ``scanlight render`` and the viewer cannot disagree on a
default (tests/cli/test_params.py checks it) and a range is checked in one place. This file is
only a name map, like f3d's F3DOptionsTools.h over its options.json.

A flag is ``--`` + the parameter's name with dashes unless the map names it otherwise (the
short names the paper uses: ``--tl``, ``--th``, ``--k``). ``DEPRECATED`` keeps old spellings
working with a warning: ``expand --exposure`` and ``evaluate --exposure`` meant the scan's alpha,
not exposure in EV as in ``render``, and are now ``--alpha``.
"""

from __future__ import annotations

import argparse
import logging

from app.errors import ScanlightError, UsageError
from app.params import BY_KEY, CUSTOM_QUALITY, EXPAND_KEYS, QUALITY_PRESETS, RENDER_KEYS, Param

log = logging.getLogger(__name__)


def _flags(keys, renamed: dict | None = None) -> dict[str, str]:
    """flag -> key: ``RENAMED``'s flag (or this command's ``renamed``), else --name."""
    renamed = {**RENAMED, **(renamed or {})}
    return {renamed.get(k, "--" + BY_KEY[k].name.replace("_", "-")): k for k in keys}


# flags that are not "--" + the parameter's name: the paper's short names, and the budget's
RENAMED = {"hdr.threshold_ldr": "--tl", "hdr.threshold_ssd": "--th", "hdr.neighbours": "--k",
           "hdr.iterations": "--exposure-iterations", "pbgi.memory_budget_mb": "--budget-mb"}

# command -> {flag: key}
COMMAND_FLAGS: dict[str, dict[str, str]] = {
    "render": _flags(("pbgi.quality",) + RENDER_KEYS + (
        "pbgi.render_scale", "pbgi.rough_render_scale", "pbgi.rough_scale_from", "pbgi.passes",
        "pbgi.glossy_passes", "pbgi.edge_samples",
        "pbgi.differential",
        "view.exposure", "view.tonemap", "view.eye_dome")),
    "turntable": _flags(("pbgi.quality",) + RENDER_KEYS + (
        "pbgi.render_scale", "pbgi.rough_render_scale", "pbgi.rough_scale_from", "pbgi.passes",
        "pbgi.glossy_passes", "pbgi.edge_samples",
        "pbgi.differential",
        "view.exposure", "view.tonemap", "view.eye_dome", "view.fov_y"), {"view.fov_y": "--fov"}),
    "expand": _flags(EXPAND_KEYS),
    "demo": _flags(("view.tonemap",)),
    "evaluate": _flags(("hdr.threshold_ldr", "hdr.alpha")),
    "bench table3": _flags(("pbgi.memory_budget_mb", "pbgi.omega_tr_factor",
                            "pbgi.parallax_tolerance")),
    "bench classic": _flags(("pbgi.memory_budget_mb",)),
    "bench glossy": _flags(("pbgi.microbuffer", "pbgi.lobe_only_microbuffer")),
    "bench asset": _flags(("pbgi.microbuffer", "pbgi.asset_surfels")),
    "bench profile": _flags(("pbgi.microbuffer",)),
    "bench expand": _flags(("hdr.face_size", "hdr.poisson_solver", "hdr.seed",
                            "hdr.registration"),
                           {"hdr.poisson_solver": "--solver"}),
}
# (command, key) -> help where the table's text does not fit the command's use of the value
HELP = {
    ("turntable", "view.fov_y"): "vertical field of view of the orbit's camera (not with --path)",
    ("evaluate", "hdr.alpha"): "the scan's alpha: scale of the evaluated cloud relative to the "
                               "ground truth; not set: measured on the well-exposed points",
    ("evaluate", "hdr.threshold_ldr"): "t_l: points whose LDR luminance exceeds this count as "
                                       "overexposed",
}
# command -> {old flag: new flag}
DEPRECATED: dict[str, dict[str, str]] = {
    "expand": {"--exposure": "--alpha"},
    "evaluate": {"--exposure": "--alpha"},
}


def _dest(key: str) -> str:
    return "param__" + key.replace(".", "__")


def _help(p: Param, text: str | None = None) -> str:
    default = "not set" if p.default is None else p.default
    rng = p.range_text()
    unit = f" {p.unit}" if p.unit else ""
    text = f"{text or p.help} (default {default}{unit}" + (f"; {rng}" if rng and p.kind != "choice"
                                                   else "") + ")"
    return text.replace("%", "%%")     # argparse %-formats help (hdr.l_max_percentile is in %)


def _typed(p: Param):
    """argparse type: the string as the parameter's kind (range checks come later, with the
    flag's name, in ``param_values``)."""
    if p.kind == "int":
        return int
    if p.kind == "float":
        return float
    if p.kind == "bool":
        def parse_bool(text: str) -> bool:
            t = text.strip().lower()
            if t in ("1", "true", "yes", "on"):
                return True
            if t in ("0", "false", "no", "off"):
                return False
            raise argparse.ArgumentTypeError(f"expected true or false, got {text!r}")
        return parse_bool
    return str


class _Deprecated(argparse.Action):
    def __init__(self, option_strings, dest, new_flag: str = "", **kw):
        self.new_flag = new_flag
        super().__init__(option_strings, dest, **kw)

    def __call__(self, parser, namespace, values, option_string=None):
        log.warning("%s is deprecated: use %s", option_string, self.new_flag)
        setattr(namespace, self.dest, values)


def add_param_options(parser, command: str) -> None:
    """Add the options of ``command`` (a key of COMMAND_FLAGS) to an argparse parser."""
    for flag, key in COMMAND_FLAGS[command].items():
        p = BY_KEY[key]
        # no default on the namespace: a flag the user gave is one present there
        # (``given_values``); ``param_values`` fills in the table's default
        kw = {"dest": _dest(key), "type": _typed(p), "default": argparse.SUPPRESS,
              "help": _help(p, HELP.get((command, key)))}
        if p.kind == "choice":
            kw["choices"] = p.choices
        elif p.kind == "bool":
            kw["metavar"] = "BOOL"
        elif p.kind in ("int", "float"):
            kw["metavar"] = p.unit.upper() if p.unit.isalpha() and len(p.unit) <= 3 else \
                p.name.upper()
        parser.add_argument(flag, **kw)
    for old, new in DEPRECATED.get(command, {}).items():
        key = COMMAND_FLAGS[command][new]
        parser.add_argument(old, dest=_dest(key), type=_typed(BY_KEY[key]), action=_Deprecated,
                            new_flag=new, default=argparse.SUPPRESS,
                            metavar=new.lstrip("-").upper(), help=f"deprecated spelling of {new}")


def param_values(args, command: str) -> dict:
    """key -> value of every parameter of ``command``, checked against the table; a bad value is
    a UsageError naming the flag (exit 2)."""
    out = {}
    for flag, key in COMMAND_FLAGS[command].items():
        p = BY_KEY[key]
        value = getattr(args, _dest(key), p.default)
        try:
            out[key] = p.check(value, what=flag)
        except ScanlightError as err:
            raise UsageError(None, err.reason) from None
    # --quality NAME: the preset's values for every setting not given by its own flag
    quality = out.get("pbgi.quality", CUSTOM_QUALITY)
    if quality != CUSTOM_QUALITY:
        for key, value in QUALITY_PRESETS[quality].items():
            if key in out and not hasattr(args, _dest(key)):
                out[key] = value
    return out


def given_values(args, command: str) -> dict:
    """key -> value of the parameters of ``command`` given on the command line (checked), even
    where the value equals the default."""
    values = param_values(args, command)
    return {k: v for k, v in values.items() if hasattr(args, _dest(k))}


__all__ = ["COMMAND_FLAGS", "DEPRECATED", "add_param_options", "param_values", "given_values"]
