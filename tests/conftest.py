"""Shared fixtures: the GL context and the cached demo scene."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def ctx():
    from app.render.context import get_context
    return get_context()


@pytest.fixture(scope="session")
def demo():
    """The built-in demo scene (200k points; generated once, then cached on disk)."""
    from app.demo.cache import load_demo
    return load_demo()
