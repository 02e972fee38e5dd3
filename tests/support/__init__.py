"""Helpers shared by the tests (scenes, image comparison, viewer sessions, BSH invariants).

Tests import these; no test imports another test, and fixtures live in ``conftest.py``.
"""

from pathlib import Path

TEST_SHADERS = Path(__file__).resolve().parent.parent / "shaders"   # test-only GLSL programs
