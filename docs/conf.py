"""Sphinx configuration of the wavemeter documentation (``make docs``).

The site builds offline and is read offline: MathJax is the single-file build shipped in
``_static/mathjax`` (no CDN), there is no intersphinx (no inventory is fetched), and the
theme's assets are those installed with it. The API reference pages are written at the
start of every build from the ``__all__`` of ``wavemeter`` and of its public subpackages
(``_api_pages``), so no public name can be left out; the gallery's examples
(``examples/gallery``) run at every build and their figures go into the pages.
"""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path

import wavemeter

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS))

from _api_pages import write_api_pages  # noqa: E402  (needs the docs folder on the path)

# the command line runs BLAS on one thread; the examples' fits are skinny products too
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
# figures are drawn without a display
os.environ.setdefault("MPLBACKEND", "agg")

project = "wavemeter"
author = "the wavemeter developers"
copyright = "the wavemeter developers, MIT licence"  # noqa: A001 - Sphinx's name
version = release = wavemeter.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "sphinx_click",
    "sphinx_gallery.gen_gallery",
]

templates_path = ["_templates"]
exclude_patterns = [
    "_build",
    "theory-map.md",  # the lead's map from modules to theory pages: not part of the site
    "_static/mathjax/README.md",
    "gallery/*.ipynb",
    "gallery/*.py",
    "gallery/*.zip",
    "sg_execution_times.rst",
]
source_suffix = {".rst": "restructuredtext"}
root_doc = "index"
default_role = "code"
nitpicky = False
# "--force" stays two hyphens, quotes stay straight: options and code in prose are typed
smartquotes = False

# -- offline equations: MathJax 3 from _static, SVG output (no web fonts) ----------------
mathjax_path = "mathjax/tex-svg-full.js"
mathjax3_config = {
    "tex": {"inlineMath": [["\\(", "\\)"]], "displayMath": [["\\[", "\\]"]]},
    "svg": {"fontCache": "global"},
}

# -- API reference ------------------------------------------------------------------------
autosummary_generate = True
autosummary_imported_members = True
autodoc_default_options = {"members": False}
autodoc_typehints = "none"
autodoc_member_order = "bysource"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
# every public name has an Examples section (tests/test_doctests.py runs them): a public
# class or function without one is a build warning (an error under -W). Left out: the
# members of classes (``Calibrator.fit``; the class's Examples show them) and constants
# (``FORMATS``, ``__version__``), whose ``#:`` comments document them
numpydoc_validation_checks = {"EX01"}
numpydoc_validation_exclude = {r"\.[A-Z]\w*\.\w+$", r"\.[A-Z][A-Z0-9_]+$", r"\.__version__$"}

# -- the gallery: examples run at build time, their figures embedded ---------------------
sphinx_gallery_conf = {
    "examples_dirs": str(DOCS.parent / "examples" / "gallery"),
    "gallery_dirs": "gallery",
    "filename_pattern": r"/plot_",
    "ignore_pattern": r"__init__\.py",
    "abort_on_example_error": True,
    "download_all_examples": False,
    "remove_config_comments": True,
    "image_scrapers": ("matplotlib",),
    "matplotlib_animations": False,
    "show_memory": False,
    "show_signature": False,
    "capture_repr": ("_repr_html_", "__repr__"),
    "min_reported_time": 0,
    "within_subsection_order": "FileNameSortKey",
    # the execution-times pages load DataTables from a CDN: left out (offline site)
    "write_computation_times": False,
}

# -- HTML ---------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"wavemeter {release}"
html_static_path = ["_static"]
html_css_files = ["wavemeter.css"]
html_show_sourcelink = False
html_copy_source = False
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "navbar_align": "left",
    "header_links_before_dropdown": 7,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}
# the theme's light/dark switch starts from "auto" (an empty mode logs a console error)
html_context = {"default_mode": "auto"}
html_sidebars = {"index": [], "getting-started": [], "results": []}


#: rST markup that plain text (click's help, a docstring's ``|error|``) must not start
_SUBSTITUTION = re.compile(r"(?<![\w|`])\|(\S[^|\n]*?)\|(?![\w|])")
_TRAILING_UNDERSCORE = re.compile(r"(\w)_(?=\W|$)")


def _escape_plain(text: str) -> str:
    """Plain text as rST that shows it unchanged."""
    text = text.replace("\\", "\\\\")
    for char in "*|`":
        text = text.replace(char, "\\" + char)
    return _TRAILING_UNDERSCORE.sub(r"\1\\_", text)


def _escape_click_lines(app, ctx, lines):
    """Click's help is plain text; sphinx-click reads it as rST. Keep its line blocks."""
    for index, line in enumerate(lines):
        if re.match(r"^\s*(\.\. |:\w[\w -]*:)", line):  # sphinx-click's own directives
            continue
        block = re.match(r"^\s*\| ", line)
        head, body = (line[: block.end()], line[block.end() :]) if block else ("", line)
        lines[index] = head + _escape_plain(body)


def _escape_docstring_substitutions(app, what, name, obj, options, lines):
    """``|x|`` meaning an absolute value in a docstring is not an rST substitution."""
    for index, line in enumerate(lines):
        if not line.lstrip().startswith(("|", "+")):  # grid tables keep their bars
            lines[index] = _SUBSTITUTION.sub(lambda m: "\\|" + m.group(1) + "\\|", line)


def _defined_outside_wavemeter(obj) -> bool:
    target = getattr(obj, "fget", None) or getattr(obj, "__func__", None) or obj
    module = getattr(target, "__module__", None) or ""
    return not module.startswith("wavemeter")


def _skip_foreign_members(app, what, name, obj, skip, options):
    """A class page lists what wavemeter defines, not int's or Enum's methods."""
    if what in ("class", "exception") and _defined_outside_wavemeter(obj):
        return True
    return None


def setup(app):
    """Write the API reference pages before Sphinx reads the sources; escape plain text."""
    write_api_pages(DOCS / "reference" / "_api")
    app.connect("autodoc-process-docstring", _escape_docstring_substitutions)
    app.connect("autodoc-skip-member", _skip_foreign_members)
    for event in ("description", "options", "arguments", "epilog"):
        app.connect(f"sphinx-click-process-{event}", _escape_click_lines)
