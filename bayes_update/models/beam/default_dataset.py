"""The embedded default data set: where it lies in the package, how it is read,
and the true parameters a virtual-rig data set states.  Apart from
:mod:`.virtual_rig` (which makes data sets): reading the shipped copy needs no
rig run."""

from __future__ import annotations

import importlib.resources
from pathlib import Path

from bayes_update.data.dataset import Dataset
from bayes_update.data.folder import read_dataset
from bayes_update.models.beam.rig import rig_of

DEFAULT_DATASET_DIR = Path(__file__).resolve().parent / "default_data"
"""Folder of the embedded default data set (inside the package)."""


def truth_paper_units(dataset) -> dict | None:
    """The true parameters a virtual-rig data set states (paper units, with
    P_eff), or None: for marking figures and checking results, never read by
    the updating."""
    t = (dataset.extra or {}).get("truth", {}).get("parameters_si")
    if not t:
        return None
    kb = rig_of(dataset).axial_stiffness
    return {
        "eta": t["eta"] / 1e6,
        "c": t["c"] / 1e3,
        "F": t["F"],
        "k_s": t["k_s"] / 1e3,
        "P_eff": t["F"] * kb / (kb + t["k_s"]),
    }


def default_dataset_path() -> Path:
    """Path of the embedded default data set folder."""
    res = importlib.resources.files("bayes_update").joinpath("models", "beam", "default_data")
    return Path(str(res))


def load_default_dataset() -> Dataset:
    """The embedded default data set: the paper's six tests from the
    paper-equivalent virtual rig at Table 3 (see the docstring of
    :mod:`bayes_update.models.beam.virtual_rig`)."""
    return read_dataset(default_dataset_path())
