"""``scanlight bench viewer`` (app/bench/viewer.py): the viewer's time to a converged picture
after an orbit and after each BRDF slider, through the viewer's own engine."""

from __future__ import annotations

import argparse

import pytest

from app.bench import viewer


def _args(*argv):
    ap = argparse.ArgumentParser()
    viewer.add_arguments(ap)
    return ap.parse_args(list(argv))


def test_orbit_and_sliders_converge_and_are_timed(capsys):
    """One record per change, each converged (the engine's refinement reached 100%: the loop
    stops only when gi.refining is False) in a positive time; the table names every row."""
    records = viewer.run(_args("--size", "64x48", "--presets", "preview",
                               "--sliders", "base_color,roughness"))
    assert [r["case"]["change"] for r in records] == ["orbit", "base_color", "roughness"]
    for rec in records:
        m = rec["metrics"]
        assert m["converged"] == 1.0 and m["s"] > 0 and m["frames"] >= 1 and m["first_ms"] > 0
        assert m["shadow_s"] >= m["s"]                   # the scan's shadow follows the GI
    colour, rough = records[1], records[2]
    assert colour["metrics"]["recombined"] == 1.0 and colour["case"]["edit"] == "recombined"
    assert colour["metrics"]["frames"] == 1                # converged in the edit's own frame
    assert rough["metrics"]["recombined"] == 0.0 and "roughness" in rough["case"]["edit"]
    out = capsys.readouterr().out
    assert "| preview | orbit |" in out and "| preview | roughness |" in out


def test_converge_reports_a_timeout_instead_of_hanging():
    """A refinement that cannot finish in the time given is reported as not converged."""
    class Stuck:
        class gi:
            refining = True
        def frame(self, interacting=False):
            return {"ms": 1.0}
    res = viewer.converge(Stuck(), timeout_s=0.05)
    assert res["converged"] is False and res["s"] != res["s"]      # NaN


@pytest.mark.parametrize("argv", [["--presets", "fastest"], ["--sliders", "glow"]])
def test_unknown_names_are_usage_errors(argv):
    from app.errors import UsageError
    with pytest.raises(UsageError):
        viewer.run(_args(*argv))


def test_size_is_checked():
    with pytest.raises(SystemExit):
        _args("--size", "big")
