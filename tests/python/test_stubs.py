"""The hand-written stub python/aos/_core.pyi must describe aos._core exactly: the same public
names, per class the same public members (properties read-only or writable as declared, static
methods static), and per function the same parameter names, in order, with defaults where the
stub has them. The stub and py.typed must be installed with the package."""

from __future__ import annotations

import ast
import inspect
import pathlib
from typing import Optional

import pytest

import aos
from aos import _core

PACKAGE_DIR = pathlib.Path(aos.__file__).parent
STUB_PATH = PACKAGE_DIR / "_core.pyi"


def _stub_module() -> ast.Module:
    return ast.parse(STUB_PATH.read_text(encoding="utf-8"))


def _public(name: str) -> bool:
    return not name.startswith("_")


def _assigned_names(node: ast.stmt) -> list[str]:
    if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
        return [node.target.id]
    if isinstance(node, ast.Assign):
        return [target.id for target in node.targets if isinstance(target, ast.Name)]
    return []


def _stub_top_level() -> dict[str, ast.stmt]:
    names: dict[str, ast.stmt] = {}
    for node in _stub_module().body:
        if isinstance(node, (ast.ClassDef, ast.FunctionDef)):
            names[node.name] = node
        for name in _assigned_names(node):
            names[name] = node
    return names


def _decorators(node: ast.FunctionDef) -> set[str]:
    result = set()
    for decorator in node.decorator_list:
        if isinstance(decorator, ast.Name):
            result.add(decorator.id)
        elif isinstance(decorator, ast.Attribute):
            result.add(decorator.attr)  # "setter" of @name.setter
    return result


def _split_top_level(text: str) -> list[str]:
    parts, depth, current = [], 0, ""
    for char in text:
        if char in "([{":
            depth += 1
        elif char in ")]}":
            depth -= 1
        if char == "," and depth == 0:
            parts.append(current.strip())
            current = ""
        else:
            current += char
    if current.strip():
        parts.append(current.strip())
    return parts


def _runtime_parameters(function: object, name: str) -> Optional[list[tuple[str, bool]]]:
    """(name, has_default) from the signature line pybind11 puts first in the docstring."""
    doc = getattr(function, "__doc__", None) or ""
    if not doc.startswith(name + "("):
        return None
    depth, end = 0, None
    for index in range(len(name), len(doc)):
        depth += doc[index] == "("
        depth -= doc[index] == ")"
        if depth == 0:
            end = index
            break
    assert end is not None, doc
    parameters = []
    for part in _split_top_level(doc[len(name) + 1:end]):
        parameter = part.split(":", 1)[0].split("=", 1)[0].strip()
        if parameter != "self":
            parameters.append((parameter, " = " in part))
    return parameters


def _stub_parameters(node: ast.FunctionDef) -> list[tuple[str, bool]]:
    args = node.args
    positional = args.posonlyargs + args.args
    first_default = len(positional) - len(args.defaults)
    parameters = [(arg.arg, index >= first_default) for index, arg in enumerate(positional)]
    if args.vararg:
        parameters.append(("*" + args.vararg.arg, False))
    parameters += [(arg.arg, default is not None)
                   for arg, default in zip(args.kwonlyargs, args.kw_defaults)]
    if args.kwarg:
        parameters.append(("**" + args.kwarg.arg, False))
    return [(name, has_default) for name, has_default in parameters if name != "self"]


def test_stub_and_marker_are_installed() -> None:
    assert STUB_PATH.is_file()
    assert (PACKAGE_DIR / "py.typed").is_file()


def test_installed_stub_is_current() -> None:
    source = pathlib.Path(__file__).resolve().parents[2] / "python" / "aos" / "_core.pyi"
    if not source.is_file():
        pytest.skip("not run from a source checkout")
    assert STUB_PATH.read_text(encoding="utf-8") == source.read_text(encoding="utf-8"), (
        "the installed aos/_core.pyi differs from python/aos/_core.pyi: run `pip install .`")


def test_version() -> None:
    assert "__version__" in _stub_top_level()
    assert aos.__version__ == _core.__version__
    assert [int(part) for part in aos.__version__.split(".")] >= [0, 1, 0]


def test_module_names_match_the_stub() -> None:
    stub = {name for name in _stub_top_level() if _public(name)}
    runtime = {name for name in dir(_core) if _public(name)}
    assert runtime - stub == set(), "in aos._core but missing from _core.pyi"
    assert stub - runtime == set(), "in _core.pyi but missing from aos._core"
    # Private names the stub declares exist too (the test hook, __version__).
    for name in _stub_top_level():
        if name.startswith("_") and isinstance(_stub_top_level()[name], ast.FunctionDef):
            assert hasattr(_core, name), name


def test_package_reexports_the_core() -> None:
    for name in aos.__all__:
        assert hasattr(aos, name), name
    public_core = {name for name in dir(_core) if _public(name)}
    assert public_core <= set(aos.__all__)


CLASSES = sorted(name for name, node in _stub_top_level().items()
                 if isinstance(node, ast.ClassDef))


@pytest.mark.parametrize("class_name", CLASSES)
def test_class_members_match_the_stub(class_name: str) -> None:
    node = _stub_top_level()[class_name]
    cls = getattr(_core, class_name, None)
    assert cls is not None, f"{class_name} is declared in the stub only"
    stub_members: dict[str, str] = {}  # name -> "attribute" | "property" | "static" | "method"
    writable: set[str] = set()
    for item in node.body:
        for name in _assigned_names(item):
            if isinstance(item, ast.AnnAssign) and "ClassVar" in ast.unparse(item.annotation):
                stub_members[name] = "classvar"
            else:
                stub_members[name] = "attribute"
                writable.add(name)
        if isinstance(item, ast.FunctionDef):
            decorators = _decorators(item)
            if "setter" in decorators:
                writable.add(item.name)
            elif "property" in decorators:
                stub_members[item.name] = "property"
            elif "staticmethod" in decorators:
                stub_members[item.name] = "static"
            else:
                stub_members[item.name] = "method"

    runtime_public = {name for name in dir(cls) if _public(name)}
    stub_public = {name for name in stub_members if _public(name)}
    assert runtime_public - stub_public == set(), f"{class_name}: missing from the stub"
    assert stub_public - runtime_public == set(), f"{class_name}: not in aos._core"

    for name, kind in stub_members.items():
        assert hasattr(cls, name), f"{class_name}.{name} declared in the stub only"
        static = inspect.getattr_static(cls, name)
        if kind in ("attribute", "property"):
            assert isinstance(static, property), f"{class_name}.{name} should be a property"
            is_writable = static.fset is not None
            assert is_writable == (name in writable), (
                f"{class_name}.{name}: writable at runtime is {is_writable}")
        elif kind == "static":
            assert isinstance(static, staticmethod), f"{class_name}.{name} should be static"
        elif kind == "method":
            assert callable(static), f"{class_name}.{name} should be a method"


def _functions():
    for name, node in _stub_top_level().items():
        if isinstance(node, ast.FunctionDef):
            yield name, getattr(_core, name, None), node
        elif isinstance(node, ast.ClassDef):
            for item in node.body:
                if (isinstance(item, ast.FunctionDef)
                        and not {"property", "setter"} & _decorators(item)
                        and item.name != "__init__"):
                    member = getattr(getattr(_core, name, None), item.name, None)
                    yield f"{name}.{item.name}", member, item


@pytest.mark.parametrize("qualified, function, node",
                         list(_functions()), ids=lambda value: value if isinstance(value, str) else "")
def test_parameters_match_the_stub(qualified: str, function: object, node: ast.FunctionDef) -> None:
    assert function is not None, f"{qualified} is declared in the stub only"
    runtime = _runtime_parameters(function, node.name)
    if runtime is None:
        pytest.skip(f"{qualified}: no pybind11 signature line (a Python-level dunder)")
    assert _stub_parameters(node) == runtime, qualified


@pytest.mark.parametrize("class_name", CLASSES)
def test_constructors_match_the_stub(class_name: str) -> None:
    node = _stub_top_level()[class_name]
    cls = getattr(_core, class_name, None)
    assert cls is not None, f"{class_name} is declared in the stub only"
    inits = [item for item in node.body
             if isinstance(item, ast.FunctionDef) and item.name == "__init__"]
    if not inits:
        # Not constructible from Python.
        with pytest.raises(TypeError):
            cls()
        return
    stub = _stub_parameters(inits[0])
    if hasattr(cls, "_fields"):
        # Options classes: keyword-only fields in the stub, **kwargs at runtime.
        assert [name for name, _ in stub] == list(cls._fields)
        assert all(has_default for _, has_default in stub)
        assert inits[0].args.kwonlyargs and not inits[0].args.args[1:]
    else:
        assert stub == _runtime_parameters(cls.__init__, "__init__"), class_name
