"""Model runs through any ``concurrent.futures.Executor``: see :mod:`surrogates.evaluation`.

The helpers live in ``surrogates`` (which knows nothing of models or of
``bayes_update``) so that both packages use one implementation.
"""

from surrogates.evaluation import default_executor, evaluate_many

__all__ = ["default_executor", "evaluate_many"]
