"""What may import what (docs/design.md#architecture-and-layering): each package imported alone, in a fresh process,
must not pull in the packages it is not allowed to know."""

import subprocess
import sys

import pytest

FORBIDDEN = {
    "surrogates": ("bayes_update", "fe", "volterra"),  # knows nothing of models or inference
    "volterra": ("bayes_update", "fe", "surrogates"),  # knows nothing of inference
    "fe": ("bayes_update", "volterra", "surrogates"),
    "bayes_update.core": ("fe",),  # the generic core knows no beam
    "bayes_update.core.discrepancy": ("fe",),  # nor does its discrepancy engine, imported
}


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_package_imports_only_what_it_may(package):
    code = f"import sys, {package}; print(sorted({{m.split('.')[0] for m in sys.modules}}))"
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    leaked = [p for p in FORBIDDEN[package] if f"'{p}'" in loaded]
    assert not leaked, f"importing {package} imports {leaked}"


def _imports(path):
    """Top-level package names and bayes_update subpackages a file imports (lazily or not)."""
    import ast

    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.add(node.module)
    return out


def test_only_the_beam_modules_import_fe_and_the_core_looks_no_higher():
    """Static: fe is imported only under bayes_update/models/beam/ (and by the beam's reports,
    reports/beam_*.py, and command line, cli/beam.py); core and data import neither models nor
    reports, models no reports."""
    from pathlib import Path

    import bayes_update

    root = Path(bayes_update.__file__).parent
    fe_users, upward = [], []
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root).as_posix()
        mods = _imports(path)
        if any(m == "fe" or m.startswith("fe.") for m in mods) and not (
            rel.startswith(("models/beam/", "reports/beam_", "cli/beam"))
        ):
            fe_users.append(rel)
        layer = rel.split("/")[0]
        higher = {
            "core": ("bayes_update.models", "bayes_update.reports"),
            "data": ("bayes_update.models", "bayes_update.reports", "bayes_update.core"),
            "models": ("bayes_update.reports",),
        }.get(layer, ())
        upward += [f"{rel} -> {m}" for m in mods if m.startswith(higher)] if higher else []
    assert not fe_users, f"modules outside the beam adapter import fe: {fe_users}"
    assert not upward, f"imports that run up the layers: {upward}"


@pytest.mark.parametrize(
    "module",
    [
        "bayes_update",
        "bayes_update.core.posterior",
        "bayes_update.core.calibrate",
        "bayes_update.core.likelihood",
        "bayes_update.data.dataset",
        "bayes_update.data.uff",
        "bayes_update.reports.calibration",
    ],
)
def test_generic_modules_load_no_fe(module):
    code = f"import sys, {module}; print('fe' in sys.modules)"
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert loaded.strip() == "False", f"importing {module} loads fe"
