"""emcee's ensemble sampler with its default move, for a vectorised log probability,
without its per-walker Python loops.

The chain on the surrogates is emcee's affine-invariant stretch move (Goodman &
Weare 2010; ``emcee.EnsembleSampler`` with its default ``StretchMove``, a = 2,
the walkers split at random into two halves each step).  emcee accepts or
rejects walker by walker in a Python loop and converts every walker's log
probability on its own: for 128 walkers that is 0.85 ms a step, more than the
two GP calls of the step themselves (0.3-0.4 ms each), and half of a 3000-step
chain's wall time.  :func:`stretch_sample` is the same algorithm over arrays.
It draws the same random numbers from the same ``RandomState`` in the same
order as emcee 3.1 (the move's choice, the split's shuffle, the stretch
factors, the partners, one uniform per walker for the acceptance), so that for
a seed it gives emcee's chain itself, to the last bit
(``tests/test_posterior.py::test_the_vectorised_stretch_move_is_emcees``): the
posterior is emcee's, only sooner.  A model's log probability (the direct path,
one run per walker through a process pool) stays in emcee.
"""

from __future__ import annotations

import numpy as np

__all__ = ["StretchChain", "stretch_sample"]


class StretchChain:
    """The run of :func:`stretch_sample`, read as an ``emcee.EnsembleSampler`` is
    (the methods the pipeline uses): ``get_chain``, ``get_log_prob``,
    ``acceptance_fraction``, ``get_autocorr_time``, ``get_last_sample``."""

    def __init__(self, chain: np.ndarray, log_prob: np.ndarray, n_accepted: np.ndarray, random=None):
        self.chain, self.log_prob, self.n_accepted = chain, log_prob, n_accepted
        self.random = random  # the RandomState the run drew from (a continuation draws on from it)

    def extend(self, log_prob, n_steps: int, progress: bool = False, desc: str = "MCMC") -> "StretchChain":
        """``n_steps`` more steps from the last walkers, drawing on from the same
        ``RandomState`` (the chain is then the one a longer run would have given,
        but for one more evaluation of the last walkers' log probability)."""
        more = stretch_sample(log_prob, self.chain[-1], n_steps, self.random, progress=progress, desc=desc)
        self.chain = np.concatenate([self.chain, more.chain])
        self.log_prob = np.concatenate([self.log_prob, more.log_prob])
        self.n_accepted = self.n_accepted + more.n_accepted
        return self

    @property
    def iteration(self) -> int:
        return len(self.chain)

    @property
    def acceptance_fraction(self) -> np.ndarray:
        return self.n_accepted / max(self.iteration, 1)

    @staticmethod
    def _read(values, discard: int, thin: int, flat: bool):
        out = values[discard + thin - 1 :: thin]  # emcee's slice of the stored steps
        return out.reshape(-1, *out.shape[2:]) if flat else out

    def get_chain(self, discard: int = 0, thin: int = 1, flat: bool = False) -> np.ndarray:
        """(steps, walkers, d), or (steps * walkers, d) with ``flat``."""
        return self._read(self.chain, discard, thin, flat)

    def get_log_prob(self, discard: int = 0, thin: int = 1, flat: bool = False) -> np.ndarray:
        return self._read(self.log_prob, discard, thin, flat)

    def get_autocorr_time(self, discard: int = 0, thin: int = 1, **kwargs) -> np.ndarray:
        """emcee's integrated autocorrelation time per coordinate [steps]."""
        import emcee

        return thin * emcee.autocorr.integrated_time(self.get_chain(discard=discard, thin=thin), **kwargs)

    def get_last_sample(self):
        import emcee

        return emcee.State(self.chain[-1].copy(), log_prob=self.log_prob[-1].copy())


def stretch_sample(
    log_prob,
    x_init,
    n_steps: int,
    random: np.random.RandomState,
    a: float = 2.0,
    progress: bool = False,
    desc: str = "MCMC",
) -> StretchChain:
    """``n_steps`` of the stretch move from the walkers ``x_init`` (n_walkers, d)
    on ``log_prob`` ((m, d) -> (m,), -inf outside the support), drawing from
    ``random`` exactly as ``emcee.EnsembleSampler(..., vectorize=True)`` with its
    default move does (module docstring)."""
    from tqdm.auto import tqdm

    X = np.array(x_init, float)
    n, d = X.shape
    if n < 2 * d:
        raise ValueError(f"{n} walkers for {d} dimensions: the stretch move needs at least {2 * d}")
    lp = _checked(log_prob, X)
    if not np.all(np.isfinite(lp)):
        raise ValueError("the walkers' initial log probability is not finite everywhere")
    chain, lps = np.empty((n_steps, n, d)), np.empty((n_steps, n))
    n_accepted = np.zeros(n)
    half = np.arange(n) % 2
    for t in tqdm(range(n_steps), desc=desc, unit="step", disable=None if progress else True):
        random.random_sample()  # emcee's choice among its moves (one move: a draw all the same)
        inds = half.copy()
        random.shuffle(inds)
        for split in (0, 1):
            active = np.flatnonzero(inds == split)
            s, c = X[active], X[inds != split]
            z = ((a - 1.0) * random.rand(len(s)) + 1.0) ** 2 / a
            partners = c[random.randint(len(c), size=(len(s),))]
            q = partners - (partners - s) * z[:, None]
            lp_new = _checked(log_prob, q)
            accept = (d - 1.0) * np.log(z) + lp_new - lp[active] > np.log(random.rand(len(s)))
            moved = active[accept]
            X[moved], lp[moved] = q[accept], lp_new[accept]
            n_accepted[moved] += 1
        chain[t], lps[t] = X, lp
    return StretchChain(chain, lps, n_accepted, random)


def _checked(log_prob, X) -> np.ndarray:
    lp = np.asarray(log_prob(X), float).reshape(-1)
    if lp.shape != (len(X),):
        raise ValueError(f"the log probability returned shape {lp.shape} for {len(X)} points")
    if np.any(np.isnan(lp)):
        raise ValueError("the log probability returned NaN")
    return lp
