"""The package's structure holds: no import cycle (module-level or inside functions), no copied
code (pylint's duplicate-code check), engine and model free of UI imports, test-only code kept
out of the package."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
APP = ROOT / "app"


def _module(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module(p): p for p in APP.rglob("*.py")}


def import_graph() -> dict[str, set[str]]:
    """module -> the app modules it imports anywhere in its text (lazy imports included)."""
    graph = {}
    for mod, path in MODULES.items():
        deps = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                for alias in node.names:
                    sub = f"{node.module}.{alias.name}"
                    deps.add(sub if sub in MODULES else node.module)
            elif isinstance(node, ast.Import):
                deps.update(alias.name for alias in node.names)
        graph[mod] = {d for d in deps if d in MODULES and d != mod}
    return graph


def strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's algorithm: the components of more than one module are the import cycles."""
    index, low, stack, on_stack, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_cycle_finder_finds_a_cycle():
    assert strongly_connected({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_import_cycle():
    assert strongly_connected(import_graph()) == []


def test_generic_job_runner_knows_no_job():
    graph = import_graph()
    assert not {d for d in graph["app.jobs"] if d.startswith(("app.hdr", "app.pbgi", "app.ui"))}


def test_no_duplicate_code():
    """pylint's similarity checker over the package: no run of 6 or more lines (comments,
    docstrings and imports aside) is written twice."""
    res = subprocess.run([sys.executable, "-m", "pylint", "--disable=all",
                          "--enable=duplicate-code", "--min-similarity-lines=6", "--score=n",
                          str(APP)], capture_output=True, text=True, cwd=ROOT)
    assert res.returncode == 0, res.stdout + res.stderr


def test_no_test_seams_in_the_package():
    """Production code reads no environment variable that only tests set."""
    seams = ("SCANLIGHT_RELIGHTER", "SCANLIGHT_UI_SCRIPT", "SCANLIGHT_UI_OUT", "SCANLIGHT_UI_MODE")
    for path in APP.rglob("*.py"):
        text = path.read_text()
        assert not [s for s in seams if s in text], path
