"""Shared fixtures: the GL context, the cached demo scene and the relighters built on it."""

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


@pytest.fixture(scope="module")
def demo_relighter(demo):
    """A Relighter with the demo room's ground-truth cloud and the default sphere."""
    from app.demo.room import default_object
    from app.io.formats import object_from_dict, placed_mesh
    from app.pbgi.renderer import Relighter
    r = Relighter()
    r.set_cloud(demo.gt)
    r.set_asset(placed_mesh(object_from_dict(default_object(), ".")))
    return r


@pytest.fixture(scope="module")
def furnace():
    """The white furnace: a sphere inside a closed shell of constant radiance 1."""
    from tests.support import scenes as S
    from app.pbgi.renderer import Relighter
    r = Relighter()
    r.set_cloud(S.furnace_shell(20000, radius=2.0, radiance=1.0))
    r.set_asset(S.sphere((0.0, 0.0, 0.0), 0.5, subdivisions=4))
    return r
