"""The benchmark record format: {"bench": NAME, "case": {...}, "metrics": {name_with_unit: number}}."""

from __future__ import annotations

import math


def record(bench: str, case: dict, metrics: dict) -> dict:
    return {"bench": bench, "case": dict(case), "metrics": {k: float(v) for k, v in metrics.items()}}


def _fmt(v) -> str:
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        return f"{v:.4g}" if abs(v) < 1e5 else f"{v:.3e}"
    return str(v)


def table(records: list[dict]) -> str:
    """A readable plain-text table: one row per case, one column per case key and metric."""
    if not records:
        return "(no records)"
    ckeys = list(dict.fromkeys(k for r in records for k in r["case"]))
    mkeys = list(dict.fromkeys(k for r in records for k in r["metrics"]))
    head = ckeys + mkeys
    rows = [[_fmt(r["case"].get(k, "")) for k in ckeys] + [_fmt(r["metrics"].get(k, float("nan")))
                                                           for k in mkeys] for r in records]
    widths = [max(len(h), *(len(row[i]) for row in rows)) for i, h in enumerate(head)]
    line = lambda cells: "  ".join(c.rjust(w) for c, w in zip(cells, widths))
    return "\n".join([line(head), line(["-" * w for w in widths])] + [line(r) for r in rows])


def write_json(records: list[dict], path) -> None:
    from app.io.files import write_json as write
    write(path, records)
