"""The documentation site, built: every public name and command, the gallery, offline equations.

The site is built once per session (``sphinx-build -W --keep-going``, as ``make docs`` does)
from a copy of ``docs/`` and ``examples/gallery/`` in a temporary folder, so the test writes
nothing into the source tree; ``WAVEMETER_DOCS_HTML=<folder>`` uses an existing build
instead. Then:

- every name of ``wavemeter.__all__`` and of the public subpackages' ``__all__`` has an
  entry in the API reference, and every ``wavemeter`` command (and ``fleet``'s
  subcommands) one in the command reference;
- every gallery example ran at build time and its figures are in its page and on disk;
- the pages load nothing from the network (scripts, styles and images are local files);
- where Chromium is installed: the index and two theory pages load with no console error
  (console.error, console.warn, an uncaught exception or a failed load) and every equation
  is rendered by MathJax (no raw ``\\(`` or ``\\[`` left in the text).
"""

from __future__ import annotations

import html
import importlib
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import click
import pytest

import wavemeter
from wavemeter.cli import cli

ROOT = Path(__file__).resolve().parent.parent
SUBPACKAGES = (
    "wavemeter.calibration",
    "wavemeter.simulation",
    "wavemeter.io",
    "wavemeter.jobs",
    "wavemeter.model",
    "wavemeter.analysis",
    "wavemeter.fleet",
    "wavemeter.report",
)
#: folders the build writes into the docs' source tree, left out of the copy
GENERATED = ("_build", "gallery", "generated", "_api")
CHROMIUM = shutil.which("chromium")
CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--hide-scrollbars",
    "--window-size=1200,900",
    "--virtual-time-budget=20000",
)

pytestmark = pytest.mark.slow


@pytest.fixture(scope="session")
def site(tmp_path_factory) -> Path:
    """The built HTML site (a fresh build in a temporary copy of the sources)."""
    given = os.environ.get("WAVEMETER_DOCS_HTML")
    if given:
        return Path(given)
    work = tmp_path_factory.mktemp("docs-build")
    shutil.copytree(ROOT / "docs", work / "docs", ignore=shutil.ignore_patterns(*GENERATED))
    shutil.copytree(ROOT / "examples" / "gallery", work / "examples" / "gallery")
    out = work / "html"
    result = subprocess.run(
        [sys.executable, "-m", "sphinx", "-b", "html", "-W", "--keep-going", "-q"]
        + [str(work / "docs"), str(out)],
        capture_output=True,
        text=True,
        timeout=1200,
        check=False,
        env=os.environ | {"MPLBACKEND": "agg"},
    )
    assert result.returncode == 0, result.stderr[-4000:]
    assert "WARNING" not in result.stderr and "ERROR" not in result.stderr, result.stderr
    return out


def _text(path: Path) -> str:
    return path.read_text(encoding="utf-8")


def _anchors(path: Path) -> set[str]:
    return set(re.findall(r'\bid="([^"]+)"', _text(path)))


def test_every_public_name_of_wavemeter_has_its_entry(site):
    names = [name for name in wavemeter.__all__ if not name.startswith("_")]
    assert len(names) >= 30
    for name in names:
        entry = site / "reference" / "generated" / f"wavemeter.{name}.html"
        assert entry.is_file(), f"no reference page for wavemeter.{name}"
        assert f"wavemeter.{name}" in _anchors(entry), f"wavemeter.{name} is not described"
    assert f"wavemeter.{names[0]}" in _text(site / "reference" / "_api" / "wavemeter.html")


@pytest.mark.parametrize("module_name", SUBPACKAGES)
def test_every_public_name_of_a_subpackage_has_its_entry(site, module_name):
    module = importlib.import_module(module_name)
    listing = _text(site / "reference" / "_api" / f"{module_name}.html")
    for name in module.__all__:
        obj = getattr(module, name)
        own = site / "reference" / "generated" / f"{module_name}.{name}.html"
        if own.is_file():
            assert f"{module_name}.{name}" in _anchors(own)
            continue
        # the same object documented under another name: listed here with a link to it
        assert f"{module_name}.{name}" in listing, f"{module_name}.{name} is not listed"
        target = f"{getattr(obj, '__module__', '')}".startswith("wavemeter")
        assert target, f"{module_name}.{name} has no entry and is no wavemeter object"
        row = re.search(rf"{re.escape(module_name)}\.{name}</span></code>: (.*?)</li>", listing)
        assert row and "href=" in row.group(1), f"{module_name}.{name} links nowhere"


def _commands(group: click.Group, prefix: str) -> list[str]:
    names = []
    context = click.Context(group)
    for name in group.list_commands(context):
        names.append(f"{prefix}-{name}")
        command = group.get_command(context, name)
        if isinstance(command, click.Group):
            names += _commands(command, f"{prefix}-{name}")
    return names


def test_every_command_has_its_entry(site):
    anchors = _anchors(site / "reference" / "cli.html")
    commands = _commands(cli, "wavemeter")
    assert "wavemeter-fleet-calibrate" in commands and len(commands) >= 13
    for command in commands:
        assert command in anchors, f"no entry for `{command.replace('-', ' ', 1)}`"
    page = _text(site / "reference" / "cli.html")
    for option in ("--fsr", "--drop-invalid", "--max-order-error", "--time-column"):
        assert f'<span class="sig-name descname"><span class="pre">{option}</span>' in page


def test_every_gallery_example_ran_and_its_figures_are_in_the_page(site):
    examples = sorted((ROOT / "examples" / "gallery").glob("plot_*.py"))
    assert len(examples) >= 8
    for example in examples:
        page = site / "gallery" / f"{example.stem}.html"
        text = _text(page)
        assert "Total running time of the script" in text, f"{example.name} did not run"
        figures = re.findall(r'src="(\.\./_images/sphx_glr_[^"]+\.png)"', text)
        figures = [figure for figure in figures if "thumb" not in figure]
        assert figures, f"{example.name}: no figure in its page"
        for figure in figures:
            assert (page.parent / figure).is_file(), f"{example.name}: {figure} missing"


def test_the_user_guide_shows_the_gallery_figures(site):
    for name in ("sweep", "temperature", "wideband", "cascade", "measure-stream", "fleet"):
        text = _text(site / "user-guide" / f"{name}.html")
        figures = re.findall(r'src="(\.\./_images/sphx_glr_[^"]+\.png)"', text)
        assert figures, f"user guide page {name} shows no figure"
        for figure in figures:
            assert (site / "user-guide" / figure).is_file()


def test_nothing_is_loaded_from_the_network(site):
    pages = list(site.rglob("*.html"))
    assert len(pages) > 50
    for page in pages:
        text = _text(page)
        loaded = re.findall(r'<(?:script|img|link|iframe)\b[^>]*?(?:src|href)="([^"]+)"', text)
        remote = [url for url in loaded if re.match(r"(https?:)?//", url)]
        assert not remote, f"{page.relative_to(site)} loads {remote}"
    index = _text(site / "index.html")
    assert "_static/mathjax/tex-svg-full.js" in index or "mathjax" not in index
    assert (site / "_static" / "mathjax" / "tex-svg-full.js").is_file()


PROBE = """<script>
(() => {
  const errors = [];
  addEventListener("error", (event) => {
    const source = event.target && (event.target.src || event.target.href);
    errors.push(source ? "failed to load " + source : String(event.message));
  }, true);
  for (const level of ["error", "warn"]) {
    const original = console[level];
    console[level] = (...args) => {
      errors.push(level + ": " + args.join(" "));
      original(...args);
    };
  }
  addEventListener("load", () => {
    const done = () => {
      const maths = [...document.querySelectorAll(".math")];
      const state = {
        errors,
        maths: maths.length,
        rendered: maths.filter((m) => m.querySelector("mjx-container svg")).length,
        raw: maths.filter((m) => /\\\\\\(|\\\\\\[|\\$\\$/.test(m.textContent)).length,
        resources: performance.getEntriesByType("resource").map((r) => r.name),
      };
      document.body.setAttribute("data-probe", JSON.stringify(state));
    };
    const ready = window.MathJax && MathJax.startup && MathJax.startup.promise;
    ready ? MathJax.startup.promise.then(done, (e) => { errors.push(String(e)); done(); }) : done();
  });
})();
</script>"""


def _chromium(arguments: list[str], profile: Path) -> subprocess.CompletedProcess:
    result = subprocess.run(
        [CHROMIUM, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", *arguments],
        capture_output=True,
        text=True,
        timeout=180,
        check=False,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    return result


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed: the browser test")
@pytest.mark.parametrize("name", ["index.html", "theory/crlb.html", "theory/cascade.html"])
def test_the_page_renders_every_equation_with_no_console_error(site, name, tmp_path):
    page = site / name
    probed = page.with_name(f"probed-{page.name}")
    probed.write_text(_text(page).replace("<head>", "<head>" + PROBE, 1), encoding="utf-8")
    try:
        dom = _chromium(["--dump-dom", probed.as_uri()], tmp_path / "profile").stdout
    finally:
        probed.unlink()
    found = re.search(r'data-probe="([^"]*)"', dom)
    assert found, "the probe did not run: " + dom[:500]
    state = json.loads(html.unescape(found.group(1)))
    assert state["errors"] == []
    if name != "index.html":
        assert state["maths"] >= 10
    assert state["rendered"] == state["maths"] and state["raw"] == 0
    assert all(url.startswith(("file:", "data:", "blob:")) for url in state["resources"])
    logged = _chromium(
        ["--enable-logging=stderr", "--v=0", "--dump-dom", page.as_uri()], tmp_path / "profile2"
    )
    # Chromium logs every console message at one level; the theme logs an informational
    # line ("[PST]: Changed to auto mode ..."). Errors, uncaught exceptions and failed loads
    # are what must not appear (the probe above also caught console.error and .warn).
    console = [line for line in logged.stderr.splitlines() if ":CONSOLE" in line]
    bad = [line for line in console if re.search(r"Uncaught|[Ee]rror|[Ff]ailed|ERR_|[Ww]arn", line)]
    assert bad == []
