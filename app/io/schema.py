"""Strict reading of JSON inputs: parsing with a depth limit, and typed field readers.

Every JSON loader (camera, capture cameras, object, material, session, ``--params``, glTF's
document) parses through ``parse_json`` and reads its fields through ``Fields``, so the same rules
hold everywhere and each error is one line naming the file and the key:

- types, not just ranges: ``true`` is not 1, ``"64"`` is not 64, ``"123"`` is not a colour;
  a number is a finite JSON number (Python's parser reads ``NaN``, ``Infinity`` and ``1e400``;
  the readers refuse them, naming the key);
- integers are whole JSON numbers (``8`` or ``8.0``, not ``8.5``);
- vectors are lists of exactly 3 numbers, positions within ``MAX_COORD`` of the origin;
- keys a schema does not know are refused where the loader lists its keys (a typo such as
  "translation" is not silently ignored).

Parameters of the parameter table (session settings, ``--params``) are checked by their
``app.params.Param`` instead, which applies the same type rules.
"""

from __future__ import annotations

import json
import math
from typing import Any

from app.errors import ScanlightError
from app.io.limits import MAX_COORD, MAX_JSON_DEPTH

REQUIRED: Any = object()   # default of a field that must be present


def show(value, limit: int = 40) -> str:
    """``repr(value)``, cut to ``limit`` characters (a message stays one short line)."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def json_depth(doc) -> int:
    """Nesting depth of a parsed JSON value (a scalar is 0, ``[]`` and ``{}`` are 1)."""
    if not isinstance(doc, (dict, list)):
        return 0                      # a bare null, 42 or true: iterating it was a TypeError
    deepest, stack = 0, [(doc, 1)]
    while stack:
        value, depth = stack.pop()
        items = value.values() if isinstance(value, dict) else value
        deepest = max(deepest, depth)
        stack.extend((v, depth + 1) for v in items if isinstance(v, (dict, list)))
    return deepest if isinstance(doc, (dict, list)) else 0


def parse_json(text: str | bytes, source, what: str = "JSON", invalid: str = ""):
    """The parsed document, or one ScanlightError line: invalid JSON, or nesting deeper than
    MAX_JSON_DEPTH (Python's parser gives up near 1000 levels with a
    RecursionError; no Scanlight file needs more than a few)."""
    too_deep = f"{what} nested deeper than {MAX_JSON_DEPTH} levels"
    try:
        doc = json.loads(text)
    except RecursionError:
        raise ScanlightError(source, too_deep) from None
    except ValueError as exc:   # JSONDecodeError, UnicodeDecodeError, 5000-digit integers
        raise ScanlightError(source, f"{invalid or 'not valid ' + what} ({exc})") from None
    if json_depth(doc) > MAX_JSON_DEPTH:
        raise ScanlightError(source, too_deep)
    return doc


def is_number(v) -> bool:
    """A JSON number: not a string and not a boolean (numpy scalars count, for in-memory use)."""
    import numpy as np
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(
        v, (bool, np.bool_))


def _as_float(value) -> float:
    """A number as a float; NaN for anything else and for integers beyond float (10**400)."""
    try:
        return float(value) if is_number(value) else math.nan
    except OverflowError:
        return math.nan


def _g(x) -> str:
    """A limit as people write it: 16384, 0.1, 1e-6, 1e9."""
    return f"{x:g}".replace("e+0", "e").replace("e-0", "e-").replace("e+", "e")


def _range_text(lo, hi) -> str:
    if lo is not None and hi is not None:
        return f" in [{_g(lo)}, {_g(hi)}]"
    if lo is not None:
        return f" >= {_g(lo)}"
    return f" <= {_g(hi)}" if hi is not None else ""


def number_value(value, what: str, source, lo=None, hi=None, unit: str = "") -> float:
    """``value`` as a finite float within ``lo .. hi``; ``what`` names it in the error."""
    v = _as_float(value)
    if not math.isfinite(v) or (lo is not None and v < lo) or (hi is not None and v > hi):
        unit = f" {unit}" if unit else ""
        raise ScanlightError(source, f"{what} must be a number{_range_text(lo, hi)}{unit}, "
                                     f"got {show(value)}")
    return v


def integer_value(value, what: str, source, lo=None, hi=None) -> int:
    """``value`` as an int within ``lo .. hi`` (``8.0`` is 8; ``true`` and ``8.5`` are not)."""
    f = _as_float(value)
    v = int(f) if math.isfinite(f) and f == int(f) else None
    if v is None or (lo is not None and v < lo) or (hi is not None and v > hi):
        raise ScanlightError(source, f"{what} must be an integer{_range_text(lo, hi)}, "
                                     f"got {show(value)}")
    return v


def vec3_value(value, what: str, source, limit: float | None = MAX_COORD
               ) -> tuple[float, float, float]:
    """3 finite JSON numbers, each within ``limit`` of 0 (None: any finite number)."""
    import numpy as np
    ok = isinstance(value, (list, tuple, np.ndarray)) and np.shape(value) == (3,)
    vals = [_as_float(v) for v in value] if ok else []
    if not ok or not all(math.isfinite(v) and (limit is None or abs(v) <= limit) for v in vals):
        within = f" within {_g(limit)} m of the origin" if limit is not None else ""
        raise ScanlightError(source, f"{what} must be a list of 3 finite numbers{within}, got "
                                     f"{show(value)}")
    return tuple(vals)


def string_value(value, what: str, source, nonempty: bool = False) -> str:
    if not isinstance(value, str) or (nonempty and not value.strip()):
        raise ScanlightError(source, f"{what} must be a{' non-empty' if nonempty else ''} "
                                     f"string, got {show(value)}")
    return value


def path_value(value, what: str, source, alternatives: str = "") -> str:
    """A non-empty string usable as a file path (no NUL character, which no OS allows);
    ``alternatives`` names the words accepted instead of a path, for the message."""
    if not isinstance(value, str) or not value.strip() or "\0" in value:
        raise ScanlightError(source, f"{what} must be a file path{alternatives}, got "
                                     f"{show(value)}")
    return value


class Fields:
    """The fields of one JSON object, read by type. ``what`` names the object in errors
    ("camera", "capture camera 2", "session 'asset_transform'"); ``known``, when given, lists
    every key the object may have (others are refused)."""

    def __init__(self, value, what: str, source, known: tuple[str, ...] | None = None):
        if not isinstance(value, dict):
            raise ScanlightError(source, f"{what} must hold a JSON object {{...}}, got "
                                         f"{show(value)}")
        self.d, self.what, self.source = value, what, source
        if known is not None:
            unknown = sorted(k for k in value if k not in known)
            if unknown:
                raise ScanlightError(source, f"unknown {what} key(s) "
                                             f"{', '.join(show(k) for k in unknown)} "
                                             f"(known: {', '.join(known)})")

    def __contains__(self, key: str) -> bool:
        return key in self.d

    def _name(self, key: str) -> str:
        return f"{self.what} {key!r}"

    def _get(self, key: str, default):
        if key in self.d:
            return self.d[key], True
        if default is REQUIRED:
            raise ScanlightError(self.source, f"{self.what} is missing {key!r}")
        return default, False

    def number(self, key: str, default=REQUIRED, lo=None, hi=None, unit: str = "") -> float:
        v, given = self._get(key, default)
        return number_value(v, self._name(key), self.source, lo, hi, unit) if given else v

    def integer(self, key: str, default=REQUIRED, lo=None, hi=None) -> int:
        v, given = self._get(key, default)
        return integer_value(v, self._name(key), self.source, lo, hi) if given else v

    def vec3(self, key: str, default=REQUIRED, limit: float | None = MAX_COORD):
        v, given = self._get(key, default)
        return vec3_value(v, self._name(key), self.source, limit) if given else v

    def string(self, key: str, default=REQUIRED, nonempty: bool = False):
        v, given = self._get(key, default)
        return string_value(v, self._name(key), self.source, nonempty) if given else v

    def path(self, key: str, default=REQUIRED, alternatives: str = ""):
        v, given = self._get(key, default)
        return path_value(v, self._name(key), self.source, alternatives) if given else v

    def optional(self, key: str, kind: type | tuple, default=None):
        """The raw value when it is of ``kind`` (dict, list...), ``default`` when the key is
        absent or null; otherwise an error naming the key."""
        v = self.d.get(key)
        if v is None:
            return default
        if not isinstance(v, kind):
            names = {dict: "an object", list: "a list", str: "a string"}
            kinds = kind if isinstance(kind, tuple) else (kind,)
            expected = " or ".join(names.get(k, k.__name__) for k in kinds)
            raise ScanlightError(self.source, f"{self._name(key)} must be {expected} or null, "
                                              f"got {show(v)}")
        return v
