"""Where a command's model runs go: ``--workers`` checked, ``--scheduler`` checked
before any long step (Dask's distributed installed, the address answering) and
its Dask executor.  Apart from :mod:`.commands` (what each command does): the
same plumbing serves every command that runs a model."""

from __future__ import annotations

import contextlib
import sys
from pathlib import Path


def workers_from(args):
    if args.workers is not None and args.workers < 1:
        raise ValueError(f"--workers must be at least 1, got {args.workers}")
    return args.workers


#: seconds a Dask scheduler has to accept a connection (the check before any long step)
SCHEDULER_TIMEOUT = 3.0
#: Dask's scheduler port when an address gives none
DASK_PORT = 8786


def check_scheduler(args) -> None:
    """``--scheduler ADDRESS``, before any long step: Dask's distributed is installed and
    a tcp (or tls) address accepts a connection within :data:`SCHEDULER_TIMEOUT`.  Another
    transport (inproc, ucx, ws) is left to Dask's own connection in :func:`executor_from`."""
    address = getattr(args, "scheduler", None)
    if not address:
        return
    import importlib.util
    import socket

    if importlib.util.find_spec("distributed") is None:
        raise ValueError("--scheduler needs Dask's distributed scheduler: pip install 'dask[distributed]'")
    scheme, sep, rest = address.rpartition("://")
    if sep and scheme not in ("tcp", "tls"):
        return
    if rest.startswith("["):  # [IPv6]:port
        host, _, tail = rest[1:].partition("]")
        port = tail[1:] if tail.startswith(":") else ""
    else:
        host, _, port = rest.partition(":") if rest.count(":") == 1 else (rest, "", "")
    if not host or (port and not port.isdigit()):
        raise ValueError(f"--scheduler {address}: expected tcp://HOST:PORT (e.g. tcp://10.0.0.5:{DASK_PORT})")
    try:
        socket.create_connection((host, int(port or DASK_PORT)), timeout=SCHEDULER_TIMEOUT).close()
    except OSError as exc:
        raise ValueError(
            f"--scheduler {address}: no Dask scheduler answers there ({exc.strerror or exc}); start "
            "one (`dask scheduler`) or check the address and port"
        ) from None


@contextlib.contextmanager
def executor_from(args):
    """The executor of the model runs: a Dask cluster's (``--scheduler``, checked first by
    :func:`check_scheduler`), else None (the functions then start a local process pool
    over ``--workers``)."""
    if not getattr(args, "scheduler", None):
        yield None
        return
    import distributed

    try:
        client = distributed.Client(args.scheduler, set_as_default=False, timeout="10s")
    except (OSError, TimeoutError) as exc:
        raise ValueError(f"--scheduler {args.scheduler}: no Dask scheduler answers there ({exc})") from None
    try:
        workers = len(client.scheduler_info().get("workers", {}))
        print(f"bayes-update: model runs on the Dask cluster at {args.scheduler} ({workers} workers)", file=sys.stderr)
        where = str(getattr(args, "model", "")).rpartition(":")[0]
        if where.endswith(".py"):
            # a model file of the user's: the workers import it by its name, as local processes
            # do (the files it imports beside it must be importable there too)
            client.upload_file(str(Path(where).expanduser().resolve()), load=False)
        yield client.get_executor()
    finally:
        client.close()
