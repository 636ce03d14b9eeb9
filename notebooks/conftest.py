"""The notebooks run as tests (nbmake).  The OpenSeesPy example is skipped, with
the reason, only where openseespy cannot be imported (it needs libblas3 and
liblapack3 on Linux); everywhere else it runs like the others."""
import pytest


def _openseespy_error():
    try:
        import openseespy.opensees  # noqa: F401
    except Exception as exc:        # ImportError, or the library's own load error (a missing liblapack)
        return f"{type(exc).__name__}: {exc}"
    return None


def pytest_collection_modifyitems(config, items):
    needs = [item for item in items if "opensees" in item.nodeid.lower() and item.nodeid.endswith(".ipynb")]
    if not needs:
        return
    error = _openseespy_error()
    if error:
        mark = pytest.mark.skip(reason=f"openseespy cannot be imported ({error}); the OpenSees example needs it")
        for item in needs:
            item.add_marker(mark)
