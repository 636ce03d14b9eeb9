"""How nonlinear each level of the virtual rig is: the Volterra share of a record
and the physics' own departure from linearity (the level choice of
:mod:`bayes_update.models.beam.virtual_rig`, checked in tests/test_rig_virtual.py)."""

from __future__ import annotations

import dataclasses

import numpy as np

from bayes_update.models.beam.virtual_rig import TestSpec, VirtualRig

__all__ = ["linear_departure", "nonlinear_shares"]


def nonlinear_shares(force, velocity, f1_hz: float, zeta1: float, fs: float, n_functions=(2, 2, 4)) -> dict:
    """Volterra decomposition of one record: nonlinear share ||y2 + y3|| / ||y||,
    ||y3|| / ||y1||, ||y2|| / ||y1|| and the fit's relative residual.

    The Kautz pole is the first mode (``f1_hz``, ``zeta1``); J per order
    ``n_functions``.  Caveat: on a chirp the share does not fall below about
    2 % even at vanishing force (J = (2, 2, 4)), because the linear response
    is not exactly in the span of J1 = 2 Kautz functions and the cubic
    regressors of a narrow-band sweep take up part of the rest; compare with
    :func:`linear_departure`, which measures the physics alone.
    """
    import volterra

    basis = volterra.KautzBasis.from_modal(f1_hz, zeta1, fs, n_functions=tuple(n_functions), feedthrough=False)
    model = volterra.fit_volterra(np.asarray(force, float), np.asarray(velocity, float), basis)
    y1, y2, y3 = model.components(np.asarray(force, float))
    y = np.asarray(velocity, float)
    n = np.linalg.norm
    return {
        "share": float(n(y2 + y3) / n(y)),
        "y3_over_y1": float(n(y3) / n(y1)),
        "y2_over_y1": float(n(y2) / n(y1)),
        "residual": float(n(y - y1 - y2 - y3) / n(y)),
    }


def linear_departure(vrig: VirtualRig, spec: TestSpec, reference_n: float = 1e-4) -> float:
    """||y(A) - (A / A0) y(A0)|| / ||y(A)||: departure of the noise-free response
    from linear scaling of a response at a tiny force A0 = ``reference_n`` [N]."""
    _, _, y = vrig.clean(spec)
    _, _, y0 = vrig.clean(dataclasses.replace(spec, amplitude_n=reference_n))
    return float(np.linalg.norm(y - y0 * spec.amplitude_n / reference_n) / np.linalg.norm(y))
