"""The dashboard's code keeps the shape its design asks for: checked from the source itself.

* the modules of ``app`` import one another without a circle, and ``rattle_core`` never
  imports ``app``;
* ``app`` is laid out by job: ``views/`` holds the ``pn.viewable.Viewer`` views, ``work/`` the
  background work and the server's threads, ``ui/`` the pieces views are built from;
* ``app`` takes anything beyond ``rattle_core``'s top-level names through ``app.core`` only;
* no module of ``app`` outgrows about 400 lines.
"""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
APP = ROOT / "app"


def app_modules() -> dict[str, Path]:
    """``app.views.diagram`` → its file, for every module of ``app`` but the package files."""
    return {"app." + ".".join(p.relative_to(APP).with_suffix("").parts): p
            for p in APP.rglob("*.py") if p.stem != "__init__"}


def package_of(module: str) -> str:
    return module.rsplit(".", 1)[0]


def imports(path: Path, package: str) -> set[str]:
    """Modules a file imports (relative imports resolved within ``package``)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package if node.level == 1 else package.rsplit(".", node.level - 1)[0]
                mod = f"{base}.{node.module}" if node.module else base
                out.add(mod)
                if node.module is None:
                    out.update(f"{base}.{a.name}" for a in node.names)
            elif node.module:
                out.add(node.module)
                out.update(f"{node.module}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
    return out


def test_app_modules_import_one_another_without_a_circle():
    """A depth-first walk of app's own imports finds no cycle."""
    mods = app_modules()
    graph = {m: sorted(i for i in imports(p, package_of(m)) if i in mods and i != m)
             for m, p in mods.items()}
    state: dict[str, int] = {}

    def visit(m: str, path: list[str]) -> None:
        state[m] = 1
        for n in graph[m]:
            assert state.get(n) != 1, "import circle: " + " → ".join([*path, m, n])
            if n not in state:
                visit(n, [*path, m])
        state[m] = 2
    for m in graph:
        if m not in state:
            visit(m, [])
    assert set(graph["app.state"]) <= {"app.core", "app.ui.labels"} and graph["app.core"] == []


def test_the_core_never_imports_the_app():
    for p in (ROOT / "rattle_core").rglob("*.py"):
        assert not any(i == "app" or i.startswith("app.") for i in imports(p, "rattle_core")), p


def test_each_folder_of_the_app_holds_one_kind_of_module():
    """Every module of app/views defines a Viewer; work/ imports no view and nothing of ui/, ui/
    no view: the folders name what their modules are."""
    mods = app_modules()
    for m, p in mods.items():
        found = imports(p, package_of(m))
        if m.startswith("app.views."):
            bases = {ast.unparse(b) for node in ast.walk(ast.parse(p.read_text()))
                     if isinstance(node, ast.ClassDef) for b in node.bases}
            assert "pn.viewable.Viewer" in bases, f"{m} defines no pn.viewable.Viewer"
        if m.startswith("app.work."):
            assert not any(i.startswith(("app.views", "app.ui")) for i in found), m
        if m.startswith("app.ui."):
            assert not any(i.startswith("app.views") for i in found), m
    assert {package_of(m) for m in mods} == {"app", "app.views", "app.work", "app.ui"}


def test_the_app_reaches_into_the_core_only_through_app_core():
    for m, p in app_modules().items():
        deep = {i for i in imports(p, package_of(m)) if i.startswith("rattle_core.")}
        top = {i for i in deep if i.count(".") == 1 and i.split(".")[1][0].isupper() or
               i in ("rattle_core.simulate", "rattle_core.classify", "rattle_core.sweep",
                     "rattle_core.units")}
        assert p.stem == "core" or deep <= top, (p.name, sorted(deep - top))


def test_no_app_module_outgrows_400_lines():
    sizes = {m: len(p.read_text().splitlines()) for m, p in app_modules().items()}
    assert max(sizes.values()) <= 410, sizes
