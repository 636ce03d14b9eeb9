"""What may import what (DESIGN.md section 6): each package imported alone, in a fresh process,
must not pull in the packages it is not allowed to know."""

import subprocess
import sys

import pytest

FORBIDDEN = {
    "surrogates": ("bayes_update", "fe", "volterra"),      # knows nothing of models or inference
    "volterra": ("bayes_update", "fe", "surrogates"),      # knows nothing of inference
    "fe": ("bayes_update", "volterra", "surrogates"),
    "bayes_update.core": ("fe",),                          # the generic core knows no beam
    "bayes_update.core.discrepancy": ("fe",),              # nor does its discrepancy engine, imported
}


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_package_imports_only_what_it_may(package):
    code = (f"import sys, {package}; "
            "print(sorted({m.split('.')[0] for m in sys.modules}))")
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    leaked = [p for p in FORBIDDEN[package] if f"'{p}'" in loaded]
    assert not leaked, f"importing {package} imports {leaked}"
