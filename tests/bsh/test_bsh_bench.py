"""``scanlight bench bsh``: arguments and the record format (tiny sizes; the real run is manual)."""

from __future__ import annotations

import argparse
import json

from app.bench import bsh
from app.bench.records import table, write_json
from app.pbgi.hierarchy import STAGES


def _args(argv):
    ap = argparse.ArgumentParser()
    bsh.add_arguments(ap)
    return ap.parse_args(argv)


def test_default_sizes_are_the_issue_s():
    assert _args([]).points == [100_000, 1_000_000, 3_000_000]


def test_records_have_the_promised_fields(tmp_path):
    records = bsh.run(_args(["--points", "3000,6000"]))
    assert [r["bench"] for r in records] == ["bsh", "bsh"]
    assert [r["case"]["points"] for r in records] == [3000, 6000]
    for r in records:
        m = r["metrics"]
        for key in ["seconds_total", "nodes", "clusters", "bytes_per_node"] + \
                [f"seconds_{s}" for s in STAGES]:
            assert key in m, key
        assert m["bytes_per_node"] == 40
        assert 0 < m["clusters"] <= m["nodes"]
        assert abs(sum(m[f"seconds_{s}"] for s in STAGES) - m["seconds_total"]) < 0.05
    assert records[1]["metrics"]["nodes"] > records[0]["metrics"]["nodes"]
    assert "seconds_total" in table(records)
    write_json(records, tmp_path / "bsh.json")
    assert json.loads((tmp_path / "bsh.json").read_text())[0]["case"]["points"] == 3000
