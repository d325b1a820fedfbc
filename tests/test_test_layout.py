"""How the tests are laid out: no test file imports another (or ``conftest.py``); what they
share lives in ``tests/helpers.py`` (fixtures in ``conftest.py``); and a test uses the
public names of ``wavemeter``, or the private ones of the module it is named after.

A private name is a dotted part that starts with ``_`` (not a dunder): a private module
(``wavemeter.cli._readings``), function, class, attribute or constant. A reference to one
is allowed in ``tests/test_<stem>.py`` when ``<stem>`` names the module that holds it or a
package above that module: its dotted parts, leading underscores dropped, joined by ``_``
(``cascade_search`` or ``model_cascade_search`` for ``wavemeter.model.cascade_search``,
``cli_readings`` for ``wavemeter.cli._readings``, ``io`` or ``io_text`` for
``wavemeter.io.text``). References are found by an AST scan of every file in ``tests/``:
imports (``from wavemeter.x import _y``, ``import wavemeter.x._y``), attribute chains on
names bound to ``wavemeter`` (``module._y``, ``Class._y``), ``setattr``/``getattr`` with a
private name, and dotted paths given to ``monkeypatch.setattr("wavemeter.x._y", ...)``,
``import_module`` or ``mock.patch``. Private
attributes of objects made at run time (``calibrator._x``) are beyond it.
"""

from __future__ import annotations

import ast
import functools
import importlib.util
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent
PACKAGE = "wavemeter"


def _private(part: str) -> bool:
    return part.startswith("_") and not (part.startswith("__") and part.endswith("__"))


def _is_module(dotted: str) -> bool:
    try:
        return importlib.util.find_spec(dotted) is not None
    except (ImportError, ValueError):
        return False


@functools.cache
def _module_of(dotted: str) -> tuple[str, ...]:
    """The parts below ``wavemeter`` of the deepest module in ``dotted`` (the module that
    holds the name, or the private module itself)."""
    parts = dotted.split(".")
    for end in range(len(parts), 1, -1):
        if _is_module(".".join(parts[:end])):
            return tuple(parts[1:end])
    return ()


def allowed_stems(dotted: str) -> set[str]:
    """The test file stems that may use the private name ``dotted`` (``wavemeter.a.b._c``):
    each run of parts of its module's path, leading underscores dropped, joined by ``_``."""
    parts = [part.lstrip("_") for part in _module_of(dotted)]
    return {"_".join(parts[i : j + 1]) for i in range(len(parts)) for j in range(i, len(parts))}


def _bindings(nodes: list[ast.AST]) -> dict[str, str]:
    """Local names bound by imports to ``wavemeter`` objects: name -> dotted path."""
    bound = {}
    for node in nodes:
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == PACKAGE:
                    if alias.asname:
                        bound[alias.asname] = alias.name
                    else:
                        bound[PACKAGE] = PACKAGE
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            if node.module.split(".")[0] == PACKAGE:
                for alias in node.names:
                    bound[alias.asname or alias.name] = f"{node.module}.{alias.name}"
    return bound


def _dotted(node: ast.AST, bound: dict[str, str]) -> str | None:
    """``a.b.c`` with ``a`` bound to a ``wavemeter`` path, as that path; else None."""
    attributes = []
    while isinstance(node, ast.Attribute):
        attributes.append(node.attr)
        node = node.value
    if isinstance(node, ast.Name) and node.id in bound:
        return ".".join([bound[node.id], *reversed(attributes)])
    return None


#: calls whose first argument may be a dotted path (``monkeypatch.setattr("wavemeter.x._y",
#: ...)``, ``importlib.import_module``, ``unittest.mock.patch``)
PATH_CALLS = ("setattr", "delattr", "import_module", "patch", "__import__")
#: calls whose second argument names an attribute of the first (``setattr(module, "_y")``)
ATTRIBUTE_CALLS = ("setattr", "getattr", "delattr", "hasattr")


def _named_by_call(node: ast.Call, bound: dict[str, str]) -> list[str]:
    """The ``wavemeter`` paths a call names by string: a dotted path as its first argument,
    or an attribute name as its second."""
    function = node.func
    called = function.attr if isinstance(function, ast.Attribute) else None
    called = function.id if isinstance(function, ast.Name) else called
    first = node.args[0]
    if called in PATH_CALLS and isinstance(first, ast.Constant) and isinstance(first.value, str):
        return [first.value]
    if called in ATTRIBUTE_CALLS and len(node.args) >= 2:
        name = node.args[1]
        owner = _dotted(first, bound)
        if owner is not None and isinstance(name, ast.Constant) and isinstance(name.value, str):
            return [f"{owner}.{name.value}"]
    return []


def private_references(nodes: list[ast.AST]) -> list[tuple[int, str]]:
    """(line, dotted path) of every reference to a private ``wavemeter`` name among the
    nodes of a module (``ast.walk``)."""
    bound = _bindings(nodes)
    found = []
    for node in nodes:
        paths = []
        if isinstance(node, ast.Import):
            paths = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            paths = [f"{node.module}.{alias.name}" for alias in node.names]
        elif isinstance(node, ast.Attribute) and _private(node.attr):
            paths = [_dotted(node, bound)]
        elif isinstance(node, ast.Call) and node.args:
            paths = _named_by_call(node, bound)
        for path in paths:
            if path and path.split(".")[0] == PACKAGE and any(map(_private, path.split("."))):
                found.append((node.lineno, path))
    return sorted(set(found))


def cross_imports(nodes: list[ast.AST]) -> list[tuple[int, str]]:
    """(line, module) of every import of a test file or of ``conftest`` among the nodes of a
    module (``ast.walk``)."""

    def is_test(module: str) -> bool:
        name = module.split(".")[-1]
        return name.startswith("test_") or name == "conftest"

    found = []
    for node in nodes:
        if isinstance(node, ast.ImportFrom):
            module = node.module or ""
            if is_test(module):
                found.append((node.lineno, module))
            elif node.level or module.split(".")[0] == "tests":
                found += [(node.lineno, alias.name) for alias in node.names if is_test(alias.name)]
        elif isinstance(node, ast.Import):
            found += [
                (node.lineno, alias.name)
                for alias in node.names
                if alias.name.split(".")[0] == "tests" and is_test(alias.name)
            ]
    return found


def layout_problems(folder: Path) -> list[str]:
    """Every import of a test file or conftest, and every private name used outside the
    test file named after its module, in the Python files of ``folder`` (recursively)."""
    problems = []
    for path in sorted(folder.rglob("*.py")):
        nodes = list(ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))))
        where = path.relative_to(folder)
        for line, module in cross_imports(nodes):
            problems.append(
                f"{where}:{line}: imports {module}: move what is shared to tests/helpers.py"
            )
        stem = path.stem.removeprefix("test_") if path.stem.startswith("test_") else None
        for line, name in private_references(nodes):
            if stem not in allowed_stems(name):
                problems.append(
                    f"{where}:{line}: uses the private {name}: use the public API, or test it in "
                    f"a file named after its module ({_suggestion(name)})"
                )
    return problems


def _suggestion(name: str) -> str:
    parts = [part.lstrip("_") for part in _module_of(name)]
    return f"tests/test_{'_'.join(parts)}.py" if parts else "no module of wavemeter holds it"


# ---------------------------------------------------------------------------- the suite
def test_the_suite_has_no_cross_imports_and_no_private_names_of_other_modules():
    problems = layout_problems(TESTS)
    assert not problems, "\n".join(problems)


def test_the_default_run_is_in_file_order_with_registered_marks_only(pytestconfig):
    """No plug-in reorders or reseeds the default run, and a mistyped mark (``slwo``) fails
    collection instead of putting a slow test in the fast tier."""
    plugins = pytestconfig.pluginmanager
    assert not plugins.has_plugin("randomly") and not plugins.has_plugin("random_order")
    assert pytestconfig.getoption("strict_markers")


# ---------------------------------------------------------------------------- the scan
SCANNED = {
    "test_cli_trust.py": """
import wavemeter as wm
import wavemeter.cli._common
from wavemeter.cli import _readings as readings, main
from wavemeter.model.cascade_search import _log_edge_rate, DesignSetting
from wavemeter.calibration.methods.learned import Calibrator
from .conftest import NOISE_W
from .test_dead_ports import darken
from . import test_cli
from .helpers import POWER_W
from ._service import serving

def test_x(monkeypatch):
    monkeypatch.setattr(Calibrator, "_fit_sweep", None)
    monkeypatch.setattr(readings, "CHUNK_ROWS", 7)
    monkeypatch.setattr("wavemeter.io.text._BLOCK_BYTES", 1)
    wm.model.kernels._workers()
    Calibrator.fit, wm.Calibrator.fit, main, DesignSetting, wm.__version__
    "wavemeter._version is not a path: it has spaces"
""",
    "test_io_text.py": """
def test_x(monkeypatch):
    monkeypatch.setattr("wavemeter.io.text._BLOCK_BYTES", 1)
    monkeypatch.setattr("wavemeter.io.text._pyarrow", None)
""",
    "test_cli.py": """
from wavemeter.cli import _readings
from wavemeter.cli._common import printable
""",
}


@pytest.fixture
def scanned(tmp_path) -> list[str]:
    for name, text in SCANNED.items():
        (tmp_path / name).write_text(text)
    return layout_problems(tmp_path)


def test_the_scan_finds_cross_imports(scanned):
    imports = [problem for problem in scanned if " imports " in problem]
    assert [problem.split(": ")[1] for problem in imports] == [
        "imports conftest",
        "imports test_dead_ports",
        "imports test_cli",
    ]


def test_the_scan_finds_private_names_of_other_modules(scanned):
    private = {
        problem.split(" the private ")[1].split(":")[0]
        for problem in scanned
        if " the private " in problem
    }
    assert private == {
        "wavemeter.cli._common",
        "wavemeter.cli._readings",
        "wavemeter.cli._readings.CHUNK_ROWS",
        "wavemeter.model.cascade_search._log_edge_rate",
        "wavemeter.calibration.methods.learned.Calibrator._fit_sweep",
        "wavemeter.io.text._BLOCK_BYTES",
        "wavemeter.model.kernels._workers",
    }
    assert all(problem.startswith("test_cli_trust.py:") for problem in scanned)
    assert "(tests/test_model_cascade_search.py)" in "\n".join(scanned)


def test_a_file_named_after_the_module_or_its_package_may_use_its_private_names():
    assert {"io", "text", "io_text"} == allowed_stems("wavemeter.io.text._pyarrow")
    assert "cli_readings" in allowed_stems("wavemeter.cli._readings.CHUNK_ROWS")
    assert "cli_trust" not in allowed_stems("wavemeter.cli._readings.CHUNK_ROWS")
    assert "cascade_search" in allowed_stems("wavemeter.model.cascade_search._log_edge_rate")
    assert "cascade_design" not in allowed_stems("wavemeter.model.cascade_search._SERIES_MARGIN")
