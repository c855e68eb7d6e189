"""Where a CLI call's log goes: stderr and a run folder's ``run.log``.

Each handler is attached for the duration of one call and removed afterwards (with the
``pushtrain`` logger's level restored), so calls in one process do not pile up handlers.
"""

from __future__ import annotations

import logging
import sys
from contextlib import contextmanager
from pathlib import Path

__all__ = ["attached", "to_stderr", "to_run_log"]

LOGGER = "pushtrain"


@contextmanager
def attached(handler: logging.Handler, level: int):
    """Attach ``handler`` at ``level`` to the ``pushtrain`` logger (lowering the logger's level
    if needed) for the duration of the block; then remove and close it and restore the level."""
    logger = logging.getLogger(LOGGER)
    old_level = logger.level
    handler.setLevel(level)
    logger.addHandler(handler)
    if logger.getEffectiveLevel() > level:
        logger.setLevel(level)
    try:
        yield handler
    finally:
        logger.removeHandler(handler)
        logger.setLevel(old_level)
        handler.close()


def to_stderr(verbose: int):
    """pushtrain's messages on stderr: warnings; ``verbose`` 1 adds info, 2 debug."""
    level = logging.WARNING if verbose == 0 else logging.INFO if verbose == 1 else logging.DEBUG
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
    return attached(handler, level)


def to_run_log(out_dir: Path):
    """Every message (debug and up) in ``out_dir/run.log``."""
    handler = logging.FileHandler(out_dir / "run.log", mode="a", encoding="utf-8")
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    return attached(handler, logging.DEBUG)
