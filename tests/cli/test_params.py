"""The parameter table (app/params.py) is the one declaration: the command line, the viewer's
settings, the render/expansion records and the README all agree with it."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from app.cli import build_parser
from app.commands.options import COMMAND_FLAGS, DEPRECATED, param_values
from app.params import BY_KEY, PARAMS, RENDER_KEYS, markdown_table
from app.pbgi.renderer import RenderParams
from app.settings import Settings

ROOT = Path(__file__).resolve().parents[2]

# The smallest valid command line of each command that exposes table parameters (the files
# are never opened: only parsing is tested).
MINIMAL = {
    "render": ["render", "--cloud", "c.ply", "--object", "o.json", "--camera", "cam.json",
               "--out", "o.exr"],
    "expand": ["expand", "--cloud", "c.ply", "--photo", "p.exr", "--cameras", "cams.json",
               "--out", "o.ply"],
    "turntable": ["turntable", "--cloud", "c.ply", "--object", "o.json", "--count", "4",
                  "--out", "frames"],
    "evaluate": ["evaluate", "expansion", "--cloud", "c.ply", "--gt", "g.ply"],
    "demo": ["demo"],
    "bench table3": ["bench", "table3"],
    "bench classic": ["bench", "classic"],
    "bench expand": ["bench", "expand"],
    "bench glossy": ["bench", "glossy"],
    "bench asset": ["bench", "asset"],
    "bench profile": ["bench", "profile"],
}


def test_every_command_with_parameters_is_checked_here():
    assert set(MINIMAL) == set(COMMAND_FLAGS)


@pytest.mark.parametrize("command", sorted(MINIMAL))
def test_cli_defaults_are_the_viewers(command):
    """A command line that sets nothing gets exactly the viewer's default settings."""
    args = build_parser().parse_args(MINIMAL[command])
    values = param_values(args, command)
    viewer = Settings()
    assert values == {k: viewer[k] for k in values}


def test_render_params_from_cli_and_viewer_are_equal():
    args = build_parser().parse_args(MINIMAL["render"])
    assert RenderParams.from_settings(param_values(args, "render")) == \
        RenderParams.from_settings(Settings())
    assert RenderParams.KEYS == RENDER_KEYS


@pytest.mark.parametrize("command", sorted(MINIMAL))
def test_cli_flags_check_the_table_range(command):
    """Every numeric flag refuses a value above the table's range, naming the flag."""
    from app.errors import UsageError
    for flag, key in COMMAND_FLAGS[command].items():
        p = BY_KEY[key]
        if p.kind not in ("int", "float"):
            continue
        too_big = str(int(p.hi) + 1 if p.kind == "int" else p.hi * 2 + 1)
        args = build_parser().parse_args(MINIMAL[command] + [flag, too_big])
        with pytest.raises(UsageError, match=flag):
            param_values(args, command)


def test_deprecated_flags_still_work(caplog):
    for command, renames in DEPRECATED.items():
        for old, new in renames.items():
            key = COMMAND_FLAGS[command][new]
            args = build_parser().parse_args(MINIMAL[command] + [old, "0.5"])
            assert param_values(args, command)[key] == 0.5
    assert "deprecated" in caplog.text


def test_one_name_one_meaning():
    """--exposure is EV (render); the scan's alpha is --alpha everywhere."""
    assert COMMAND_FLAGS["render"]["--exposure"] == "view.exposure"
    for command, flags in COMMAND_FLAGS.items():
        assert flags.get("--alpha", "hdr.alpha") == "hdr.alpha"
        assert flags.get("--exposure", "view.exposure") == "view.exposure", command


def _hand_written_flags() -> dict[str, list[str]]:
    """file -> the literal flags of add_argument calls in app/ (what is not generated)."""
    out = {}
    for path in (ROOT / "app").rglob("*.py"):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "add_argument":
                for a in node.args:
                    if isinstance(a, ast.Constant) and isinstance(a.value, str):
                        out.setdefault(str(path.relative_to(ROOT)), []).append(a.value)
    return out


def test_no_parameter_flag_is_declared_by_hand():
    """Flags of table parameters exist only through app/commands/options.py."""
    generated = {f for flags in COMMAND_FLAGS.values() for f in flags} | {
        f for renames in DEPRECATED.values() for f in renames}
    # engine parameters under their default flag name (the viewer's display settings such as
    # view.cloud share names with file options like --cloud, so they are not counted)
    names = {"--" + p.name.replace("_", "-") for p in PARAMS if p.group in ("pbgi", "hdr")}
    # flags that only share a name: bench bsh's --seed seeds its random cloud, not PatchMatch
    other_meaning = {"app/bench/bsh.py": {"--seed"}}
    for path, flags in _hand_written_flags().items():
        if path == "app/commands/options.py":
            continue
        clash = sorted(set(flags) & (generated | names) - other_meaning.get(path, set()))
        assert not clash, f"{path} declares table parameters by hand: {clash}"


def test_readme_holds_the_generated_table():
    readme = (ROOT / "README.md").read_text()
    assert markdown_table() in readme, "regenerate the README table: " \
        "python -c 'from app.params import markdown_table; print(markdown_table())'"


def test_expand_flags_given_win_over_params_json():
    """--params fills fields by name or by key; a flag given on the command line wins, even at
    its default value; what neither sets keeps the table's default."""
    from app.commands.expand import expand_params
    parse = lambda *extra: expand_params(build_parser().parse_args(MINIMAL["expand"] + list(extra)))
    assert parse("--k", "8", "--params", '{"neighbours": 4}').neighbours == 8
    assert parse("--k", "8", "--params", '{"hdr.neighbours": 4}').neighbours == 8
    assert parse("--face-size", "512", "--params", '{"face_size": 64}').face_size == 512
    assert parse("--params", '{"neighbours": 4}').neighbours == 4
    assert parse().neighbours == BY_KEY["hdr.neighbours"].default
