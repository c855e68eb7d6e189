"""Result files and run folders.

Every result file is written under a temporary name in its folder and renamed over the target,
so an interrupted write never leaves a half-written file; a write that fails (a full disk) raises
:class:`WriteError` naming the file and its folder. A run folder holds the files of exactly one
run: it is marked (:data:`RUN_MARKER`, written first), a previous run in it is moved aside in one
rename before the new run writes anything, and the run that writes it holds a lock on its marker
(:func:`claim_run_folder`), so a second run into the same folder is refused while the first
writes.
"""

from __future__ import annotations

import errno
import fcntl
import logging
import os
import shutil
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from pushtrain.errors import InputError, PushtrainError

__all__ = ["atomic_write", "atomic_write_text", "atomic_write_bytes", "WriteError",
           "remove_partials", "RUN_MARKER", "is_run_folder", "claim_run_folder",
           "fresh_run_folder"]

log = logging.getLogger(__name__)

RUN_MARKER = ".pushtrain-run"
"""Name of the file that marks a folder as a pushtrain run folder (its files may be replaced)."""

_MARKER_TEXT = ("pushtrain run folder: the next run written here replaces every file in it\n")


_DISK_FULL = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG}


class WriteError(OSError, PushtrainError):
    """A file that could not be written (an :class:`OSError` with the cause's ``errno`` and
    ``strerror``): "disk full while writing results.npz in DIR", or "cannot write NAME in DIR:
    REASON". A run-time failure (the CLI's exit 1), not bad input."""

    def __init__(self, path, cause: OSError):
        super().__init__(cause.errno, cause.strerror or str(cause), str(path))
        self.path = Path(path)

    def __str__(self) -> str:
        where = f"{self.path.name} in {self.path.parent}"
        if self.errno in _DISK_FULL:
            return f"disk full while writing {where}"
        return f"cannot write {where}: {self.strerror}"


_PARTIALS: set[tuple[int, Path]] = set()
"""(pid, partial path) of the writes under way in this process, for :func:`remove_partials`."""


def _partial_name(path: Path, pid: int, keep_suffix: bool) -> str:
    return f".{path.stem}.{pid}.part{path.suffix}" if keep_suffix else f".{path.name}.{pid}.part"


def atomic_write(path, write: Callable[[Path], object], *, keep_suffix: bool = False) -> Path:
    """Call ``write(partial)`` on a temporary path in ``path``'s folder, then rename it to ``path``.

    The temporary name is ``.<name>.<pid>.part``; with ``keep_suffix`` it is
    ``.<stem>.<pid>.part<suffix>`` (matplotlib and Pillow choose the format by the suffix). It
    is removed whatever happens: a failure leaves neither a partial file nor a changed ``path``.
    An OSError of the write itself (a full disk, ...) is raised as :class:`WriteError`; one that
    names another file (a source that cannot be read) is raised as it is.
    """
    path = Path(path)
    pid = os.getpid()
    partial = path.with_name(_partial_name(path, pid, keep_suffix))
    entry = (pid, partial)
    _PARTIALS.add(entry)
    try:
        write(partial)
        os.replace(partial, path)
    except WriteError:
        raise
    except OSError as exc:
        if exc.filename is not None and str(exc.filename) not in (str(partial), str(path)):
            raise
        raise WriteError(path, exc) from exc
    finally:
        try:
            partial.unlink(missing_ok=True)
        finally:
            _PARTIALS.discard(entry)
    return path


def remove_partials(folder=None, pid: int | None = None) -> None:
    """Remove partial files: with ``folder`` and ``pid``, every ``.*.<pid>.part*`` file in
    ``folder`` (those of a process that was stopped or killed); without, the writes under way
    in this process (a signal handler, before the process ends at once)."""
    if folder is not None:
        for partial in Path(folder).glob(f".*.{pid}.part*"):
            partial.unlink(missing_ok=True)
        return
    here = os.getpid()
    for owner, partial in list(_PARTIALS):
        if owner == here:
            try:
                partial.unlink(missing_ok=True)
            except OSError:
                pass


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
    from .validation import clip_text

    reason = exc.strerror or str(exc)
    try:
        blocker = next((p for p in path.parents if p.exists() and not p.is_dir()), None)
    except OSError:  # a name or path too long to look at
        blocker = None
    if blocker is not None:
        reason = f"{clip_text(str(blocker), 120)!r} is a file"
    elif exc.filename and str(exc.filename) != str(path):
        reason += f" ({clip_text(str(exc.filename), 120)})"
    return InputError(f"output folder {clip_text(str(path), 120)!r}: cannot {what}: {reason}; "
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


class _Claim:
    """A lock (``flock``) on a run folder's marker, held by the run that writes the folder."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.fd: int | None = None

    def take(self) -> bool:
        """Lock the marker now in the folder; False when another run holds it (or has moved
        the folder away). The lock must be on the file the marker's name leads to once locked:
        a marker replaced meanwhile (by a run making the folder anew) is locked again."""
        marker = self.folder / RUN_MARKER
        while True:
            try:
                fd = os.open(marker, os.O_RDONLY)
            except FileNotFoundError:
                return False
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                current = os.stat(marker).st_ino == os.fstat(fd).st_ino
            except (BlockingIOError, FileNotFoundError):
                os.close(fd)
                return False
            except BaseException:
                os.close(fd)
                raise
            if current:
                self.release()
                self.fd = fd
                _CLAIMS.add(fd)
                return True
            os.close(fd)

    def release(self) -> None:
        if self.fd is not None:
            _CLAIMS.discard(self.fd)
            os.close(self.fd)
            self.fd = None


_CLAIMS: set[int] = set()
"""The descriptors of the locked markers of this process."""


def _forget_claims() -> None:
    """In a forked child (a plot process): close its copies of the locks' descriptors, so the
    folder is free when the run ends, whatever the child does (a copy closed does not unlock)."""
    for fd in list(_CLAIMS):
        try:
            os.close(fd)
        except OSError:
            pass
    _CLAIMS.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_claims)


def _in_use(path: Path) -> InputError:
    pid = ""
    try:
        for line in (path / RUN_MARKER).read_text(encoding="utf-8").splitlines():
            if line.startswith("pid "):
                pid = f" (pid {line[4:].strip()})"
    except (OSError, UnicodeDecodeError):
        pass
    return InputError(f"output folder {str(path)!r} is in use by another run{pid} that is "
                      "still writing it; allowed: a folder no run is writing (wait for that "
                      "run to end, or give another folder)")


def _mark(path: Path) -> None:
    atomic_write_text(path / RUN_MARKER, f"{_MARKER_TEXT}pid {os.getpid()}\n")


def _remove_moved(old: Path | None) -> None:
    """Delete a previous run moved aside (its folder has a new run now, or will have)."""
    if old is None or not old.exists():
        return
    shutil.rmtree(old, ignore_errors=True)
    if old.exists():
        log.warning("could not delete the previous run moved aside to %s", old)


@contextmanager
def claim_run_folder(path) -> Iterator[Path]:
    """Make ``path`` an empty, marked run folder and hold it for one run (the block).

    A missing folder is created (with its parents), an empty one is used; a previous run
    folder is renamed aside in one ``os.rename`` (so ``path`` never holds files of two runs),
    a new folder is created in its place and the old one is deleted. The marker is the first
    file written; its lock (``flock``) is held until the block ends, so a second run into the
    folder meanwhile is refused (:class:`~pushtrain.errors.InputError` "in use by another
    run"), as is anything else that cannot be a run folder (a file, a folder of other files, a
    place where no folder can be created); a refusal changes nothing.
    """
    path = Path(path)
    try:
        is_file = path.exists() and not path.is_dir()
    except OSError as exc:  # a name or a path too long
        raise _cannot(path, exc, "be used as a run folder") from None
    if is_file:
        raise InputError(f"output folder {str(path)!r} is a file; allowed: a folder path")
    claim, old = _Claim(path), None
    try:
        if path.is_dir() and any(path.iterdir()):
            _check_replaceable(path)
            if not claim.take():
                raise _in_use(path)
            old = path.with_name(f".{path.name}.replaced-{uuid.uuid4().hex[:12]}")
            os.rename(path, old)
        try:
            path.mkdir(parents=True, exist_ok=True)
        except OSError:
            if old is not None:
                os.rename(old, path)
                old = None
            raise
        # another run may have made the folder too, since we looked: the one that locks the
        # marker first has it (a folder that holds more than the marker is another run's)
        if not any(path.iterdir()):
            _mark(path)
        if not (is_run_folder(path) and claim.take() and len(list(path.iterdir())) == 1):
            _remove_moved(old)  # the other run's files replace that run now
            raise _in_use(path)
    except OSError as exc:
        claim.release()
        raise _cannot(path, exc, "be used as a run folder") from None
    except BaseException:
        claim.release()
        raise
    if old is not None:
        _remove_moved(old)
        log.info("replaced the previous run in %s", path)
    try:
        yield path
    finally:
        claim.release()


def fresh_run_folder(path) -> Path:
    """Make ``path`` an empty, marked run folder, ready for one run (:func:`claim_run_folder`
    without holding it: use that for a run that writes the folder)."""
    with claim_run_folder(path) as folder:
        return folder
