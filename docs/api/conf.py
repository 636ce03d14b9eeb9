"""Sphinx configuration of the API reference (``docs/api``), generated from the docstrings.

Build: ``sphinx-build -W --keep-going -b html docs/api OUT`` (``tests/test_docs_build.py`` does
it in the default test run, warnings as errors).

Each package page holds one directive line, ``.. package-modules:: NAME``, which this file expands
(on ``source-read``) into one ``automodule`` section per module of the package, found by walking
the package: a module added or renamed by a refactor appears in the reference without editing the
pages, and nothing is written into the source folder.  Private modules (a name part starting with
``_``) and ``__main__`` are left out.  Packages are documented with ``:ignore-module-all:``, so
that the names a package re-exports from its modules are documented once, where they are defined.
"""

import importlib
import os
import pkgutil
import re
import sys
from pathlib import Path

# autodoc imports every module: matplotlib must never try to open a window
os.environ.setdefault("MPLBACKEND", "Agg")

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

project = "bayes-update"
author = "the bayes-update developers"
copyright = "2017-2026, the bayes-update developers; after Bussetta, Shiki and da Silva (2017)"
release = version = "0.1.0"

extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon"]

# numpy- and Google-style sections are both in use
napoleon_google_docstring = True
napoleon_numpy_docstring = True
napoleon_use_rtype = False

autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_member_order = "bysource"
# signatures keep the code's annotations; types in the description stay as text
autodoc_typehints = "signature"
# docstrings of this project are in plain text with ``literals``: single backquotes are literals too
default_role = "code"

nitpicky = False
exclude_patterns = ["_build"]
html_theme = "alabaster"
html_static_path = []
html_title = "bayes-update API reference"

# -- the project's field convention ---------------------------------------------------------
# Most docstrings here write a parameter as ``name : what it is`` (the text after the colon is a
# description, often with units), where numpy style reads ``name : type``.  Before napoleon reads a
# Parameters / Other Parameters / Attributes section, such an entry becomes ``name`` with the text
# as its indented description; a short ``name : type`` followed by an indented description (the
# numpy style of ``volterra``) is left alone.  A paragraph after the entries, at their indentation,
# closes the section (napoleon would read it as more entries).
_FIELD_SECTIONS = {"parameters", "other parameters", "attributes"}
_ENTRY = re.compile(r"^(\s*)([A-Za-z_*][\w*]*(?:, *[A-Za-z_*][\w*]*)*) : (.*)$")
_BARE_ENTRY = re.compile(r"^\s*[A-Za-z_*][\w*]*(?:, *[A-Za-z_*][\w*]*)*\s*$")


def _indent(line):
    return len(line) - len(line.lstrip())


_PLAIN = {}


def _keep_plain(app, what, name, obj, options, lines):
    """Undo napoleon on attributes, data and properties: it reads a first line with a colon as
    ``type: description``, and here that colon is prose (``#: what it is: why``)."""
    if what in ("attribute", "data", "property") and name in _PLAIN:
        lines[:] = _PLAIN.pop(name)


def _project_fields(app, what, name, obj, options, lines):
    if what in ("attribute", "data", "property"):
        _PLAIN[name] = list(lines)
        return
    out, i, base = [], 0, None
    while i < len(lines):
        line, nxt = lines[i], (lines[i + 1] if i + 1 < len(lines) else "")
        if re.fullmatch(r"\s*-{3,}\s*", nxt) and line.strip():
            base = _indent(line) if line.strip().lower() in _FIELD_SECTIONS else None
            out += [line, nxt]
            i += 2
            continue
        if base is not None and line.strip() and _indent(line) == base:
            m = _ENTRY.match(line)
            if m:
                rest = m.group(3).strip()
                typed = len(rest.split()) <= 4 and nxt.strip() and _indent(nxt) > base
                out += [line] if typed else [m.group(1) + m.group(2), m.group(1) + "    " + rest]
                i += 1
                continue
            if not _BARE_ENTRY.match(line) and out and not out[-1].strip():
                out.append("")  # two blank lines end a napoleon section
                base = None
        out.append(line)
        i += 1
    lines[:] = out


_DIRECTIVE = re.compile(r"^\.\. package-modules:: *(\S+) *$", re.M)


def package_modules(package):
    """The public modules of ``package`` (itself first), sorted by name."""
    pkg = importlib.import_module(package)
    names = [package]
    for info in pkgutil.walk_packages(pkg.__path__, prefix=package + "."):
        if any(part.startswith("_") for part in info.name.split(".")):
            continue
        names.append(info.name)
    return sorted(names)


def _module_section(name):
    is_package = hasattr(importlib.import_module(name), "__path__")
    lines = [f"``{name}``", "-" * (len(name) + 4), "", f".. automodule:: {name}"]
    if is_package:
        lines.append("   :ignore-module-all:")
    return "\n".join(lines) + "\n\n"


def _expand(app, docname, source):
    source[0] = _DIRECTIVE.sub(lambda m: "".join(_module_section(n) for n in package_modules(m.group(1))), source[0])


def setup(app):
    app.connect("source-read", _expand)
    # before napoleon (priority 500) turns the sections into fields
    app.connect("autodoc-process-docstring", _project_fields, priority=100)
    app.connect("autodoc-process-docstring", _keep_plain, priority=900)
    return {"parallel_read_safe": True}
