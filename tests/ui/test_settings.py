"""The settings table, the change set, and session JSON (save, load, last session)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from app.camera import Camera
from app.errors import ScanlightError
from app.material import Material
from app.params import BY_KEY, PARAMS, markdown_table
from app.settings import (
    DOCUMENT_KEYS,
    AssetTransform,
    CaptureCamera,
    ChangeHandlers,
    Session,
    Settings,
    last_session_path,
    load_last_session,
    load_session,
    save_last_session,
)


def test_table_is_consistent():
    """Every default is valid for its own declaration, keys are unique and grouped."""
    assert len(BY_KEY) == len(PARAMS)
    for s in PARAMS:
        assert s.group in ("view", "light", "compare", "pbgi", "hdr"), s.key
        assert s.help.strip(), s.key
        assert s.clamp(s.default) == s.default and s.check(s.default) == s.default, s.key
        if s.kind in ("float", "int"):
            assert s.lo < s.hi, s.key
            assert s.default is None or s.lo <= s.default <= s.hi, s.key
            lo, hi = s.slider_range
            assert s.lo <= lo < hi <= s.hi, s.key
        if s.kind == "choice":
            assert s.default in s.choices and len(set(s.choices)) == len(s.choices), s.key
    table = markdown_table().splitlines()
    assert len(table) == 2 + len(PARAMS)
    assert all(f"`{s.key}`" in markdown_table() for s in PARAMS)


def test_change_set_records_only_real_changes():
    st = Settings()
    assert st.take_changes() == frozenset()
    assert st.set("view.exposure", 1.5) is True
    assert st.set("view.exposure", 1.5) is False          # same value: no change
    assert st.set("pbgi.mode", "envmap") is True
    st.mark("materials")
    # the mode is one of the quality preset's settings: the preset becomes "custom" with it
    assert st.take_changes() == {"view.exposure", "pbgi.mode", "pbgi.quality", "materials"}
    assert st.take_changes() == frozenset()                # taken once
    st.reset("view.exposure")
    assert st.take_changes() == {"view.exposure"} and st["view.exposure"] == 0.0


def test_change_handlers_run_once_each_in_connection_order():
    """napari-style subscriptions, dispatched once per change set: per key, per group and per
    Param.redo; each handler once, with its own changed keys, in the order connected."""
    calls = []
    h = ChangeHandlers()
    h.connect(("files.cloud", "files.photo"), lambda k: calls.append(("files", k)))
    h.connect("view.exposure", lambda k: calls.append(("exposure", k)))
    h.connect_group("pbgi", lambda k: calls.append(("pbgi", k)))
    h.connect_redo("display", lambda k: calls.append(("display", k)))
    h.dispatch({"view.exposure", "pbgi.mode", "pbgi.frame_budget_ms", "files.photo",
                "files.cloud", "capture_cameras"})
    assert calls == [("files", {"files.cloud", "files.photo"}), ("exposure", {"view.exposure"}),
                     ("pbgi", {"pbgi.mode", "pbgi.frame_budget_ms"}),
                     ("display", {"view.exposure"})]
    calls.clear()
    h.dispatch({"hdr.bins", "capture_cameras"})            # nobody listens: nothing runs
    h.dispatch(frozenset())
    assert calls == []
    redo_display = {p.key for p in PARAMS if p.redo == "display"}
    assert {k for k in redo_display if h.handlers_for(k)} == redo_display


def test_change_handlers_refuse_unknown_keys():
    """A renamed or misspelt key cannot silently lose its handler."""
    h = ChangeHandlers()
    for connect, arg in ((h.connect, "view.exposur"), (h.connect, ()), (h.connect_group, "viw"),
                         (h.connect_redo, "everything")):
        with pytest.raises(ValueError):
            connect(arg, print)
    for key in DOCUMENT_KEYS + tuple(BY_KEY):
        h.connect(key, print)


def test_values_are_validated_and_clamped():
    st = Settings()
    st.set("pbgi.microbuffer", 100)
    assert st["pbgi.microbuffer"] == BY_KEY["pbgi.microbuffer"].hi
    st.set("pbgi.microbuffer", 11.6)
    assert st["pbgi.microbuffer"] == 12 and isinstance(st["pbgi.microbuffer"], int)
    st.set("view.exposure", -99)
    assert st["view.exposure"] == -10.0
    for key, bad in (("view.exposure", float("nan")), ("view.exposure", "3"),
                     ("pbgi.mode", "fast"), ("view.show_cameras", 2), ("view.exposure", True)):
        with pytest.raises(ScanlightError) as err:
            st.set(key, bad, source="s.json")
        assert key in str(err.value) and "s.json" in str(err.value)
    with pytest.raises(ScanlightError, match="unknown setting"):
        st.set("view.nope", 1)


def test_asset_transform_matches_object_json_placement():
    """Same convention as the object JSON (app.io.formats): T @ scale @ Rz Ry Rx."""
    from app.io.formats import ObjectSpec, object_matrix
    t = AssetTransform((0.1, 0.6, -0.3), (20.0, -35.0, 50.0), 0.7)
    ref = object_matrix(ObjectSpec("sphere", t.translate, t.scale, t.rotate_deg))
    np.testing.assert_allclose(t.matrix(), ref, atol=1e-12)
    quarter = AssetTransform((0, 0, 0), (0.0, 90.0, 0.0), 2.0).matrix()
    np.testing.assert_allclose(quarter @ [1, 0, 0, 1], [0, 0, -2, 1], atol=1e-12)  # +x -> -z
    back = AssetTransform.from_matrix(t.matrix())
    np.testing.assert_allclose(back.matrix(), t.matrix(), atol=1e-9)
    np.testing.assert_allclose(back.rotate_deg, t.rotate_deg, atol=1e-7)


def _session(tmp_path) -> Session:
    cloud = tmp_path / "data" / "room.ply"
    cloud.parent.mkdir()
    cloud.write_text("ply")
    s = Session(cloud=str(cloud), photo="demo", asset="knot",
                transform=AssetTransform((1.0, 2.0, 3.0), (0.0, 90.0, 0.0), 0.5),
                capture_cameras=[CaptureCamera("left", (0.5, 1.4, 0.8)),
                                 CaptureCamera("right", (-0.5, 1.2, 0.1))],
                materials=[Material(base_color=(0.1, 0.2, 0.3), roughness=0.25, name="paint")],
                camera=Camera((0, 1, 3), (0, 0.6, 0), fov_y_deg=40, width=64, height=48))
    s.settings.set("pbgi.mode", "envmap")
    s.settings.set("view.exposure", -1.25)
    s.settings.set("hdr.method", "landis")
    return s


def test_session_round_trip(tmp_path):
    s = _session(tmp_path)
    path = s.save(tmp_path / "sessions" / "look.json")
    d = json.loads(path.read_text())
    assert d["files"]["cloud"] == "../data/room.ply"    # stored relative to the session file
    assert d["mode"] == "envmap" and "pbgi.mode" not in d["settings"]
    back = load_session(path)
    assert back.cloud == str((tmp_path / "sessions" / "../data/room.ply"))
    assert back.settings.to_dict() == s.settings.to_dict()
    assert back.settings.take_changes() == frozenset()   # a loaded session is not "changed"
    assert back.capture_cameras == s.capture_cameras and back.transform == s.transform
    assert back.asset == "knot" and back.photo == "demo"
    assert back.materials[0].to_dict() == s.materials[0].to_dict()
    assert back.materials[0].name == "paint"
    np.testing.assert_allclose(back.camera.view(), s.camera.view())


def test_a_session_saved_before_a_preset_changed_opens_as_it_was_saved(tmp_path):
    """balanced was M 24 until 2026-12-06 (app/params.py: QUALITY_PRESETS) and a session stores
    every value: it keeps its M 24, and the quality says custom rather than naming a preset
    whose values it no longer has; choosing the preset again takes its values."""
    from app.params import QUALITY_PRESETS
    assert QUALITY_PRESETS["balanced"]["pbgi.microbuffer"] != 24
    s = _session(tmp_path)
    s.settings.set("pbgi.quality", "balanced")
    path = s.save(tmp_path / "old.json")
    d = json.loads(path.read_text())
    d["settings"]["pbgi.microbuffer"] = 24                 # what balanced stored before
    path.write_text(json.dumps(d))
    back = load_session(path)
    assert back.settings["pbgi.microbuffer"] == 24 and back.settings["pbgi.quality"] == "custom"
    back.settings.set("pbgi.quality", "balanced")
    assert back.settings["pbgi.microbuffer"] == QUALITY_PRESETS["balanced"]["pbgi.microbuffer"]


def test_bad_session_files_name_the_file(tmp_path):
    p = tmp_path / "s.json"
    cases = {
        "{": "not valid JSON",
        '{"files": {}}': "not a Scanlight session",
        '{"scanlight_session": 99}': "version",
        '{"scanlight_session": 1, "capture_cameras": [{"position": [1, 2]}]}': "position",
        '{"scanlight_session": 1, "settings": {"pbgi.mode": "x"}}': "pbgi.mode",
        '{"scanlight_session": 1, "asset_transform": {"scale": -1}}': "scale",
        '{"scanlight_session": 1, "materials": [{"roughness": "high"}]}': "roughness",
    }
    for text, what in cases.items():
        p.write_text(text)
        with pytest.raises(ScanlightError) as err:
            load_session(p)
        assert str(p) in str(err.value) and what in str(err.value), text
    with pytest.raises(ScanlightError, match="not found"):
        load_session(tmp_path / "missing.json")


def test_last_session_lives_in_the_config_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("SCANLIGHT_CONFIG", str(tmp_path / "cfg"))
    with pytest.raises(ScanlightError, match="no last session"):
        load_last_session()
    s = _session(tmp_path)
    s.path = tmp_path / "mine.json"
    save_last_session(s)
    assert last_session_path() == tmp_path / "cfg" / "last_session.json"
    assert s.path == tmp_path / "mine.json"               # the user's file name is kept
    d = json.loads(last_session_path().read_text())
    assert d["files"]["cloud"] == str((tmp_path / "data" / "room.ply").resolve())  # absolute
    assert load_last_session().settings["pbgi.mode"] == "envmap"
