import os
import sys
from pathlib import Path

# the suite runs in two processes on two cores (pytest -n 2): a BLAS thread each, in them and in
# the processes they start (two OpenBLAS threads per process spin against each other: the modal
# fits of one test module took 175 s in the suite against 58 s alone)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import matplotlib  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

_ONE_BLAS_THREAD = threadpool_limits(1, user_api="blas")

matplotlib.use("Agg")
sys.path.insert(0, str(Path(__file__).parent))  # for tests/reference.py


import pytest  # noqa: E402


@pytest.fixture(autouse=True, scope="module")
def _module_run_cache(tmp_path_factory):
    """The commands' run cache defaults to the user's (~/.cache/bayes-update): never there in
    the tests.  Each module its own (autouse: set before the module's own fixtures run, so that
    a module's fixtures never find another module's runs, whatever the order of the modules)."""
    import os

    old = os.environ.get("BAYES_UPDATE_CACHE")
    os.environ["BAYES_UPDATE_CACHE"] = str(tmp_path_factory.mktemp("run_cache_module"))
    yield
    if old is None:
        os.environ.pop("BAYES_UPDATE_CACHE", None)
    else:
        os.environ["BAYES_UPDATE_CACHE"] = old


@pytest.fixture(autouse=True)
def _run_cache(tmp_path_factory, monkeypatch):
    """Every test its own run cache: a test must not find another test's runs."""
    monkeypatch.setenv("BAYES_UPDATE_CACHE", str(tmp_path_factory.mktemp("run_cache")))
