"""Fixtures of the viewer tests."""

from __future__ import annotations

import pytest

from tests.support.viewer import RenderCall, spy_renders


@pytest.fixture
def renders(monkeypatch) -> list[RenderCall]:
    """Every call of the real renderer during the test, with what it computed."""
    return spy_renders(monkeypatch)
