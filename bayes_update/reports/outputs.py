"""Writing a command's results into its output folder all or nothing per file.

A long command (``sample``, ``reproduce``) may be interrupted at any point.
Its writers therefore never write into OUT directly: they write into a staging
folder inside OUT, and only when the command has finished is each file moved
into place with :func:`os.replace` (atomic on one file system).  An
interrupted or failed command leaves OUT as it was, except for OUT/cache,
which is written atomically by :class:`surrogates.EvaluationCache` and is what
a rerun resumes from.
"""

from __future__ import annotations

import contextlib
import os
import shutil
from pathlib import Path

__all__ = ["staged_output"]

STAGING_PREFIX = ".partial-"


@contextlib.contextmanager
def staged_output(out):
    """Yield a fresh staging folder inside ``out``; on success move its files
    into ``out`` (same relative paths, one atomic rename each), on any
    exception (including ``KeyboardInterrupt``) delete it (and ``out`` itself
    if this call created it and nothing else, e.g. a cache, is in it) and
    re-raise."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out} exists and is not a folder")
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    staging = out / f"{STAGING_PREFIX}{os.getpid()}"
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir()
    try:
        yield staging
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        if created and not any(out.iterdir()):  # a failed command leaves no empty OUT behind
            out.rmdir()
        raise
    _publish(staging, out)
    shutil.rmtree(staging, ignore_errors=True)


def _publish(staging: Path, out: Path) -> None:
    for src in sorted(p for p in staging.rglob("*") if p.is_file()):
        dst = out / src.relative_to(staging)
        dst.parent.mkdir(parents=True, exist_ok=True)
        os.replace(src, dst)
