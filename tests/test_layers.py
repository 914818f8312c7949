"""Data flows one way: every import, static or dynamic, points to the same layer or a lower one.

Layers, lowest first: ``rattle_core.measure`` (measured signals) → ``model`` → ``solver`` →
``analysis`` → ``batch`` → ``store`` → ``paper`` → the ``rattle_core`` package itself (the facade that re-exports the
public names) → the top: the CLI (``rattle_cli``) and the dashboard (``app``, installed as
``rattle_app``).  ``rattle_core.jitcache`` and ``rattle_core.checks`` sit below them all.  The test reads the source with
:mod:`ast`, so an import inside a function, under ``TYPE_CHECKING`` or spelled
``importlib.import_module("...")`` / ``__import__("...")`` counts like any other.  No two
modules import each other, by any of these imports: a circle hidden in a function still ties
them into one.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
CORE_LAYERS = ("measure", "model", "solver", "analysis", "batch", "store", "paper")
BASE = -1
FACADE = len(CORE_LAYERS)
TOP = FACADE + 1
TOP_PACKAGES = ("rattle_cli", "app", "rattle_app")
#: Third-party packages that only the top layer may use (the core draws no widgets).
UI_PACKAGES = ("panel", "bokeh", "holoviews", "datashader", "param", "tqdm")


def layer_of(module: str) -> int | None:
    """The layer of a module name, or None for the standard library and third parties."""
    parts = module.split(".")
    if parts[0] in TOP_PACKAGES:
        return TOP
    if parts[0] != "rattle_core":
        return None
    if len(parts) == 1:
        return FACADE
    if parts[1] in CORE_LAYERS:
        return CORE_LAYERS.index(parts[1])
    if parts[1] in ("jitcache", "checks"):
        return BASE
    raise AssertionError(f"{module}: every module of rattle_core belongs to a layer")


def module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _resolve(module: str, is_package: bool, level: int, name: str | None) -> str:
    """The absolute module named by a (possibly relative) import inside ``module``."""
    if level == 0:
        return name or ""
    base = module.split(".")
    if not is_package:
        base = base[:-1]
    base = base[:len(base) - (level - 1)]
    return ".".join(base + ([name] if name else []))


def imports_of(module: str, source: str, is_package: bool = False,
               names: bool = False) -> list[tuple[int, str]]:
    """``(line, absolute module)`` of every import in ``source``; a dynamic import whose target
    is not a string literal is returned as ``"<dynamic>"``, since it cannot be checked.
    With ``names``, ``from pkg import name`` also gives ``pkg.name`` (a module, if it is one)."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            target = _resolve(module, is_package, node.level, node.module)
            # ``from pkg import name`` is checked at pkg: a layer's sub-packages share its layer
            found.append((node.lineno, target))
            if names:
                found += [(node.lineno, f"{target}.{a.name}") for a in node.names]
        elif isinstance(node, ast.Call):
            f = node.func
            name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")
            if name in ("import_module", "__import__"):
                arg = node.args[0] if node.args else None
                if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
                    level = len(arg.value) - len(arg.value.lstrip("."))
                    found.append((node.lineno, _resolve(module, is_package, level,
                                                        arg.value.lstrip(".") or None)))
                else:
                    found.append((node.lineno, "<dynamic>"))
    return found


def violations(module: str, source: str, is_package: bool = False) -> list[str]:
    """Imports of ``module`` that point to a higher layer, or that cannot be checked."""
    own = layer_of(module)
    out = []
    for line, target in imports_of(module, source, is_package):
        if target == "<dynamic>":
            out.append(f"{module}:{line}: a dynamic import whose target is not a literal")
            continue
        target_layer = layer_of(target)
        if target_layer is not None and own is not None and target_layer > own:
            out.append(f"{module}:{line}: imports {target} (a higher layer)")
        top = target.split(".")[0]
        if own is not None and own < TOP and top in UI_PACKAGES:
            out.append(f"{module}:{line}: imports {top}, which only the top layer may use")
        if own is not None and own < CORE_LAYERS.index("paper") and top == "matplotlib":
            out.append(f"{module}:{line}: draws with matplotlib below the paper layer")
    return out


def project_modules() -> list[tuple[str, Path]]:
    files = [p for d in ("rattle_core", "rattle_cli", "app") for p in (ROOT / d).rglob("*.py")]
    return [(module_name(p), p) for p in sorted(files)]


def test_every_import_points_down():
    """No module imports a higher layer, and the core never imports the CLI or the dashboard."""
    found = []
    for module, path in project_modules():
        found += violations(module, path.read_text(encoding="utf-8"), path.name == "__init__.py")
    assert found == []


def test_every_core_module_has_a_layer():
    """Each module of rattle_core lives in one of the layer packages (or is the facade)."""
    for module, _ in project_modules():
        if module.startswith("rattle_core"):
            assert layer_of(module) is not None, module


@pytest.mark.parametrize("module, source, expected", [
    ("rattle_core.model.params", "from ..solver.trajectory import simulate", "rattle_core.solver"),
    ("rattle_core.solver.kernel", "def f():\n    from rattle_core.batch import sweep",
     "rattle_core.batch"),
    ("rattle_core.store.cache", "import importlib\nimportlib.import_module('app.main')", "app.main"),
    ("rattle_core.batch.maps", "m = __import__('rattle_core.paper.cases')", "rattle_core.paper"),
    ("rattle_core.analysis.classify", "from rattle_core import simulate", "rattle_core"),
    ("rattle_core.analysis.classify", "import panel as pn", "panel"),
    ("rattle_core.batch.sweep", "import matplotlib.pyplot", "matplotlib"),
    ("rattle_core.paper.cases", "import importlib\nimportlib.import_module(name)", "dynamic"),
])
def test_the_checker_sees_upward_imports(module, source, expected):
    """The checker flags each kind of upward import it is meant to catch."""
    found = violations(module, source)
    assert len(found) == 1 and expected in found[0], found


@pytest.mark.parametrize("module, source", [
    ("rattle_core.batch.sweep", "from ..solver import kernel as solver"),
    ("rattle_core.paper.cases", "from ..store.cache import cached_sweep\nimport matplotlib"),
    ("rattle_cli.main", "import importlib\nimportlib.import_module('rattle_app.main')"),
    ("rattle_core.solver.trajectory", "from . import kernel"),
])
def test_the_checker_accepts_downward_imports(module, source):
    """Imports of the same or a lower layer pass."""
    assert violations(module, source) == []


def _module_level_imports(module: str, tree: ast.Module) -> set[str]:
    """Modules imported by the statements that run when ``module`` is imported (``if`` blocks,
    ``TYPE_CHECKING`` included; imports inside functions run later and are left out)."""
    found: set[str] = set()
    body = list(tree.body)
    while body:
        node = body.pop()
        if isinstance(node, (ast.If, ast.Try)):
            body += node.body + node.orelse + getattr(node, "handlers", []) + getattr(node, "finalbody", [])
        elif isinstance(node, ast.ExceptHandler):
            body += node.body
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = _resolve(module, False, node.level, node.module)
            found.add(base)
            # ``from . import kernel`` names the package; the module it names is an edge too
            found.update(f"{base}.{a.name}" for a in node.names)
    return found


def module_graph() -> dict[str, set[str]]:
    """Each module of rattle_core → the modules of rattle_core it imports at import time
    (packages left out: a package's own imports are its facade)."""
    mods = {m: p for m, p in project_modules() if m.startswith("rattle_core") and p.name != "__init__.py"}
    return {m: {t for t in _module_level_imports(m, ast.parse(p.read_text(encoding="utf-8")))
                if t in mods and t != m} for m, p in mods.items()}


def find_cycle(graph: dict[str, set[str]]) -> list[str]:
    """One import circle of ``graph`` (its modules, first repeated at the end), or []."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(m: str) -> list[str]:
        state[m] = 1
        stack.append(m)
        for n in sorted(graph[m]):
            if state.get(n) == 1:
                return stack[stack.index(n):] + [n]
            if n not in state:
                found = visit(n)
                if found:
                    return found
        stack.pop()
        state[m] = 2
        return []
    for m in sorted(graph):
        if m not in state:
            found = visit(m)
            if found:
                return found
    return []


def _project_name(module: str) -> str:
    """``rattle_app`` is how the dashboard is installed; its modules are ``app``'s."""
    head, _, rest = module.partition(".")
    return "app" + ("." + rest if rest else "") if head == "rattle_app" else module


def import_graph(sources: dict[str, str]) -> dict[str, set[str]]:
    """Each module of ``sources`` (name → source) → the modules of ``sources`` it imports
    anywhere: at import time, inside a function, or by a literal ``import_module`` /
    ``__import__``.  An import inside a function runs later, but the two modules still need
    each other: a circle through it is a circle all the same."""
    return {m: {t for t in (_project_name(t) for _, t in imports_of(m, src, names=True))
                if t in sources and t != m}
            for m, src in sources.items()}


def project_sources() -> dict[str, str]:
    """Every module of the project (packages left out: a package's own imports are its
    facade), name → source."""
    return {m: p.read_text(encoding="utf-8") for m, p in project_modules()
            if p.name != "__init__.py"}


def test_no_core_module_imports_itself_through_another():
    """No import circle between the core's modules at import time, imports under
    TYPE_CHECKING included."""
    assert find_cycle(module_graph()) == []


def test_the_cycle_finder_sees_a_circle():
    """The circle finder reports a two-module circle and passes a chain."""
    assert find_cycle({"a": {"b"}, "b": {"a"}}) == ["a", "b", "a"]
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": set()}) == []


def test_no_module_imports_itself_through_another_even_from_a_function():
    """No import circle between the project's modules through any import: those inside
    functions and the literal dynamic ones count like the ones at the top."""
    assert find_cycle(import_graph(project_sources())) == []


CODIM2, TWOPARAM = ("rattle_core.analysis.continuation.codim2",
                    "rattle_core.analysis.continuation.twoparam")


@pytest.mark.parametrize("a, a_src, b, b_src", [
    (CODIM2, "def f():\n    from .twoparam import _orbit\n    return _orbit",
     TWOPARAM, "from .codim2 import _record"),
    (CODIM2, "def f():\n    from . import twoparam", TWOPARAM, "from .codim2 import _record"),
    (CODIM2, "import importlib\ndef f():\n    return importlib.import_module("
     "'rattle_core.analysis.continuation.twoparam')", TWOPARAM, "from .codim2 import _record"),
    ("app.state", "def f():\n    from rattle_app.views.page import build",
     "app.views.page", "from ..state import State"),
])
def test_a_circle_through_a_function_level_import_is_seen(a, a_src, b, b_src):
    """Two modules that import each other, one of them only inside a function (or by a
    literal dynamic import), form a circle; the import-time graph alone does not see it."""
    sources = {a: a_src, b: b_src}
    cycle = find_cycle(import_graph(sources))
    assert len(cycle) == 3 and cycle[0] == cycle[-1] and set(cycle) == {a, b}
    at_import = {m: {t for t in _module_level_imports(m, ast.parse(src)) if t in sources and t != m}
                 for m, src in sources.items()}
    assert find_cycle(at_import) == []
