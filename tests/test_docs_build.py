"""The API reference (docs/api: Sphinx autodoc + napoleon over the four packages) builds with
warnings as errors: a docstring that breaks the reST markup, or a module that no longer imports,
fails here rather than on a reader's screen.  One HTML build, about 15-20 s on 2 cores."""

import os
from pathlib import Path

from sphinx.cmd.build import build_main

DOCS_API = Path(__file__).resolve().parents[1] / "docs" / "api"


def test_api_reference_builds_without_warnings(tmp_path):
    os.environ.setdefault("MPLBACKEND", "Agg")  # autodoc imports every module (conf.py sets it too)
    warnings = tmp_path / "warnings.txt"
    status = build_main(
        ["-W", "--keep-going", "-q", "-E", "-b", "html", "-w", str(warnings), str(DOCS_API), str(tmp_path / "html")]
    )
    text = warnings.read_text() if warnings.exists() else ""
    assert status == 0, f"sphinx-build failed ({status}):\n{text}"
    assert not text.strip(), text
    pages = {p.name for p in (tmp_path / "html").glob("*.html")}
    assert {"index.html", "bayes_update.html", "volterra.html", "surrogates.html", "fe.html"} <= pages
    # every package page holds its modules' documentation, not just a title
    for package in ("bayes_update", "volterra", "surrogates", "fe"):
        html = (tmp_path / "html" / f"{package}.html").read_text()
        assert html.count('class="py ') >= 5, f"{package}.html documents almost nothing"
