"""A non-editable install, imported from another directory, finds its shaders."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_wheel_install_ships_shaders(tmp_path):
    target = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation",
                    "--target", str(target), str(ROOT)], check=True, cwd=tmp_path)
    # Every shader of the source tree is in the installed package.
    shipped = {p.relative_to(target / "app" / "shaders").as_posix()
               for p in (target / "app" / "shaders").rglob("*.glsl")}
    expected = {p.relative_to(ROOT / "shaders").as_posix() for p in (ROOT / "shaders").rglob("*.glsl")}
    assert expected and expected <= shipped
    # Imported from elsewhere, the installed copy (not the checkout) resolves and expands them.
    code = ("import app.render.programs as p, sys; d = p.shaders_dir(); print(d); "
            "src, _ = p.build_source('splat.glsl', 'VERTEX_SHADER'); assert 'gl_PointSize' in src")
    out = subprocess.run([sys.executable, "-I", "-c", f"import sys; sys.path.insert(0, {str(target)!r}); {code}"],
                         check=True, cwd=tmp_path, capture_output=True, text=True).stdout
    assert Path(out.strip()).is_relative_to(target)


def test_every_subpackage_is_listed_in_pyproject():
    import tomllib
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "app").rglob("__init__.py")}
    assert found <= listed, f"add to pyproject.toml packages: {sorted(found - listed)}"
