"""The UFF58 side of the mapping of :mod:`.uff`: the specific data type and
function type codes, the units labels each channel accepts and their factors
to SI, the precision of the format's abscissa increment, and ``pyuff`` (an
optional extra, imported when a file is read or written).  Apart from the
reader (:mod:`.uff`) and the writer (:mod:`.uff_writer`), which both use it."""

from __future__ import annotations

FORCE_TYPE = 13  # UFF specific data type: excitation force
VELOCITY_TYPE = 11  # UFF specific data type: velocity
TIME_TYPE = 17  # UFF specific data type: time
TIME_RESPONSE = 1  # UFF function type: time response

FORCE_UNITS = {"": 1.0, "n": 1.0, "kn": 1e3, "mn": 1e-3, "lbf": 4.4482216152605}
VELOCITY_UNITS = {"": 1.0, "m/s": 1.0, "mm/s": 1e-3, "um/s": 1e-6, "µm/s": 1e-6, "in/s": 0.0254}
TIME_UNITS = {"": 1.0, "s": 1.0, "ms": 1e-3}
SPEC_NAMES = {
    0: "unknown",
    1: "general",
    2: "stress",
    3: "strain",
    5: "temperature",
    8: "displacement",
    9: "reaction force",
    11: "velocity",
    12: "acceleration",
    13: "excitation force",
    15: "pressure",
    17: "time",
}
RATE_TOLERANCE = 1e-5  # relative, the precision of the E13.5 abscissa increment


def load_pyuff():
    """The ``pyuff`` module, or an ImportError saying how to install it."""
    try:
        import pyuff
    except ImportError as exc:  # pragma: no cover - pyuff is an extra
        raise ImportError(
            "reading or writing UFF files needs pyuff: pip install 'bayes-update[uff]' (or pip install pyuff)"
        ) from exc
    return pyuff
