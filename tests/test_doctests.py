"""The Examples of every public name run, and every public name has them.

The public names are those of ``wavemeter.__all__`` and of the public subpackages' ``__all__``
that the API reference lists (``docs/_api_pages.py``); the docs build warns of a public
name without Examples too (numpydoc's EX01). Each class or function among them is
one test: its docstring's examples run as doctests (``doctest.DocTestFinder`` on the object,
not its members) and any failure fails the test. Constants (a version string, a tuple of
FSRs, a table of formats) are not objects with a docstring of their own: their ``#:``
comments document them where they are defined, and they are left out here.

Module docstrings say what a module owns; the theory is on the docs' theory pages, so no
module docstring in ``src/wavemeter`` may be longer than ``MAX_MODULE_DOCSTRING_LINES``.
"""

from __future__ import annotations

import ast
import doctest
import importlib
import inspect
import re
from pathlib import Path

import pytest

#: the packages whose ``__all__`` the API reference documents and whose names need Examples
PACKAGES = (
    "wavemeter",
    "wavemeter.calibration",
    "wavemeter.simulation",
    "wavemeter.model",
    "wavemeter.io",
    "wavemeter.analysis",
    "wavemeter.jobs",
    "wavemeter.fleet",
)

#: a module docstring longer than this is an essay: the theory belongs in docs/theory
MAX_MODULE_DOCSTRING_LINES = 40

SOURCE = Path(__file__).resolve().parents[1] / "src" / "wavemeter"


def _public_objects() -> dict[str, object]:
    """Every public class and function, once, under the first name it is exported as."""
    objects: dict[str, object] = {}
    seen: set[int] = set()
    for package_name in PACKAGES:
        package = importlib.import_module(package_name)
        for name in package.__all__:
            value = getattr(package, name)
            if not (inspect.isclass(value) or inspect.isroutine(value)) or id(value) in seen:
                continue
            seen.add(id(value))
            objects[f"{package_name}.{name}"] = value
    return objects


PUBLIC = _public_objects()


def _examples_section(obj) -> str | None:
    """The text of the numpydoc Examples section of ``obj``'s own docstring, or None."""
    doc = inspect.cleandoc(obj.__doc__ or "")
    found = re.search(r"^Examples\n-{8}\n(.*)", doc, flags=re.MULTILINE | re.DOTALL)
    return found.group(1) if found else None


def test_every_public_package_is_covered():
    """The API reference's public subpackages (but the report, whose one name
    ``write_report`` is ``wavemeter``'s) are the ones checked here."""
    import sys

    sys.path.insert(0, str(SOURCE.parents[1] / "docs"))
    try:
        from _api_pages import SUBPACKAGES
    finally:
        sys.path.pop(0)
    assert set(SUBPACKAGES) - set(PACKAGES) == {"wavemeter.report"}
    assert len(PUBLIC) > 100  # sanity: the packages were read


@pytest.mark.parametrize("name", sorted(PUBLIC))
def test_public_name_has_examples(name):
    section = _examples_section(PUBLIC[name])
    assert section is not None, f"{name} has no Examples section"
    assert re.search(r"^>>> ", section, flags=re.MULTILINE), f"{name}'s Examples has no >>>"


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(PUBLIC))
def test_examples_run(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # an example that writes a file writes it here
    obj = PUBLIC[name]
    finder = doctest.DocTestFinder(recurse=False, exclude_empty=True)
    tests = finder.find(obj, name, module=False, globs={})
    assert tests and tests[0].examples, f"{name}: no doctest found"
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    output: list[str] = []
    for test in tests:
        runner.run(test, out=output.append)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, "".join(output)


def _module_docstring_lines(path: Path) -> int:
    """Lines from the opening to the closing quotes of a module's docstring (0: none)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    first = tree.body[0] if tree.body else None
    if not (
        isinstance(first, ast.Expr)
        and isinstance(first.value, ast.Constant)
        and isinstance(first.value.value, str)
    ):
        return 0
    return first.end_lineno - first.lineno + 1


def test_module_docstrings_are_short():
    modules = sorted(SOURCE.rglob("*.py"))
    assert len(modules) > 100
    long = {
        str(path.relative_to(SOURCE)): lines
        for path in modules
        if (lines := _module_docstring_lines(path)) > MAX_MODULE_DOCSTRING_LINES
    }
    assert not long, f"module docstrings over {MAX_MODULE_DOCSTRING_LINES} lines: {long}"


def test_module_docstring_count_sees_the_quotes(tmp_path):
    """The line count includes the quote lines, so a 40-line text with its closing quotes on
    a line of their own counts 41."""
    path = tmp_path / "essay.py"
    path.write_text('"""' + "\n".join(["line"] * 40) + '\n"""\n', encoding="utf-8")
    assert _module_docstring_lines(path) == 41
    path.write_text("x = 1\n", encoding="utf-8")
    assert _module_docstring_lines(path) == 0
