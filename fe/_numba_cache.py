"""Where numba keeps the compiled kernels of ``fe`` (``@njit(cache=True)``).

By default numba writes its cache next to the source, in ``__pycache__``.  For
an installed package that is inside site-packages, in files pip did not
install and so never removes: ``pip uninstall`` (or an editable reinstall)
then leaves ``site-packages/fe/`` behind as an empty namespace package that
shadows the real one.  So the cache goes to the user's cache directory
instead, unless ``NUMBA_CACHE_DIR`` says otherwise.  Imported by
``fe/__init__.py`` before any kernel module, since numba fixes a function's
cache location when it is decorated.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numba


def user_cache_dir() -> Path:
    """The per-user cache folder of this project: ``$XDG_CACHE_HOME/bayes-update``
    (``~/.cache`` when unset) on Linux, ``~/Library/Caches`` on macOS,
    ``%LOCALAPPDATA%`` on Windows."""
    if sys.platform == "win32":
        root = Path(os.environ.get("LOCALAPPDATA") or Path.home() / "AppData" / "Local")
    elif sys.platform == "darwin":
        root = Path.home() / "Library" / "Caches"
    else:
        root = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return root / "bayes-update"


def configure() -> str:
    """Point numba's on-disk cache at :func:`user_cache_dir` unless the user chose one
    (``NUMBA_CACHE_DIR``); returns the folder in use."""
    if not numba.config.CACHE_DIR:
        numba.config.CACHE_DIR = str(user_cache_dir() / "numba")
    return numba.config.CACHE_DIR


configure()
