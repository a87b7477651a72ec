"""The package's own import graph, read from the code with ast: no circle among the module-level imports, and
no function-local import of a contouring_ros module except the few listed below, each for a stated reason
(an optional or heavy dependency, or a process that must stay light), never to dodge a circle."""
import ast
import graphlib
from pathlib import Path

from conftest import ROOT

PACKAGE = "contouring_ros"

# (importing module, imported module) -> why the import is made inside a function; "*" stands for any module,
# "package.*" for the package and every module in it
LOCAL_IMPORTS_ALLOWED = {
    ("contouring_ros", "contouring_ros.api"):
        "the top level loads the Python API on first attribute use (PEP 562), so a node's process does not",
    ("contouring_ros.cli.*", "*"):
        "the command line loads a subcommand's modules only when it runs: --help, argument errors and run's "
        "launch start without numpy, scipy and the validation",
    ("contouring_ros.studies.executors", "contouring_ros.studies.executors"):
        "runs on a Dask worker: imports the worker's own installed copy to report its source digest",
}


def _modules() -> dict:
    """{dotted module name: path} of every module of the package."""
    modules = {}
    for path in sorted((ROOT / PACKAGE).rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return modules


def _targets(module: str, path: Path, node, modules: dict) -> list:
    """The package modules one import statement names."""
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names if alias.name in modules]
    if node.level:
        package = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
        package = package[:len(package) - node.level + 1]
        base = ".".join(package + ([node.module] if node.module else []))
    else:
        base = node.module or ""
    targets = []
    for alias in node.names:
        name = f"{base}.{alias.name}"
        target = name if name in modules else base
        if target in modules and target not in targets:
            targets.append(target)
    return targets


def _imports() -> tuple:
    """({module: {package modules it imports at module level}}, [(module, imported, line) made in a function])."""
    modules = _modules()
    top, local = {}, []
    for module, path in modules.items():
        top[module] = set()

        def visit(node, in_function):
            for child in ast.iter_child_nodes(node):
                inside = in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
                if isinstance(child, (ast.Import, ast.ImportFrom)):
                    for target in _targets(module, path, child, modules):
                        if in_function:
                            local.append((module, target, child.lineno))
                        else:
                            top[module].add(target)
                visit(child, inside)
        visit(ast.parse(path.read_text(encoding="utf-8"), str(path)), False)
    return top, local


def _names(pattern: str, module: str) -> bool:
    """Whether an entry's ``pattern`` names ``module``: the module itself, "*" any, "package.*" the package and
    every module in it."""
    return pattern in ("*", module) or (pattern.endswith(".*") and f"{module}.".startswith(pattern[:-1]))


def _allowed(module: str, target: str) -> bool:
    return any(_names(importer, module) and _names(imported, target) for importer, imported in LOCAL_IMPORTS_ALLOWED)


def test_the_graph_is_read_from_the_package():
    top, _ = _imports()
    assert {"contouring_ros.config", "contouring_ros.experiment.registry", "contouring_ros.core.simulation",
            "contouring_ros.experiment.catalogue.curves"} <= set(top)
    assert "contouring_ros.experiment.registry" in top["contouring_ros.experiment.catalogue.curves"]
    assert "contouring_ros.experiment.validate" in top["contouring_ros.config"]


def test_module_level_imports_have_no_circle():
    top, _ = _imports()
    try:
        graphlib.TopologicalSorter(top).prepare()
    except graphlib.CycleError as error:
        raise AssertionError(f"import circle: {' -> '.join(error.args[1])}") from None


def test_function_local_imports_of_the_package_have_a_stated_reason():
    _, local = _imports()
    unlisted = [f"{module}:{line} imports {target}" for module, target, line in local if not _allowed(module, target)]
    assert not unlisted, "function-local imports without a reason in LOCAL_IMPORTS_ALLOWED:\n" + "\n".join(unlisted)


def test_every_allowed_entry_is_used_and_has_a_reason():
    _, local = _imports()
    for (importer, imported), reason in LOCAL_IMPORTS_ALLOWED.items():
        assert reason.strip(), (importer, imported)
        assert any(_names(importer, module) and _names(imported, target)
                   for module, target, _ in local), f"unused entry {importer} -> {imported}"


# The package's roles from the bottom up (docs/ARCHITECTURE.md): a module may import its own role and those
# below it, never one above. The top level (api, cli, config) stands over all; errors, notices and _version
# are the ground every role may use.
ROLES = ["core", "wire", "experiment", "records", "nodes", "run", "studies"]
GROUND = {"contouring_ros._version", "contouring_ros._moved", "contouring_ros.errors", "contouring_ros.notices"}


def _role(module: str):
    """A module's rank among ROLES; the top level's len(ROLES); the ground's -1."""
    if module in GROUND:
        return -1
    parts = module.split(".")
    return ROLES.index(parts[1]) if len(parts) > 1 and parts[1] in ROLES else len(ROLES)


def test_every_arrow_points_down_the_roles():
    top, local = _imports()
    arrows = [(module, target) for module, targets in top.items() for target in targets]
    arrows += [(module, target) for module, target, _ in local]
    upward = sorted({f"{module} -> {target}" for module, target in arrows
                     if module != "contouring_ros" and _role(target) > _role(module)})
    assert not upward, "imports that run back up the roles " + str(ROLES) + ":\n" + "\n".join(upward)


def test_the_top_level_holds_no_role():
    """Every module outside the role folders is the package's face, the command line or the ground."""
    flat = {path.stem for path in (ROOT / PACKAGE).glob("*.py")}
    flat |= {path.parent.name for path in (ROOT / PACKAGE).glob("*/__init__.py") if path.parent.name not in ROLES}
    assert flat == {"__init__", "_version", "_moved", "api", "cli", "config", "errors", "notices"}, flat


def test_old_import_paths_give_the_moved_modules():
    import importlib
    import sys
    import warnings

    from contouring_ros._moved import MOVED
    for old, new in MOVED.items():
        sys.modules.pop(f"{PACKAGE}.{old}", None)          # a test before may have imported the old name
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            module = importlib.import_module(f"{PACKAGE}.{old}")
        assert module is importlib.import_module(f"{PACKAGE}.{new}"), old
        assert [str(w.message) for w in caught] == [f"{PACKAGE}.{old} has moved to {PACKAGE}.{new}"], old
    from contouring_ros.registry import Entry             # the plugin documentation's own path
    assert Entry.__module__ == "contouring_ros.experiment.registry"
    assert not (ROOT / PACKAGE / "bag.py").exists()


def test_old_import_paths_of_split_modules_give_their_parts_names():
    import importlib
    import sys
    import warnings

    from contouring_ros._moved import SPLIT
    for old, parts in SPLIT.items():
        sys.modules.pop(f"{PACKAGE}.{old}", None)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            module = importlib.import_module(f"{PACKAGE}.{old}")
        new = ", ".join(f"{PACKAGE}.{part}" for part in parts)
        assert [str(w.message) for w in caught] == [f"{PACKAGE}.{old} has been split into {new}"], old
        for part in parts:
            moved = importlib.import_module(f"{PACKAGE}.{part}")
            assert all(getattr(module, name) is getattr(moved, name) for name in moved.__all__), (old, part)
    from contouring_ros.analysis import compare_table, figures, html_report, replay_estimators, run_names
    assert (compare_table.__module__, run_names.__module__, replay_estimators.__module__, figures.__module__,
            html_report.__module__) == tuple(f"{PACKAGE}.records.{name}" for name in (
                "comparison", "comparison", "replay", "figures", "html_report"))


def test_every_module_attribute_used_exists():
    """``module.name`` where ``module`` is a package module bound by an import names something that module
    has: a name moved to another module when a module was split fails here, not in a node at run time."""
    import importlib
    import warnings
    modules = _modules()
    wrong = []
    for module, path in modules.items():
        tree = ast.parse(path.read_text())
        bound = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                for alias in node.names:                       # `from package import module`
                    single = ast.ImportFrom(module=node.module, names=[alias], level=node.level)
                    bound.update({alias.asname or alias.name: target for target in _targets(module, path, single, modules)
                                  if target.endswith(f".{alias.name}")})
            elif isinstance(node, ast.Import):
                bound.update({alias.asname: alias.name for alias in node.names
                              if alias.asname and alias.name in modules})
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in bound:
                target = bound[node.value.id]
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    found = hasattr(importlib.import_module(target), node.attr) or f"{target}.{node.attr}" in modules
                if not found:
                    wrong.append(f"{path.relative_to(ROOT)}:{node.lineno}: {target} has no {node.attr}")
    assert not wrong, wrong
