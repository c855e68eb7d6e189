"""The pictures of a run (four PNG plots and the GIF), drawn in helper processes while the main
process plans, co-simulates and saves.

:func:`plotter` starts, as soon as the scenario and its map are loaded, up to two plot
processes (forked, so they share the loaded scenario, map and modules). While the main process
plans and co-simulates they import matplotlib and ready its fonts. :meth:`PlotWorkers.submit`
then sends each of them the results table (its raw bytes through the process's pipe, from a
thread, so the main process saves the results meanwhile), and each takes the next file nobody
has taken yet (the GIF first, the largest job) until none is left. :meth:`PlotWorkers.wait`
waits for the named files and returns what went wrong with them.

What can go wrong becomes a :class:`PlotProblem` naming the file: the drawing raised (the
message and the traceback, which goes to ``run.log``), the process died (its pipe closed), or
no word came from the processes for :data:`SILENCE_LIMIT_S` (they are stopped). Files already
written stay: each is written atomically. Where processes cannot be forked, :class:`InlinePlotter`
draws the same files in the main process, behind the same methods.

The main process never imports matplotlib on this route, so its peak memory is that of planning
and co-simulation; each plot process logs its own peak (``run.log``).
"""

from __future__ import annotations

import gc
import logging
import multiprocessing
import os
import resource
import signal
import sys
import threading
import time
import traceback
from contextlib import contextmanager
from dataclasses import dataclass
from multiprocessing.connection import wait as wait_for_any
from pathlib import Path

import numpy as np

__all__ = ["PNG_FILES", "GIF_FILE", "PlotProblem", "PlotWorkers", "InlinePlotter", "plotter",
           "SILENCE_LIMIT_S"]

log = logging.getLogger(__name__)

PNG_FILES = ("map.png", "inputs_joints.png", "tracking_error.png", "lateral_forces.png")
GIF_FILE = "train.gif"
_ORDER = (GIF_FILE, "inputs_joints.png", "tracking_error.png", "map.png", "lateral_forces.png")
"""The order in which the files are handed out: the slowest first, so that two processes end
at about the same time."""

SILENCE_LIMIT_S = 300.0
"""A plot process that sends nothing (no file started or finished) for this long [s] is stopped
and its file reported as failed (a file takes well under 10 s)."""

MAX_PROCESSES = 2


@dataclass(frozen=True)
class PlotProblem:
    """A file that was not written: its ``name`` and a one-line ``message`` saying why."""

    name: str
    message: str

    def __str__(self) -> str:
        return f"{self.name}: {self.message}"


def _peak_rss_mib() -> float:
    """This process's peak resident memory [MiB] (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


@dataclass(frozen=True)
class _Setting:
    """What every file of a run needs besides the results: drawn by :func:`_draw`."""

    n: int
    out_dir: Path
    world: object
    geometry: object
    footprints: dict


def _setting(sc, out_dir: Path) -> _Setting:
    from pushtrain.mission.runner import geometry_of, world_of

    t = sc.train
    return _Setting(sc.train.n, Path(out_dir), world_of(sc), geometry_of(sc),
                    {"robot": (t.robot_size.length, t.robot_size.width),
                     "trailer": (t.trailer_size.length, t.trailer_size.width)})


def _draw(name: str, data, setting: _Setting, path_xy, status) -> Path:
    from pushtrain.report.plots import plot_file

    return plot_file(name, data, setting.n, setting.out_dir, world=setting.world,
                     path_xy=path_xy, footprints=setting.footprints, geometry=setting.geometry,
                     status=status)


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _path_xy(path):
    return None if path is None else np.ascontiguousarray(path.poses[:, :2])


# ---------------------------------------------------------------------------------------------
# in the main process
# ---------------------------------------------------------------------------------------------
class InlinePlotter:
    """The files drawn one after the other in the main process, when :meth:`wait` asks for
    them (the same methods as :class:`PlotWorkers`)."""

    def __init__(self, setting: _Setting, files):
        self.setting, self.files = setting, tuple(files)
        self.finished: dict[str, PlotProblem | None] = {}
        self.data = self.path_xy = self.status = None

    def submit(self, result, path=None) -> None:
        self.data, self.status, self.path_xy = result.data, result.status, _path_xy(path)

    def wait(self, names) -> list[PlotProblem]:
        problems = []
        for name in names:
            if name not in self.finished:
                try:
                    _draw(name, self.data, self.setting, self.path_xy, self.status)
                    self.finished[name] = None
                except Exception as exc:
                    log.error("drawing %s failed", name, exc_info=True)
                    self.finished[name] = PlotProblem(name, _one_line(exc))
                gc.collect()
            if self.finished[name] is not None:
                problems.append(self.finished[name])
        return problems

    def close(self) -> None:
        self.data = None


# ---------------------------------------------------------------------------------------------
# in the plot processes
# ---------------------------------------------------------------------------------------------
def _warm_up() -> None:
    """Import the figures' modules and draw a small figure once (fonts, text layout)."""
    from pushtrain.report.common import new_figure

    fig = new_figure(2.0, 1.5, dpi=50)
    ax = fig.add_subplot()
    ax.plot([0.0, 1.0], [0.0, 1.0], label="warm-up")
    ax.legend()
    ax.set_title("warm-up")
    fig.canvas.draw()


def _read_exactly(fd: int, buffer: memoryview) -> None:
    got = 0
    while got < len(buffer):
        count = os.readv(fd, [buffer[got:]])
        if count == 0:
            raise EOFError("the main process closed the pipe")
        got += count


def _worker(conn, counter, setting: _Setting, inherited) -> None:
    """A plot process: import matplotlib, receive the results, draw files until none is left.

    Messages to the main process: ``("start", name)``, ``("done", name, wall [s], CPU [s])``,
    ``("failed", name, message, traceback)``, ``("fatal", message, traceback)`` (nothing more
    will come) and ``("end", peak memory [MiB])``.
    """
    for other in inherited:  # the other processes' pipes: only the main process may hold them
        other.close()
    # stopped by the main process: end through the ``finally`` blocks (no partial file is left)
    signal.signal(signal.SIGTERM, lambda signum, frame: sys.exit(128 + signum))
    gc.freeze()  # the inherited objects are never collected here: their pages stay shared
    try:
        try:
            _warm_up()
        except Exception as exc:  # e.g. matplotlib missing: say so and end
            conn.send(("fatal", f"cannot draw: {_one_line(exc)}", traceback.format_exc()))
            return
        header = conn.recv()
        data = np.empty(header["rows"], dtype=header["dtype"])
        _read_exactly(conn.fileno(), memoryview(data.view(np.uint8)).cast("B"))
        files = header["files"]
        while True:
            with counter.get_lock():
                k = counter.value
                counter.value = k + 1
            if k >= len(files):
                break
            name = files[k]
            conn.send(("start", name))
            wall, cpu = time.perf_counter(), time.process_time()
            try:
                _draw(name, data, setting, header["path_xy"], header["status"])
            except Exception as exc:
                conn.send(("failed", name, _one_line(exc), traceback.format_exc()))
            else:
                conn.send(("done", name, time.perf_counter() - wall, time.process_time() - cpu))
            gc.collect()
        conn.send(("end", _peak_rss_mib()))
    except (EOFError, OSError, KeyboardInterrupt):
        return  # the main process stopped us or went away: nothing to report to
    finally:
        conn.close()


# ---------------------------------------------------------------------------------------------
# the main process's side of the plot processes
# ---------------------------------------------------------------------------------------------
class _Process:
    def __init__(self, process, conn):
        self.process, self.conn = process, conn
        self.current: str | None = None  # the file it is drawing
        self.open = True  # its pipe may still bring messages
        self.peak_mib: float | None = None


class PlotWorkers:
    """Up to :data:`MAX_PROCESSES` forked plot processes drawing ``files`` of one run.

    Raises OSError or ValueError when processes cannot be forked (use :class:`InlinePlotter`).
    """

    def __init__(self, setting: _Setting, files, processes: int = MAX_PROCESSES):
        context = multiprocessing.get_context("fork")
        self.files = tuple(name for name in _ORDER if name in files)
        self.counter = context.Value("i", 0)
        self.finished: dict[str, PlotProblem | None] = {}
        self.taken: set[str] = set()
        self.last_word = "no answer"
        self.sender: threading.Thread | None = None
        self.procs: list[_Process] = []
        try:
            for k in range(max(1, min(processes, len(self.files)))):
                mine, theirs = context.Pipe(duplex=True)
                process = context.Process(
                    target=_worker, name=f"pushtrain-plot-{k + 1}", daemon=True,
                    args=(theirs, self.counter, setting, [p.conn for p in self.procs]))
                process.start()
                theirs.close()
                self.procs.append(_Process(process, mine))
        except BaseException:
            self.close()
            raise
        log.debug("started plot processes %s", [p.process.pid for p in self.procs])

    # -- sending the results -----------------------------------------------------------------
    def submit(self, result, path=None) -> None:
        """Send the results (and the planned ``path``, if any) to every plot process; they
        start drawing. Returns at once (a thread sends the table)."""
        data = np.ascontiguousarray(result.data)
        header = {"rows": len(data), "dtype": data.dtype, "files": self.files,
                  "path_xy": _path_xy(path), "status": result.status}
        conns = [p.conn for p in self.procs]
        self.sender = threading.Thread(target=_send, args=(conns, header, data),
                                       name="pushtrain-plot-sender", daemon=True)
        self.sender.start()

    # -- waiting for files -------------------------------------------------------------------
    def wait(self, names) -> list[PlotProblem]:
        """Wait until each of ``names`` is written or has failed; the problems, in the order
        of ``names``."""
        deadline = time.monotonic() + SILENCE_LIMIT_S
        while any(name not in self.finished for name in names):
            live = [p for p in self.procs if p.open]
            if not live:
                self._give_up(f"no plot process left ({self.last_word})")
                break
            ready = wait_for_any([p.conn for p in live], timeout=deadline - time.monotonic())
            if not ready:
                self._stop_all()
                self._give_up(f"no word from the plot processes in {SILENCE_LIMIT_S:g} s; "
                              "stopped them")
                break
            for p in live:
                if p.conn in ready:
                    self._receive(p)
            deadline = time.monotonic() + SILENCE_LIMIT_S
        return [self.finished[name] for name in names if self.finished[name] is not None]

    def _receive(self, p: _Process) -> None:
        try:
            message = p.conn.recv()
        except (EOFError, OSError):
            self._lost(p)
            return
        kind = message[0]
        if kind == "start":
            p.current = message[1]
            self.taken.add(p.current)
        elif kind == "done":
            name, wall, cpu = message[1:]
            log.info("%s drawn in %.2f s (CPU %.2f s) by plot process %d", name, wall, cpu,
                     p.process.pid)
            self.finished[name], p.current = None, None
        elif kind == "failed":
            name, text, trace = message[1:]
            log.error("drawing %s failed (plot process %d):\n%s", name, p.process.pid, trace)
            self.finished[name], p.current = PlotProblem(name, text), None
        elif kind == "fatal":
            text, trace = message[1:]
            log.error("plot process %d: %s\n%s", p.process.pid, text, trace)
            self.last_word = text
            self._lost(p, text)
        elif kind == "end":
            p.peak_mib = message[1]
            p.open = False

    def _lost(self, p: _Process, why: str | None = None) -> None:
        """``p``'s pipe closed or it gave up: its current file failed."""
        p.open = False
        if why is None:
            p.process.join(timeout=2.0)
            code = p.process.exitcode
            why = ("the plot process ended unexpectedly" if code is None else
                   f"the plot process was killed by signal {-code}" if code < 0 else
                   f"the plot process exited with code {code}")
            self.last_word = why
        if p.current is not None:
            self.finished[p.current] = PlotProblem(p.current, why)
            p.current = None

    def _give_up(self, why: str) -> None:
        for p in self.procs:
            if p.current is not None:
                self.finished[p.current] = PlotProblem(p.current, why)
                p.current = None
        for name in self.files:
            self.finished.setdefault(name, PlotProblem(name, why))

    def _stop_all(self) -> None:
        for p in self.procs:
            p.open = False
            if p.process.is_alive():
                p.process.terminate()

    # -- the end -----------------------------------------------------------------------------
    def close(self) -> None:
        """End the plot processes and log their peak memory: with every file finished, they
        end on their own; otherwise (the run failed) they are stopped."""
        if all(name in self.finished for name in self.files):
            for p in self.procs:  # their last word: the peak memory
                while p.open and p.conn.poll(5.0):
                    self._receive(p)
        else:
            for p in self.procs:
                if p.process.is_alive():
                    p.process.terminate()
        if self.sender is not None:
            self.sender.join(timeout=5.0)
        for p in self.procs:
            p.conn.close()
            p.process.join(timeout=5.0)
            if p.process.is_alive():
                p.process.kill()
                p.process.join(timeout=5.0)
        peaks = [f"{p.peak_mib:.1f}" for p in self.procs if p.peak_mib is not None]
        if peaks:
            log.info("peak resident memory [MiB]: main process %.1f, plot processes %s",
                     _peak_rss_mib(), ", ".join(peaks))


def _send(conns, header: dict, data: np.ndarray) -> None:
    """Send ``header`` and the raw bytes of ``data`` to each pipe (a process that died is
    skipped: the main process learns of it from its pipe)."""
    raw = memoryview(data.view(np.uint8)).cast("B")
    for conn in conns:
        try:
            conn.send(header)
            fd, sent = conn.fileno(), 0
            while sent < len(raw):
                sent += os.write(fd, raw[sent:])
        except (OSError, ValueError):
            continue


# ---------------------------------------------------------------------------------------------
@contextmanager
def plotter(sc, out_dir: Path, *, plots: bool = True, gif: bool = True,
            processes: int | None = None):
    """The plotter of a run into ``out_dir``: :class:`PlotWorkers` (``processes`` of them,
    default up to 2, one per core), or :class:`InlinePlotter` when processes cannot be forked
    or ``processes`` is 0; None without ``plots``. Closed at the end of the block."""
    if not plots:
        yield None
        return
    files = PNG_FILES + ((GIF_FILE,) if gif else ())
    setting = _setting(sc, out_dir)
    if processes is None:
        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 1
        processes = max(1, min(MAX_PROCESSES, cores))
    used = InlinePlotter(setting, files)
    if processes > 0:
        try:
            used = PlotWorkers(setting, files, processes)
        except (OSError, ValueError) as exc:
            log.warning("cannot start plot processes (%s): drawing in this one", exc)
    try:
        yield used
    finally:
        used.close()
