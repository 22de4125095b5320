#!/usr/bin/env python3
"""Writes what the Options structs' field tables define into the files that restate them:

- python/aos/_core.pyi: the head of every Options class (docstring, keyword constructor, one
  annotated attribute or property per field with its help, to_json/from_json), from the class's
  ``_field_table`` (cpp/aos/util/option_fields.h; cpp/python/bindings.h OptionsClass::Table).
  The methods after it (check, __eq__, ...) stay hand-written.
- python/aos/_keywords.py: the keyword TypedDict of every wrapper, from its router
  (aos._Router: the routed field names, each typed as its field's table says it is given, plus
  the router's ``also`` types).

    python3 tools/options.py            # rewrites both files
    python3 tools/options.py --check    # exit 1 naming the stale files (tests/python/test_options.py)

Standard library only (and the aos under test).
"""
from __future__ import annotations

import argparse
import re
import sys
import textwrap
import warnings
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
STUB = ROOT / "python" / "aos" / "_core.pyi"
KEYWORDS = ROOT / "python" / "aos" / "_keywords.py"
WIDTH = 100


def _docstring(text: str, indent: str) -> list[str]:
    """A docstring of `text` wrapped at WIDTH columns."""
    text = " ".join(text.split()).replace('"""', "'''")
    one = f'{indent}"""{text}"""'
    if len(one) <= WIDTH:
        return [one]
    lines = textwrap.wrap(text, WIDTH - len(indent) - 3)
    lines[0] = '"""' + lines[0]
    return [indent + line for line in lines[:-1]] + [indent + lines[-1] + '"""']


def option_classes() -> list[type]:
    from aos import _core

    return [getattr(_core, name) for name in dir(_core)
            if hasattr(getattr(_core, name), "_field_table")]


def options_base(cls: type) -> type | None:
    """The Options class `cls` derives from (ApertureOptions), or None."""
    base = cls.__bases__[0]
    return base if hasattr(base, "_field_table") else None


def stub_head(cls: type) -> list[str]:
    """The generated head of `cls`'s block in _core.pyi: the fields of a base Options class
    (OptionsClass<Options, Base>) are typed on the base only, and the constructor takes them."""
    name = cls.__name__
    table = cls._field_table  # type: ignore[attr-defined]
    base = options_base(cls)
    inherited = {row["name"] for row in base._field_table} if base else set()  # type: ignore
    lines = [f"class {name}({base.__name__}):" if base else f"class {name}:"]
    lines += _docstring(cls.__doc__ or name, "    ")
    lines += ["", "    _fields: ClassVar[tuple[str, ...]]", "    def __init__(", "        self,",
              "        *,"]
    for row in sorted(table, key=lambda row: row["name"] in inherited):
        lines.append(f"        {row['name']}: {row['given']} = ...,")
    lines += ["    ) -> None:", '        """Defaults from C++; unknown names raise TypeError."""']
    for row in table:
        if row["name"] in inherited:
            continue
        help_text = row["help"]
        if row["unit"] or row["range"]:
            facts = ", ".join(part for part in (row["unit"], row["range"]) if part)
            help_text = f"{help_text} [{facts}]"
        if row["type"] == row["given"]:
            lines.append(f"    {row['name']}: {row['type']}")
            lines += _docstring(help_text, "    ")
        else:
            lines += ["    @property", f"    def {row['name']}(self) -> {row['type']}:"]
            lines += _docstring(help_text, "        ")
            setter = f"    def {row['name']}(self, value: {row['given']}) -> None: ..."
            if len(setter) > WIDTH:
                setter = (f"    def {row['name']}(\n        self, value: {row['given']}\n"
                          "    ) -> None: ...")
            lines += [f"    @{row['name']}.setter", setter]
    for old, new in sorted(getattr(cls, "_deprecated", {}).items()):
        row = next(row for row in table if row["name"] == new)
        # A deprecated spelling (OptionsClass::Deprecated): typed as what it reads, so that
        # code using it type-checks for the release it is kept.
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            read = type(getattr(cls(), old)).__name__
        lines += ["    @property", f"    def {old}(self) -> {read} | None:",
                  f'        """Deprecated: use {new}."""',
                  f"    @{old}.setter",
                  f"    def {old}(self, value: {row['given']}) -> None: ..."]
    lines += ["    def to_json(self) -> str:",
              '        """The options as one JSON object (lightfield/options_json.h)."""',
              "    @staticmethod",
              f"    def from_json(text: str) -> {name}:",
              '        """Default options with the JSON object\'s members read in (ValueError '
              'naming the key)."""']
    return lines


def write_stub(text: str) -> str:
    lines = text.split("\n")
    for cls in option_classes():
        start = next((i for i, line in enumerate(lines)
                      if re.match(rf"class {cls.__name__}\b", line)), None)
        if start is None:
            raise SystemExit(f"{STUB}: no block 'class {cls.__name__}' to write its head into "
                             "(add the class with its check/__eq__ methods by hand)")
        end = start + 1
        while not re.match(r"    def (check|__eq__|__copy__|__repr__)\b", lines[end]):
            if lines[end].startswith("class "):
                raise SystemExit(f"{STUB}: class {cls.__name__} has no check/__eq__ method to "
                                 "end its generated head")
            end += 1
        lines[start:end] = stub_head(cls)
    text = "\n".join(lines)
    # The typing names the heads use.
    match = re.search(r"^from typing import (.*)$", text, re.M)
    if match is None:
        raise SystemExit(f"{STUB}: no 'from typing import' line")
    names = set(match.group(1).split(", ")) | {"ClassVar", "Literal", "Sequence"}
    return text.replace(match.group(0), "from typing import " + ", ".join(sorted(names)), 1)


def _union(types: list[str]) -> str:
    parts: list[str] = []
    for text in types:
        for part in text.split(" | "):
            if part not in parts:
                parts.append(part)
    if "None" in parts:  # last, as written by hand
        parts.remove("None")
        parts.append("None")
    return " | ".join(parts)


def keyword_types(router: Any) -> dict[str, str]:
    """Keyword -> its type: every field it routes to, as given, and the router's extras."""
    roots = [root_type() for root_type in router.root_types]
    types: dict[str, list[str]] = {}
    for name, paths in router.paths.items():
        for path in paths:
            owner = roots[path[0]]
            for step in path[1:-1]:
                owner = getattr(owner, step)
            row = next(row for row in type(owner)._field_table if row["name"] == name)
            types.setdefault(name, []).append(row["given"])
        if name in router.also:
            types[name].append(router.also[name])
    return {name: _union(found) for name, found in types.items()}


def keyword_owners(router: Any) -> dict[str, str]:
    """Keyword -> the name of the Options class whose table defines its field (the base block,
    ApertureOptions, for a field a render's options inherit); '' where several do."""
    roots = [root_type() for root_type in router.root_types]
    owners: dict[str, str] = {}
    for name, paths in router.paths.items():
        found = set()
        for path in paths:
            owner = roots[path[0]]
            for step in path[1:-1]:
                owner = getattr(owner, step)
            cls = type(owner)
            base = options_base(cls)
            while base is not None and any(row["name"] == name for row in base._field_table):
                cls, base = base, options_base(base)
            found.add(cls.__name__)
        owners[name] = found.pop() if len(found) == 1 else ""
    return owners


def reachable(root_types: list[type]) -> set[str]:
    """The names of the Options classes `root_types` fill, nested ones included."""
    found: set[str] = set()
    pending = [root() for root in root_types]
    while pending:
        options = pending.pop()
        if type(options).__name__ in found:
            continue
        found.add(type(options).__name__)
        for row in getattr(type(options), "_field_table", ()):
            value = getattr(options, row["name"], None)
            if hasattr(type(value), "_field_table"):
                pending.append(value)
    return found


def keywords_module() -> str:
    import aos

    routers = [value for value in vars(aos).values() if isinstance(value, aos._Router)]
    by_name: dict[str, list[Any]] = {}
    for router in routers:
        by_name.setdefault(router.keywords, []).append(router)
    used: set[str] = set()
    written: dict[str, dict[str, str]] = {}  # class -> every keyword it types, inherited too
    roots_of: dict[str, set[str]] = {}  # class -> the Options classes its routers fill
    planned: list[tuple[str, str, str | None, dict[str, str], dict[str, str]]] = []
    for keywords, group in by_name.items():
        types: dict[str, str] = {}
        owners: dict[str, str] = {}
        for router in group:
            for name, text in keyword_types(router).items():
                types[name] = _union([types[name], text]) if name in types else text
            for name, owner in keyword_owners(router).items():
                owners[name] = owner if owners.get(name, owner) == owner else ""
        functions = ", ".join(f"aos.{router.function}" for router in group)
        roots = ", ".join(dict.fromkeys(t.__name__ for router in group
                                        for t in router.root_types))
        # A class whose keywords (with the same types) are all this one's is its base: the
        # nested structs' fields are then typed once (mypy merges TypedDict bases).
        reach = reachable([t for router in group for t in router.root_types])
        bases = [name for name, typed in written.items()
                 if typed and roots_of[name] <= reach
                 and all(types.get(key) == text for key, text in typed.items())]
        base = max(bases, key=lambda name: len(written[name]), default=None)
        inherited = written[base] if base else {}
        own = {name: text for name, text in types.items() if name not in inherited}
        planned.append((keywords, f"{functions}: the fields of {roots}", base, own, owners))
        written[keywords] = dict(types)
        roots_of[keywords] = {t.__name__ for router in group for t in router.root_types}
    # The fields of one Options class that several keyword classes take alike (same names and
    # types: the detection options of aos.detect and aos.detect_map, the aperture block of the
    # renders, the telemetry fields of import_telemetry and import_video) are typed once, in a
    # TypedDict of their own that those classes derive from.
    taking: dict[str, list[dict[str, str]]] = {}  # owner -> each class's fields of it
    for _, _, _, own, owners in planned:
        for owner in {owners.get(name, "") for name in own} - {""}:
            taking.setdefault(owner, []).append(
                {name: text for name, text in own.items() if owners[name] == owner})
    shared: list[tuple[str, tuple[tuple[str, str], ...]]] = []
    for owner, fields in sorted(taking.items()):
        common = [(name, text) for name, text in fields[0].items()
                  if all(other.get(name) == text for other in fields[1:])]
        if len(fields) >= 2 and len(common) >= 3:
            shared.append((owner, tuple(common)))
    classes: list[str] = []
    for owner, block in shared:
        lines = [f"class {owner}Keywords(TypedDict, total=False):"]
        lines += _docstring(f"The fields of {owner} that several wrappers take alike: a base "
                            "of their keyword classes.", "    ")
        lines.append("")
        for name, text in block:
            lines.append(f"    {name}: {text}")
            used.update(re.findall(r"\b[A-Z]\w*", text))
        classes.append("\n".join(lines))
    for keywords, what, base, own, owners in planned:
        parents = [base] if base else []
        for owner, block in shared:
            if all(own.get(name) == text and owners.get(name) == owner for name, text in block):
                parents.append(f"{owner}Keywords")
                for name, _ in block:
                    del own[name]
        lines = [f"class {keywords}({', '.join(parents) or 'TypedDict'}, total=False):"]
        lines += _docstring(f"Keywords of {what} (nested ones included) that its router accepts"
                            + (f"; those of {', '.join(parents)} too." if parents else "."),
                            "    ")
        if own:
            lines.append("")
        for name, text in own.items():
            lines.append(f"    {name}: {text}")
            used.update(re.findall(r"\b[A-Z]\w*", text))
        classes.append("\n".join(lines))
    from aos import _core

    core_names = sorted(name for name in used if hasattr(_core, name))
    typing_names = sorted(name for name in used if name in ("Literal", "Sequence", "TypedDict"))
    head = f'''"""The keyword arguments of the aos wrappers, typed for type checkers. GENERATED by
tools/options.py from the routers (aos._Router) and the Options structs' field tables: do not edit.

Each wrapper (``aos.render_integral(light_field, **kwargs)``, ...) routes its keywords by name to
the fields of its C++ Options structs; these TypedDicts give those keywords their types, so that
``**kwargs: Unpack[IntegralKeywords]`` lets mypy reject ``aos.render_integral(lf,
pose_view="191")``. A keyword's type is what its field takes when set (a plane also as a number,
an enum also by name); tests/python/test_options.py fails when this file is stale.
"""

from __future__ import annotations

from typing import {", ".join(sorted(set(typing_names) | {"TypedDict"}))}

from ._core import (
{"".join(f"    {name},{chr(10)}" for name in core_names)})
'''
    return head + "\n\n" + "\n\n\n".join(classes) + "\n"


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if a file is stale")
    args = parser.parse_args(argv)
    outputs = {STUB: write_stub(STUB.read_text(encoding="utf-8")), KEYWORDS: keywords_module()}
    stale = [path for path, text in outputs.items() if path.read_text(encoding="utf-8") != text]
    if args.check:
        for path in stale:
            print(f"{path.relative_to(ROOT)} is stale: run python3 tools/options.py")
        return 1 if stale else 0
    for path in stale:
        path.write_text(outputs[path], encoding="utf-8")
        print(f"wrote {path.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
