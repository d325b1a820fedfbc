"""The README is the short entry: its example runs as written, its links lead to the site.

The walk-throughs and the numbers they quote moved to the documentation pages with the
content; ``tests/test_docs_pages.py`` replays them there.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).parent.parent
README = (ROOT / "README.md").read_text(encoding="utf-8")


def test_the_python_example_runs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code = re.search(r"```python\n(.*?)```", README, re.S).group(1)
    namespace: dict = {}
    exec(compile(code, "README.md", "exec"), namespace)  # noqa: S102 - the README's own code
    assert namespace["cal"].fsr_hz_ == pytest.approx(namespace["dev"].true_fsr_hz, rel=1e-4)
    assert (tmp_path / "chip.wmcal.json").is_file()


def test_every_link_leads_to_a_file_of_the_repository():
    links = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", README)
    assert len(links) >= 15  # every user-guide page, the theory, both references, ...
    for link in links:
        assert (ROOT / link).exists(), f"README links to a missing file: {link}"


def test_the_readme_links_every_user_guide_page():
    guide = (ROOT / "docs" / "user-guide" / "index.rst").read_text(encoding="utf-8")
    pages = re.findall(r"^   (\S+)$", guide, re.M)
    assert "custom-calibrator" in pages and "absolute" in pages  # the toctree was read
    for page in pages:
        assert f"docs/user-guide/{page}.rst" in README, page
