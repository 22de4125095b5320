"""The command line and the Python call that set a given Options value, from its field table.

Every field of an Options class with a field table (cpp/aos/util/option_fields.h) has its
aos-render flag in the row (`_field_table[i]["flag"]`, the flag cpp/exe/cli.h binds). These
helpers spell a value the way that flag and the Python keyword read it, and list only what
differs from the default, numbers in their shortest exact text, so that a generated command
renders what its options do (the viewer's "copy command", python/aos/viewer/session.py). A value with no spelling (a surface
built in memory) raises ValueError naming the field.
"""
from __future__ import annotations

import math
import shlex
from typing import Any, Iterable, Mapping, Optional, Sequence

import numpy as np


def _number(value: float) -> str:
    # The shortest text that reads back as the same double (repr), "3" for 3.0.
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    text = repr(float(value) + 0.0)
    return text[:-2] if text.endswith(".0") else text


def ranges_text(indices: Sequence[int]) -> str:
    """[0, 1, 2, 6] -> '0:3,6' (what --view-indices reads)."""
    parts: list[str] = []
    ordered = list(indices)
    i = 0
    while i < len(ordered):
        j = i
        while j + 1 < len(ordered) and ordered[j + 1] == ordered[j] + 1:
            j += 1
        parts.append(str(ordered[i]) if j == i else f"{ordered[i]}:{ordered[j] + 1}")
        i = j + 1
    return ",".join(parts)


def _plane_numbers(plane: Any) -> list[float]:
    # + 0.0: no "-0.0" in the text.
    return [float(v) + 0.0 for v in np.asarray(plane.point)] + [
        float(v) + 0.0 for v in np.asarray(plane.normal)]


def _horizontal(plane: Any) -> bool:
    return [float(v) for v in np.asarray(plane.normal)] == [0.0, 0.0, 1.0]


def flag_text(name: str, value: Any) -> Optional[str]:
    """The text a flag reads for `value`; None for a switch that is off ("" for one that is on);
    a list of numbers other than view indices as its numbers separated by spaces (one argument
    each, as --extent reads them)."""
    kind = type(value).__name__
    if isinstance(value, (bool, np.bool_)):
        return "" if value else None
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return _number(float(value))
    if isinstance(value, str):
        return value
    if kind == "Rigid3d":
        return ",".join(_number(float(v)) for v in np.asarray(value.matrix3x4).ravel())
    if kind == "FocalSurface":
        if value.plane is not None:
            if _horizontal(value.plane):
                return _number(float(np.asarray(value.plane.point)[2]))
            return ",".join(_number(v) for v in _plane_numbers(value.plane))
        if value.file:
            return value.file
        raise ValueError(f"{name}: a focal surface built in memory has no command-line spelling "
                         "(write it to a file and read it with aos.FocalSurface.read)")
    if hasattr(type(value), "__members__"):  # an enum: its name
        return value.name
    if isinstance(value, (list, tuple)):
        if name == "view_indices":
            return ranges_text(value)
        return " ".join(flag_text(name, v) or "" for v in value)
    raise ValueError(f"{name}: no command-line spelling for a {kind}")


def python_text(name: str, value: Any) -> str:
    """A Python expression for `value` as the keyword `name` takes it."""
    kind = type(value).__name__
    if isinstance(value, (float, np.floating)) and math.isinf(value):
        return 'float("inf")' if value > 0 else '-float("inf")'
    if isinstance(value, (bool, int, float, str, np.integer, np.floating, np.bool_)):
        return repr(value.item() if isinstance(value, np.generic) else value)
    if kind == "Rigid3d":
        numbers = [float(v) + 0.0 for v in np.asarray(value.matrix3x4).ravel()]
        return f"aos.Rigid3d.from_matrix3x4({numbers!r})"
    if kind == "FocalSurface":
        if value.plane is not None:
            if _horizontal(value.plane):
                return repr(float(np.asarray(value.plane.point)[2]))
            numbers = _plane_numbers(value.plane)
            return f"aos.Plane({tuple(numbers[:3])!r}, {tuple(numbers[3:])!r})"
        if value.file:
            return f"aos.FocalSurface.read({value.file!r})"
        raise ValueError(f"{name}: a focal surface built in memory has no Python spelling here")
    if hasattr(type(value), "__members__"):
        return repr(value.name)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(python_text(name, v) for v in value) + "]"
    raise ValueError(f"{name}: no Python spelling for a {kind}")


def changed_fields(options: Any, table: Optional[Iterable[Mapping[str, Any]]] = None,
                   defaults: Any = None, skip: Iterable[str] = ()) -> list[tuple[dict, Any]]:
    """(row, value) of every field whose spelling differs from the default's, in table order.
    `options` is an Options object, or a dict of values with `table` and `defaults` given."""
    rows = list(table if table is not None else type(options)._field_table)
    if defaults is None:
        defaults = type(options)()
    skipped = set(skip)
    get = (lambda o, n: o.get(n)) if isinstance(options, Mapping) else getattr
    default_of = (lambda n: defaults.get(n)) if isinstance(defaults, Mapping) else (
        lambda n: getattr(defaults, n))
    changed = []
    for row in rows:
        name = row["name"]
        if name in skipped:
            continue
        value = get(options, name)
        if value is None:
            continue
        if flag_text(name, value) != flag_text(name, default_of(name)):
            changed.append((dict(row), value))
    return changed


def cli_arguments(changed: Sequence[tuple[dict, Any]]) -> str:
    """The flags of `changed` (changed_fields) as one shell-quoted string."""
    words: list[str] = []
    for row, value in changed:
        text = flag_text(row["name"], value)
        if text is None:  # a switch turned off: only a default of off is spelt (by nothing)
            raise ValueError(f"{row['name']}: no flag turns it off (its default is on)")
        words.append(row["flag"])
        if isinstance(value, (list, tuple)) and row["name"] != "view_indices":
            words += [shlex.quote(part) for part in text.split(" ")]
        elif not isinstance(value, (bool, np.bool_)):
            words.append(shlex.quote(text))
    return " ".join(words)


def python_keywords(changed: Sequence[tuple[dict, Any]]) -> str:
    """The keywords of `changed` (changed_fields): 'name=expr, ...'."""
    return ", ".join(f"{row['name']}={python_text(row['name'], value)}" for row, value in changed)
