"""The package's log: stdlib ``logging`` under the name ``bayes_update``.

Long steps report through :func:`info` (the default ``log`` of every verb);
the command line sets the level (``--quiet``, ``--verbose``) and where the
lines go (stderr, ``--log-file``).  In a script or a notebook, nothing shows
until logging is configured, e.g. ``logging.basicConfig(level=logging.INFO)``,
or pass ``log=print`` to the verb.
"""

from __future__ import annotations

import logging

__all__ = ["LOG", "info"]

LOG = logging.getLogger("bayes_update")


def info(*parts) -> None:
    """Log one line at INFO level (the parts joined by spaces, like ``print``)."""
    LOG.info(" ".join(str(p) for p in parts))
