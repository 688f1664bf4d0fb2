"""The package's structure, read from its import graph (issue 15): layers along the data flow.

Units are the subpackages (``field``, ``maps`` ...) and the top-level modules (``errors``,
``pipeline`` ...). A unit imports only from itself or from a unit on a lower layer; across units
only through the other unit's facade (its ``__init__`` and the names in its ``__all__``); never a
private name of another module; package-internal imports at the top of a module; no import circle;
no module over 500 lines and no function over 80 (issue 24: "one model, written once"; exceptions are listed
in :data:`SIZE_EXCEPTIONS` with their reason).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "solenoid_fmu"

#: Layer of each unit, lowest first: the data flow of the README's package map.
LAYERS = {
    "errors": 0, "argtypes": 0, "_version": 0,
    "fileio": 1, "realtime": 1,
    "field": 2, "measure": 2,
    "identification": 3, "maps": 3,
    "fmu": 4, "rig": 4,
    "loop": 5, "report": 5,
    "pipeline": 6,
    "lot": 6.5,  # a production lot: above pipeline (runs it per unit), below api/cli
    "api": 7,
    "cli": 8,
    "__main__": 9,
}
#: Lines per module and per function (def to its end, decorators not counted): issue 24.
MAX_LINES = 500
MAX_FUNCTION_LINES = 80
#: Modules or functions (``path:function``) allowed to be longer, with the reason.
SIZE_EXCEPTIONS: dict[str, str] = {}
#: Function-level package imports allowed, with the reason.
LAZY_IMPORTS = {"__init__.py": "the public verbs load on first use so `import solenoid_fmu` stays cheap"}


def _modules() -> dict[str, Path]:
    """Dotted name (``solenoid_fmu.maps.io``) -> file, for every module of the package."""
    out = {}
    for f in sorted(PKG.rglob("*.py")):
        rel = f.relative_to(PKG.parent).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = f
    return out


MODULES = _modules()


def _unit(dotted: str) -> str | None:
    parts = dotted.split(".")
    return parts[1] if len(parts) > 1 else None


def _resolve(module: str, f: Path, node: ast.ImportFrom) -> str:
    """Absolute dotted name of the module a relative ``from ... import`` reads from."""
    if node.level == 0:
        return node.module or ""
    base = module.split(".")
    if f.name != "__init__.py":
        base = base[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _imports(modules: dict[str, Path]):
    """(importing module, file, target module, imported names, at module level?) for package imports."""
    found = []
    for module, f in modules.items():
        tree = ast.parse(f.read_text(encoding="utf-8"), filename=str(f))
        top_level = {id(n) for n in tree.body}
        top_level |= {id(n) for s in tree.body if isinstance(s, ast.If) for n in s.body}  # TYPE_CHECKING blocks
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                target = _resolve(module, f, node)
                names = [a.name for a in node.names]
            elif isinstance(node, ast.Import):
                target, names = None, [a.name for a in node.names]
                pkg_names = [n for n in names if n.split(".")[0] == "solenoid_fmu"]
                if not pkg_names:
                    continue
                target, names = pkg_names[0], []
            else:
                continue
            if not target.startswith("solenoid_fmu"):
                continue
            found.append((module, f, target, names, id(node) in top_level))
    return found


IMPORTS = _imports(MODULES)


def _where(f: Path) -> str:
    return str(f.relative_to(PKG)) if f.is_relative_to(PKG) else f.name


def test_the_graph_is_read():
    """The test sees the package: many modules, many internal imports (a broken reader fails here)."""
    assert len(MODULES) > 30
    assert len(IMPORTS) > 60
    assert {_unit(m) for m in MODULES} - {None} <= set(LAYERS), "a unit without a layer: add it to LAYERS"


def upward(imports) -> list[str]:
    bad = []
    for module, f, target, _names, _top in imports:
        a, b = _unit(module), _unit(target)
        if a is None or b is None or a == b:
            continue
        if LAYERS[b] >= LAYERS[a]:
            bad.append(f"{_where(f)}: {a} (layer {LAYERS[a]}) imports {target} (layer {LAYERS[b]})")
    return bad


def test_no_upward_or_sideways_import():
    bad = upward(IMPORTS)
    assert not bad, "\n".join(bad)


def past_facade(imports) -> list[str]:
    bad = []
    for module, f, target, names, _top in imports:
        a, b = _unit(module), _unit(target)
        if a is None or b is None or a == b:
            continue
        facade = f"solenoid_fmu.{b}"
        if target != facade:
            bad.append(f"{_where(f)}: imports {target}, not the facade {facade}")
            continue
        if (PKG / b / "__init__.py").exists():
            exported = _all_of(PKG / b / "__init__.py")
            missing = [n for n in names if n not in exported]
            if missing:
                bad.append(f"{_where(f)}: {', '.join(missing)} not in {facade}.__all__")
    return bad


def test_across_units_only_through_the_facade():
    bad = past_facade(IMPORTS)
    assert not bad, "\n".join(bad)


def _all_of(init: Path) -> set[str]:
    for node in ast.parse(init.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "__all__" for t in node.targets):
            return set(ast.literal_eval(node.value))
    return set()


def private(imports) -> list[str]:
    return [f"{_where(f)}: imports {n} from {target}"
            for module, f, target, names, _top in imports if target != module
            for n in names if n.startswith("_") and not n.startswith("__")]


def test_no_private_name_across_modules():
    bad = private(IMPORTS)
    assert not bad, "\n".join(bad)


def nested(imports) -> list[str]:
    return [f"{_where(f)}: imports {target} inside a function or class"
            for module, f, target, _names, top in imports
            if not top and _where(f) not in LAZY_IMPORTS]


def test_package_imports_at_the_top():
    bad = nested(IMPORTS)
    assert not bad, "\n".join(bad)


def test_no_import_circle():
    graph: dict[str, set[str]] = {m: set() for m in MODULES}
    for module, _f, target, names, top in IMPORTS:
        if not top:
            continue
        for t in [target] + [f"{target}.{n}" for n in names]:
            if t in MODULES and t != module:
                graph[module].add(t)
    # a package's __init__ imports its own modules; a module importing its own facade would close a circle
    state: dict[str, int] = {}
    circles = []

    def visit(m, path):
        state[m] = 1
        for n in sorted(graph[m]):
            if state.get(n) == 1:
                circles.append(" -> ".join(path[path.index(n):] + [n]))
            elif n not in state:
                visit(n, path + [n])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])
    assert not circles, "\n".join(circles)


def from_root(imports) -> list[str]:
    """Imports from the package root (``from .. import x``, ``import solenoid_fmu``) by any module but the root:
    the root re-exports the units, so such an import runs back up the layers (``__version__`` is in the leaf
    module ``_version``)."""
    return [f"{_where(f)}: imports {', '.join(names) or target} from the package root"
            for module, f, target, names, _top in imports if target == "solenoid_fmu" and module != "solenoid_fmu"]


def test_no_import_from_the_package_root():
    bad = from_root(IMPORTS)
    assert not bad, "\n".join(bad)


def test_the_rules_catch_a_bad_module(tmp_path):
    """The checks are live: an upward import, an inner module, a private name and a nested import are found."""
    f = tmp_path / "probe.py"
    f.write_text("from ..loop import improve\nfrom ..maps.io import _read\nfrom .. import __version__\n\n"
                 "def f():\n    from ..rig import run_campaign\n", encoding="utf-8")
    imports = _imports({"solenoid_fmu.field.probe": f})
    assert [(t, n, top) for _m, _f, t, n, top in imports] == [
        ("solenoid_fmu.loop", ["improve"], True), ("solenoid_fmu.maps.io", ["_read"], True),
        ("solenoid_fmu", ["__version__"], True), ("solenoid_fmu.rig", ["run_campaign"], False)]
    assert len(upward(imports)) == 3
    assert "probe.py: imports solenoid_fmu.maps.io, not the facade solenoid_fmu.maps" in past_facade(imports)
    assert private(imports) == ["probe.py: imports _read from solenoid_fmu.maps.io"]
    assert nested(imports) == ["probe.py: imports solenoid_fmu.rig inside a function or class"]
    assert from_root(imports) == ["probe.py: imports __version__ from the package root"]


def _long_module(f: Path, limit: int) -> str | None:
    """``path has n lines (> limit)`` if ``f`` is over ``limit`` lines and not a listed exception, else None."""
    n = len(f.read_text(encoding="utf-8").splitlines())
    return f"{_where(f)} has {n} lines (> {limit})" if n > limit and _where(f) not in SIZE_EXCEPTIONS else None


def _long_functions(f: Path, limit: int) -> list[str]:
    """``path:name (n lines)`` of each function or method of ``f`` over ``limit`` lines (decorators not counted)."""
    tree = ast.parse(f.read_text(encoding="utf-8"), filename=str(f))
    return [f"{_where(f)}:{node.name} ({node.end_lineno - node.lineno + 1} lines)"
            for node in ast.walk(tree) if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
            and node.end_lineno - node.lineno + 1 > limit
            and f"{_where(f)}:{node.name}" not in SIZE_EXCEPTIONS]


@pytest.mark.parametrize("f", sorted(PKG.rglob("*.py")), ids=lambda f: _where(f))
def test_module_and_function_size(f):
    """Every module reads by job: no module over 500 lines, no function over 80 (issue 24)."""
    too_long = _long_module(f, MAX_LINES)
    assert not too_long, f"{too_long}: split it by job"
    long = _long_functions(f, MAX_FUNCTION_LINES)
    assert not long, f"functions over {MAX_FUNCTION_LINES} lines: {', '.join(long)}"


def test_the_size_exceptions_are_needed():
    """Each listed exception names a module or function that exists and is still over its limit."""
    stale = []
    for key in SIZE_EXCEPTIONS:
        path, _, name = key.partition(":")
        f = PKG / path
        if not f.exists():
            stale.append(f"{key}: no such module")
        elif not name and len(f.read_text(encoding="utf-8").splitlines()) <= MAX_LINES:
            stale.append(f"{key}: not over {MAX_LINES} lines any more")
        elif name:
            tree = ast.parse(f.read_text(encoding="utf-8"), filename=str(f))
            sizes = [n.end_lineno - n.lineno + 1 for n in ast.walk(tree)
                     if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef) and n.name == name]
            if not any(size > MAX_FUNCTION_LINES for size in sizes):
                stale.append(f"{key}: no such function over {MAX_FUNCTION_LINES} lines")
    assert not stale, "stale exceptions: " + "; ".join(stale)


def test_the_size_rules_catch_a_long_function(tmp_path):
    """The size checks are live: an 81-line function is found, an 80-line one is not; a 501-line module is found."""
    f = tmp_path / "probe.py"
    f.write_text("def ok():\n" + "    x = 1\n" * 79 + "\n\ndef too_long():\n" + "    x = 1\n" * 80, encoding="utf-8")
    assert _long_functions(f, 80) == ["probe.py:too_long (81 lines)"]
    assert _long_module(f, 500) is None
    f.write_text("x = 1\n" * 501, encoding="utf-8")
    assert _long_module(f, 500) == "probe.py has 501 lines (> 500)"


def test_the_realtime_facade_exports_the_whole_model():
    """``realtime`` re-exports ``realtime.model``'s public names by a star import; its ``__all__`` (a literal,
    read above) names every one of them and nothing it does not define."""
    import solenoid_fmu.realtime as realtime

    assert set(realtime.model.__all__) <= set(realtime.__all__)
    assert all(hasattr(realtime, name) for name in realtime.__all__)
