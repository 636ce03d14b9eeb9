"""The beam rig of a data set: the one place where the beam code reads the ``rig`` block.

The data layer (:mod:`bayes_update.data.dataset`) knows no model and keeps the
``rig`` block of ``dataset.json`` as given (:attr:`Dataset.rig`: the raw
block, None when absent, or an :class:`fe.Rig` the beam code built the data
set with).  :func:`rig_of` turns it into an :class:`fe.Rig`.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import fe
from bayes_update.data.dataset import DatasetError

__all__ = ["rig_of"]


def _where(dataset) -> str:
    source = getattr(dataset, "source", None)
    if source is None:
        return str(getattr(dataset, "name", "<data set>"))
    path = Path(source)
    return str(path / "dataset.json") if path.is_dir() else str(source)


def rig_of(dataset) -> fe.Rig:
    """The beam rig (:class:`fe.Rig`, SI) of ``dataset``.

    * no ``rig`` block (``dataset.rig is None``): the paper's rig,
      ``fe.Rig.from_dict({})`` (``bending_stiffness_factor`` 1.0);
    * a ``rig`` block: :meth:`fe.Rig.from_dict` of it (absent keys take the
      paper's values, ``bending_stiffness_factor`` 1.0);
    * an :class:`fe.Rig`: itself.

    Raises :class:`DatasetError` naming the ``dataset.json`` for a bad block
    (unknown key, non-physical value).
    """
    rig = dataset.rig
    if isinstance(rig, fe.Rig):
        return rig
    if rig is None:
        rig = {}
    if not isinstance(rig, Mapping):
        raise DatasetError(
            f"{_where(dataset)}: 'rig' must be an object (the rig block) or an fe.Rig, got {type(rig).__name__}"
        )
    try:
        return fe.Rig.from_dict(dict(rig))
    except (TypeError, ValueError) as exc:
        raise DatasetError(f"{_where(dataset)}: bad 'rig' block: {exc}") from None
