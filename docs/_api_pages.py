"""Write the API reference pages from ``__all__``: every public name gets an entry.

One page for ``wavemeter`` and one per public subpackage. A subpackage name that is the same
object as one already documented (``wavemeter.calibration.Calibrator`` is
``wavemeter.Calibrator``) links to that entry instead of documenting it twice. Called by
``conf.py`` at the start of every build, so a name added to an ``__all__`` appears without
editing the docs; the pages are generated files (``docs/reference/_api/``, not in git).
"""

from __future__ import annotations

import importlib
import inspect
from pathlib import Path

#: the public subpackages, in reading order, with what each holds
SUBPACKAGES = {
    "wavemeter.calibration": "Calibrators, reading flags, calibration files.",
    "wavemeter.simulation": "Simulated interferometers, cascades, faults and lasers.",
    "wavemeter.io": "Reading and writing tables of readings: formats, columns, units.",
    "wavemeter.jobs": "File-level jobs: measure, stream, calibrate a file, a noise series.",
    "wavemeter.model": "The physics: cone, couplers, retrieval, bounds, orders, cascade design.",
    "wavemeter.analysis": "Evaluation against the truth, error metrics, frequency noise.",
    "wavemeter.fleet": "Many devices in parallel on dask.distributed.",
    "wavemeter.report": "The HTML report of a calibration.",
}


def _public_names(module) -> list[str]:
    return [name for name in module.__all__ if not name.startswith("_")]


def _role(obj) -> str:
    if inspect.isclass(obj):
        return "exc" if issubclass(obj, BaseException) else "class"
    if callable(obj):
        return "func"
    return "data"


def _is_documentable_twice(obj) -> bool:
    """Constants (numbers, tuples, dicts) are documented where they are exported."""
    return inspect.isclass(obj) or inspect.isroutine(obj)


def _page(module_name: str, summary: str, seen: dict[int, str]) -> str:
    module = importlib.import_module(module_name)
    own, elsewhere = [], []
    for name in _public_names(module):
        obj = getattr(module, name)
        if _is_documentable_twice(obj) and id(obj) in seen:
            elsewhere.append((name, obj, seen[id(obj)]))
            continue
        own.append(name)
        if _is_documentable_twice(obj):
            seen[id(obj)] = f"{module_name}.{name}"
    title = f"``{module_name}``"
    lines = [
        f".. _api-{module_name.replace('.', '-')}:",
        "",
        title,
        "=" * len(title),
        "",
        summary,
        "",
        f".. currentmodule:: {module_name}",
        "",
    ]
    if own:
        lines += [
            ".. autosummary::",
            "   :toctree: ../generated/",
            "   :nosignatures:",
            "",
            *[f"   {name}" for name in own],
            "",
        ]
    if elsewhere:
        lines += [
            "Also exported here (the same objects, documented once):",
            "",
            *[
                f"- ``{module_name}.{name}``: :py:{_role(obj)}:`{target}`"
                for name, obj, target in elsewhere
            ],
            "",
        ]
    return "\n".join(lines)


def write_api_pages(folder: Path) -> list[str]:
    """Write ``wavemeter.rst`` and one page per subpackage into ``folder``; their names."""
    folder.mkdir(parents=True, exist_ok=True)
    seen: dict[int, str] = {}
    pages = {
        "wavemeter": _page(
            "wavemeter",
            "The names ``import wavemeter as wm`` gives: calibrators, simulated devices, "
            "the physical limit, calibration files, errors and warnings.",
            seen,
        )
    }
    for name, summary in SUBPACKAGES.items():
        pages[name] = _page(name, summary, seen)
    for name, text in pages.items():
        path = folder / f"{name}.rst"
        if not path.exists() or path.read_text(encoding="utf-8") != text:
            path.write_text(text, encoding="utf-8")  # unchanged pages keep their time
    return list(pages)
