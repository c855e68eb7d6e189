"""Result files and run folders.

Every result file is written under a temporary name in its folder and renamed over the target,
so an interrupted write never leaves a half-written file. A run folder holds the files of exactly
one run: it is marked (:data:`RUN_MARKER`, written first) and a previous run in it is moved aside
in one rename before the new run writes anything.
"""

from __future__ import annotations

import logging
import os
import shutil
import uuid
from collections.abc import Callable
from pathlib import Path

from pushtrain.errors import InputError

__all__ = ["atomic_write", "atomic_write_text", "atomic_write_bytes", "RUN_MARKER",
           "is_run_folder", "fresh_run_folder"]

log = logging.getLogger(__name__)

RUN_MARKER = ".pushtrain-run"
"""Name of the file that marks a folder as a pushtrain run folder (its files may be replaced)."""

_MARKER_TEXT = ("pushtrain run folder: the next run written here replaces every file in it\n")


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
    """Write ``text`` to ``path`` atomically (:func:`atomic_write`), UTF-8 encoded."""
    return atomic_write(path, lambda partial: partial.write_text(text, encoding="utf-8"))


def atomic_write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (:func:`atomic_write`)."""
    return atomic_write(path, lambda partial: partial.write_bytes(data))


def is_run_folder(path) -> bool:
    """Whether ``path`` is a folder marked as a pushtrain run folder."""
    return (Path(path) / RUN_MARKER).is_file()


def _cannot(path: Path, exc: OSError, what: str) -> InputError:
    reason = exc.strerror or str(exc)
    blocker = next((p for p in path.parents if p.exists() and not p.is_dir()), None)
    if blocker is not None:
        reason = f"{str(blocker)!r} is a file"
    elif exc.filename and str(exc.filename) != str(path):
        reason += f" ({exc.filename})"
    return InputError(f"output folder {str(path)!r}: cannot {what}: {reason}; "
                      "allowed: a new or empty folder, or a previous pushtrain run folder, "
                      "in a place where folders can be created")


def _check_replaceable(path: Path) -> None:
    """Raise InputError unless ``path`` may be emptied: a marked run folder that does not
    hold the current working directory."""
    if not is_run_folder(path):
        raise InputError(
            f"output folder {str(path)!r} holds files but is not a pushtrain run folder "
            f"(no {RUN_MARKER} marker); allowed: a new or empty folder, or a previous pushtrain "
            "run folder (its files are replaced)")
    here, target = Path.cwd().resolve(), path.resolve()
    if here == target or target in here.parents:
        raise InputError(f"output folder {str(path)!r} holds the current folder {str(here)!r}; "
                         "allowed: a run folder that is not (inside) the current folder")


def fresh_run_folder(path) -> Path:
    """Make ``path`` an empty, marked run folder, ready for one run.

    A missing folder is created (with its parents), an empty one is used; a previous run
    folder is renamed aside in one ``os.rename`` (so ``path`` never holds files of two runs),
    a new folder is created in its place and the old one is deleted. The marker is the first
    file written. Anything else (a file, a folder of other files, a place where no folder can
    be created) raises :class:`~pushtrain.errors.InputError` and changes nothing.
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise InputError(f"output folder {str(path)!r} is a file; allowed: a folder path")
    old = None
    try:
        if path.is_dir() and any(path.iterdir()):
            _check_replaceable(path)
            old = path.with_name(f".{path.name}.replaced-{uuid.uuid4().hex[:12]}")
            os.rename(path, old)
        try:
            path.mkdir(parents=True, exist_ok=True)
        except OSError:
            if old is not None:
                os.rename(old, path)
            raise
        atomic_write_text(path / RUN_MARKER, _MARKER_TEXT)
    except OSError as exc:
        raise _cannot(path, exc, "be used as a run folder") from None
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
        if old.exists():
            log.warning("could not delete the previous run moved aside to %s", old)
        log.info("replaced the previous run in %s", path)
    return path
