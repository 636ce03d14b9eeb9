"""Installing, running and uninstalling leave nothing behind in site-packages.

numba's on-disk cache used to be written next to the installed sources
(site-packages/fe/__pycache__); ``pip uninstall`` or an editable reinstall
removed the package's own files but not those, and the orphaned folder became
an empty namespace package that shadowed the project (issue 20).  These tests
install the project non-editable into a scratch environment, run a model
through the command line, uninstall, and look for leftovers.
"""

import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("fe", "volterra", "surrogates", "bayes_update")


def _run(cmd, **kw):
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=600, **kw)
    assert res.returncode == 0, f"{' '.join(map(str, cmd))} failed:\n{res.stdout[-3000:]}\n{res.stderr[-3000:]}"
    return res


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    # built from a clean copy: a build/ folder left in the checkout by an earlier
    # `pip install .` may hold modules that no longer exist
    src = tmp_path_factory.mktemp("src") / "project"
    shutil.copytree(
        ROOT,
        src,
        ignore=shutil.ignore_patterns(
            ".git", "build", "*.egg-info", "__pycache__", ".pytest_cache", "results", "out", "docs", "benchmarks"
        ),
    )
    out = tmp_path_factory.mktemp("wheel")
    _run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(out), str(src)])
    (whl,) = out.glob("bayes_update-*.whl")
    return whl


def _scratch_env(tmp_path):
    """A venv without pip whose dependencies (numpy, numba, ... and pip itself)
    come from this interpreter's site-packages through a .pth line, so the
    install under test is the only thing in its own site-packages."""
    env_dir = tmp_path / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", str(env_dir)])
    python = env_dir / ("Scripts/python.exe" if os.name == "nt" else "bin/python")
    purelib = Path(
        _run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"]).stdout.strip()
    )
    (purelib / "_outer_site_packages.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    return python, purelib


def test_install_run_uninstall_leaves_nothing(tmp_path, wheel):
    python, purelib = _scratch_env(tmp_path)
    # a checkout on PYTHONPATH would shadow the scratch install (the check below would fail on it)
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_") and k != "PYTHONPATH"}
    env["XDG_CACHE_HOME"] = str(tmp_path / "user-cache")
    env["MPLBACKEND"] = "Agg"
    _run([str(python), "-m", "pip", "install", "-q", "--no-deps", str(wheel)], env=env)
    # the scratch install, not this checkout or its editable install, is what runs
    where = _run(
        [str(python), "-c", "import fe, bayes_update; print(fe.__file__); print(bayes_update.__file__)"],
        env=env,
        cwd=tmp_path,
    ).stdout.split()
    assert all(Path(w).is_relative_to(purelib) for w in where), where
    script = python.parent / ("bayes-update.exe" if os.name == "nt" else "bayes-update")
    _run([str(script), "simulate", "--model", "rom", "--out", str(tmp_path / "out")], env=env, cwd=tmp_path)
    assert (tmp_path / "out" / "simulate.json").is_file()
    # the GP mean's compiled loop (surrogates.gp_mean) as a sampler calls it
    _run(
        [
            str(python),
            "-c",
            "import numpy as np; from surrogates.gp_mean import _matern_sum; "
            "print(_matern_sum(np.ones((3, 2)), np.zeros(2), np.ones(2), np.ones(2), np.ones((4, 2)), np.ones(4), 2))",
        ],
        env=env,
        cwd=tmp_path,
    )
    # numba compiled the ROM's kernels into the user's cache, not into site-packages
    assert list((tmp_path / "user-cache" / "bayes-update" / "numba").rglob("*.nbi"))
    assert not [p for pkg in PACKAGES for p in (purelib / pkg).rglob("*.nb[ic]")]
    _run([str(python), "-m", "pip", "uninstall", "-y", "-q", "bayes-update"], env=env)
    left = [pkg for pkg in PACKAGES if (purelib / pkg).exists()]
    assert not left, f"left behind in site-packages after uninstall: {left}"


def test_packages_import_from_any_working_directory(tmp_path):
    """A kernel started in notebooks/ (or anywhere) imports the real packages, not a
    namespace package of the same name (which has no __file__)."""
    code = (
        "import importlib; "
        f"mods = [importlib.import_module(n) for n in {PACKAGES!r}]; "
        "print([m.__file__ for m in mods])"
    )
    for cwd in (tmp_path, ROOT / "notebooks"):
        res = _run([sys.executable, "-c", code], cwd=cwd)
        assert "None" not in res.stdout, f"namespace package imported from {cwd}: {res.stdout}"
