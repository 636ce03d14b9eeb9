"""The beam's mesh: where the nodes go and how a position on it is read.

Apart from :class:`fe.BeamModel` because its analyses (:mod:`fe.equilibrium`,
:mod:`fe.transient`) and the modal ROM (:mod:`fe.rom`) read the mesh too: the
node placement (:func:`distribute`), the cubic Hermite interpolation of the
transverse displacement (:func:`hermite_weights`) and the half bandwidth ``KD``
of the chain of 3-dof nodes (the storage of the banded matrices).
"""

from __future__ import annotations

import numpy as np

KD = 5  # half bandwidth of a chain of 3-dof nodes


def distribute(n: int, lengths: np.ndarray) -> np.ndarray:
    """Split n elements over segments proportionally (largest remainder, >= 1 each)."""
    if n < lengths.size:
        raise ValueError(
            f"n_elements = {n} is too small: the mesh needs at least {lengths.size} "
            "(a node at the shaker and one at the sensor)"
        )
    share = n * lengths / lengths.sum()
    counts = np.maximum(1, np.floor(share).astype(int))
    while counts.sum() < n:
        counts[np.argmax(share - counts)] += 1
    while counts.sum() > n:
        i = np.argmax(np.where(counts > 1, counts - share, -np.inf))
        counts[i] -= 1
    return counts


def hermite_weights(node_x: np.ndarray, x: float) -> np.ndarray:
    """Weights w (length 3 n_nodes) with w @ u = transverse displacement at x
    (cubic Hermite interpolation on the reference mesh)."""
    n_nodes = node_x.size
    if not node_x[0] <= x <= node_x[-1]:
        raise ValueError(f"position {x} m lies outside the beam [0, {node_x[-1]}] m")
    w = np.zeros(3 * n_nodes)
    hit = np.flatnonzero(np.isclose(node_x, x, rtol=0, atol=1e-12))
    if hit.size:
        w[3 * hit[0] + 1] = 1.0
        return w
    e = int(np.searchsorted(node_x, x) - 1)
    le = node_x[e + 1] - node_x[e]
    xi = (x - node_x[e]) / le
    w[3 * e + 1] = 1 - 3 * xi**2 + 2 * xi**3
    w[3 * e + 2] = le * (xi - 2 * xi**2 + xi**3)
    w[3 * e + 4] = 3 * xi**2 - 2 * xi**3
    w[3 * e + 5] = le * (-(xi**2) + xi**3)
    return w
