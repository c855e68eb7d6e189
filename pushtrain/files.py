"""Atomic file writing: every result file is written under a temporary name in its folder and
renamed over the target, so an interrupted write never leaves a half-written file."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable

__all__ = ["atomic_write", "atomic_write_text", "atomic_write_bytes"]


def atomic_write(path, write: Callable[[Path], object], *, keep_suffix: bool = False) -> Path:
    """Call ``write(partial)`` on a temporary path in ``path``'s folder, then rename it to ``path``.

    The temporary name is ``.<name>.<pid>.part``; with ``keep_suffix`` it is
    ``.<stem>.<pid>.part<suffix>`` (matplotlib and Pillow choose the format by the suffix). It
    is removed whatever happens: a failure leaves neither a partial file nor a changed ``path``.
    """
    path = Path(path)
    pid = os.getpid()
    name = f".{path.stem}.{pid}.part{path.suffix}" if keep_suffix else f".{path.name}.{pid}.part"
    partial = path.with_name(name)
    try:
        write(partial)
        os.replace(partial, path)
    finally:
        partial.unlink(missing_ok=True)
    return path


def atomic_write_text(path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (:func:`atomic_write`)."""
    return atomic_write(path, lambda partial: partial.write_text(text))


def atomic_write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (:func:`atomic_write`)."""
    return atomic_write(path, lambda partial: partial.write_bytes(data))
