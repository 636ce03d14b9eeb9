"""The notebooks run as tests (nbmake).  The OpenSeesPy example needs openseespy
(and, on Linux, libblas3 and liblapack3): where it cannot be imported that
notebook FAILS with what is missing and how to install it, as the other tests
of a missing reference do (tests/reference.py); with
``BAYES_UPDATE_ALLOW_MISSING_REFERENCES=1`` it is skipped instead."""

import os

import pytest

#: the opt-out of tests/reference.py, by the same name
ALLOW_MISSING_ENV = "BAYES_UPDATE_ALLOW_MISSING_REFERENCES"


def _openseespy_error():
    try:
        import openseespy.opensees  # noqa: F401
    except Exception as exc:  # ImportError, or the library's own load error (a missing liblapack)
        return f"{type(exc).__name__}: {exc}"
    return None


def _needs_opensees(item) -> bool:
    return "opensees" in item.nodeid.lower() and item.nodeid.endswith(".ipynb")


def pytest_collection_modifyitems(config, items):
    if os.environ.get(ALLOW_MISSING_ENV) != "1" or not any(_needs_opensees(i) for i in items):
        return
    error = _openseespy_error()
    if error:
        mark = pytest.mark.skip(
            reason=f"openseespy cannot be imported ({error}); the OpenSees example needs it ({ALLOW_MISSING_ENV}=1)"
        )
        for item in items:
            if _needs_opensees(item):
                item.add_marker(mark)


def pytest_runtest_setup(item):
    if _needs_opensees(item) and os.environ.get(ALLOW_MISSING_ENV) != "1":
        error = _openseespy_error()
        if error:
            pytest.fail(
                f"openseespy cannot be imported ({error}); the OpenSees example needs it: pip install "
                f"openseespy (the dev extra; libblas3 and liblapack3 on Linux). Set {ALLOW_MISSING_ENV}=1 to "
                "skip it instead.",
                pytrace=False,
            )
