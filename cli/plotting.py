"""The pictures of a run: what the options ask for (:func:`pictures_options`,
:func:`chosen_files`), the page written in this process (:func:`draw_page`), and the PNG plots
and the GIF drawn in helper processes while the main process plans, co-simulates and saves.

By default a run writes ``report.html`` only: the main process writes it from the data with
the bundled renderer (about 0.1 CPU-s, no matplotlib), and no plot process is started. With
``--plots all`` (the four PNGs) or ``--gif``, :func:`plotter` forks a plot process as soon as the
scenario is read. While the main process checks the map, plans and co-simulates, that process
imports matplotlib (and the map's module, ``pushtrain.facility.free_space``, to unpickle the
map) and draws a small figure to ready the fonts. :meth:`PlotWorkers.submit` sends it the run's
setting (map, geometry, planned path, status, output folder) and the results table (its raw
bytes through the pipe, from a thread, so the main process saves the results meanwhile); it
then forks the second plot process, which so shares matplotlib and the results, and each takes
the next file nobody has taken yet (the GIF first, the largest job) until none is left.
:meth:`PlotWorkers.wait` waits for the named files and returns what went wrong with them.
Measured (``benchmarks/bench_plan_and_run.py``): the plot processes cost no more CPU than
drawing in the main process (matplotlib is imported once, before the fork) and on idle cores
they draw while the main process plans; so they stay for the matplotlib files.

What can go wrong becomes a :class:`PlotProblem` naming the file: the drawing raised (its
message; the traceback goes to ``run.log``), the process died (its pipe closed), or no word came
from the processes for :data:`SILENCE_LIMIT_S` (they are stopped). Files already written stay:
each is written atomically. A plot process told to stop (SIGTERM, from the main process when the
run fails or is interrupted, or from a scheduler signalling the whole group) removes the file it
is writing and ends at once. Where processes cannot be forked, :class:`InlinePlotter` draws the
same files in the main process, behind the same methods.

The main process never imports matplotlib on this route, so its peak memory is that of planning
and co-simulation; ``run.log`` gets the peak of every process.
"""

from __future__ import annotations

import gc
import logging
import os
import signal
import threading
import time
import traceback
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from pushtrain.files import remove_partials
from pushtrain.report import GIF_FILE, HTML_FILE  # names only: no matplotlib here

if TYPE_CHECKING:  # numpy and multiprocessing load when a run is drawn
    import numpy as np

__all__ = ["footprints_of", "keep_out_of", "PlotProblem", "PlotWorkers", "InlinePlotter", "plotter",
           "run_of", "one_line", "SILENCE_LIMIT_S"]

log = logging.getLogger(__name__)

_ORDER = (GIF_FILE, "inputs_joints.png", "tracking_error.png", "map.png", "lateral_forces.png",
          HTML_FILE)
"""The order in which the files are handed out: the slowest first, so that two processes end
at about the same time."""

SILENCE_LIMIT_S = 300.0
"""A plot process that says nothing (no file started or finished) for this long [s] is stopped
and its file reported as failed (one file takes well under 10 s)."""

MAX_PROCESSES = 2


@dataclass(frozen=True)
class PlotProblem:
    """A file that was not written: its ``name`` and a one-line ``message`` saying why."""

    name: str
    message: str

    def __str__(self) -> str:
        return f"{self.name}: {self.message}"


@dataclass(frozen=True)
class _Run:
    """What the files of one run need besides the results table (picklable)."""

    out_dir: Path
    n: int
    world: object  # pushtrain.facility.free_space.World or None
    geometry: object  # pushtrain.core.kinematics.ChainGeometry
    footprints: dict
    path_xy: np.ndarray | None  # the planned path of the last trailer [m]
    status: str | None
    summary: dict | None = None  # the run's summary (for report.html)
    phi_max_deg: float | None = None  # the joint limit drawn on the joint plots [deg]
    keep_out: float | None = None  # the clearance whose band report.html draws [m]


def run_of(sc, out_dir, result, path) -> _Run:
    """What the files of a run of ``sc`` into ``out_dir`` need besides its table."""
    import numpy as np

    from pushtrain.mission.runner import geometry_of, world_of

    t = sc.train
    return _Run(Path(out_dir), t.n, world_of(sc), geometry_of(sc), footprints_of(sc),
                None if path is None else np.ascontiguousarray(path.poses[:, :2]),
                getattr(result, "status", None), getattr(result, "summary", None),
                t.phi_max_deg, keep_out_of(sc))


def footprints_of(sc) -> dict:
    """The body rectangles (length, width) [m] of ``sc``'s train, as the pictures take them."""
    t = sc.train
    return {"robot": (t.robot_size.length, t.robot_size.width),
            "trailer": (t.trailer_size.length, t.trailer_size.width)}


def keep_out_of(sc) -> float | None:
    """The clearance [m] the planner kept from the walls (the largest, if per body)."""
    clearance = getattr(getattr(sc, "planner", None), "clearance", None)
    if sc.map is None or clearance is None:
        return None
    return float(max(clearance)) if isinstance(clearance, list) else float(clearance)


def _draw(name: str, data, run: _Run) -> Path:
    from pushtrain.report.plots import plot_file

    return plot_file(name, data, run.n, run.out_dir, world=run.world, path_xy=run.path_xy,
                     footprints=run.footprints, geometry=run.geometry, status=run.status,
                     summary=run.summary, phi_max_deg=run.phi_max_deg, keep_out=run.keep_out)


def one_line(exc: BaseException) -> str:
    """``exc`` as one line: its type and its message with the whitespace folded."""
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _peak_rss_mib() -> float:
    """This process's peak resident memory [MiB] (Linux reports KiB; nan where unknown)."""
    try:
        import resource
    except ImportError:  # Windows
        return float("nan")
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


# ---------------------------------------------------------------------------------------------
# in the main process
# ---------------------------------------------------------------------------------------------
class InlinePlotter:
    """The files drawn one after the other in the main process, when :meth:`wait` asks for
    them (the methods of :class:`PlotWorkers`)."""

    def __init__(self, sc, files):
        self.sc, self.files = sc, tuple(files)
        self.finished: dict[str, PlotProblem | None] = {}
        self.data = self.run = None

    def submit(self, out_dir, result, path=None) -> None:
        self.data, self.run = result.data, run_of(self.sc, out_dir, result, path)

    def wait(self, names) -> list[PlotProblem]:
        problems = []
        for name in names:
            if name not in self.finished:
                wall, cpu = time.perf_counter(), time.process_time()
                try:
                    _draw(name, self.data, self.run)
                    self.finished[name] = None
                    log.info("%s drawn in %.3f s (CPU %.3f s) by the main process", name,
                             time.perf_counter() - wall, time.process_time() - cpu)
                except Exception as exc:  # the traceback goes to run.log only
                    log.debug("drawing %s failed", name, exc_info=True)
                    self.finished[name] = PlotProblem(name, one_line(exc))
                gc.collect()
            if self.finished[name] is not None:
                problems.append(self.finished[name])
        return problems

    def close(self) -> None:
        self.data = None


# ---------------------------------------------------------------------------------------------
# in the plot processes
# ---------------------------------------------------------------------------------------------
def _warm_up(with_map: bool) -> None:
    """Import the figures' modules (and the map's, to unpickle it at once) and draw a small
    figure (fonts, text layout)."""
    from pushtrain.report.common import new_figure

    if with_map:
        import pushtrain.facility.free_space  # noqa: F401

    fig = new_figure(2.0, 1.5, dpi=50)
    ax = fig.add_subplot()
    ax.plot([0.0, 1.0], [0.0, 1.0], label="warm-up")
    ax.legend()
    ax.set_title("warm-up")
    fig.canvas.draw()


def _first_process(conns, counter, with_map: bool, inherited) -> None:
    """The first plot process: warm up, receive the run and its results, fork the second plot
    process (which so shares matplotlib and the results), then draw; wait for the second.
    ``conns`` are the plot processes' pipes, its own first; ``inherited`` are the main
    process's ends of them, closed here."""
    for other in inherited:
        other.close()
    # Ctrl-C is the main process's to handle; it stops us with SIGTERM (as may a scheduler
    # that signals the whole process group), which ends us at once (_end_on_sigterm)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _end_on_sigterm)
    gc.freeze()  # the inherited objects are never collected here: their pages stay shared
    try:
        _warm_up(with_map)
        conns[0].send(("ready", os.getpid()))
        header = conns[0].recv()
        import numpy as np

        data = np.empty(header["rows"], dtype=header["dtype"])
        _read_exactly(conns[0].fileno(), memoryview(data.view(np.uint8)).cast("B"))
    except (EOFError, OSError):
        return  # the main process stopped us or went away: nothing to report to
    except Exception as exc:  # e.g. matplotlib missing: say so (not as a traceback) and end
        for conn in conns:
            _last_word(conn, ("fatal", f"cannot draw: {one_line(exc)}", traceback.format_exc()))
        return
    second = 0
    if len(conns) > 1:
        gc.freeze()
        try:
            second = os.fork()
        except OSError as exc:
            _last_word(conns[1], ("fatal", f"cannot fork: {exc}", traceback.format_exc()))
        else:
            if second == 0:  # the second plot process
                try:
                    conns[0].close()
                    _draw_files(conns[1], counter, header, data, hello=True)
                finally:
                    os._exit(0)
            global _SECOND
            _SECOND = second
            conns[1].close()
    try:
        _draw_files(conns[0], counter, header, data)
    finally:
        if second > 0:
            os.waitpid(second, 0)


_SECOND = 0
"""In the first plot process: the pid of the second (its child), once forked."""


def _end_on_sigterm(signum, frame) -> None:
    """A plot process's SIGTERM: remove the file it is writing, stop and reap the second plot
    process (from the first), and end at once with ``os._exit`` (128 + SIGTERM). Not an
    exception: raised inside matplotlib's or Pillow's finalizers, SystemExit was printed as
    "Exception ignored ..." and did not end the process."""
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    remove_partials()
    if _SECOND > 0:
        try:
            os.kill(_SECOND, signal.SIGTERM)
            os.waitpid(_SECOND, 0)
        except OSError:
            pass
    os._exit(128 + signum)


def _last_word(conn, message) -> None:
    try:
        conn.send(message)
    except OSError:
        pass
    conn.close()


def _read_exactly(fd: int, buffer: memoryview) -> None:
    got = 0
    while got < len(buffer):
        count = os.readv(fd, [buffer[got:]])
        if count == 0:
            raise EOFError("the main process closed the pipe")
        got += count


def _draw_files(conn, counter, header: dict, data: np.ndarray, *, hello: bool = False) -> None:
    """Draw files of ``header["files"]`` until none is left (``counter`` says which is next).

    Messages to the main process: ``("ready", pid)`` (with ``hello``), ``("start", name)``,
    ``("done", name, wall [s], CPU [s])``, ``("failed", name, message, traceback)`` and, at the
    end, ``("end", peak memory [MiB])``.
    """
    run, files = header["run"], header["files"]
    try:
        if hello:
            conn.send(("ready", os.getpid()))
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
                _draw(name, data, run)
            except Exception as exc:
                conn.send(("failed", name, one_line(exc), traceback.format_exc()))
            else:
                conn.send(("done", name, time.perf_counter() - wall, time.process_time() - cpu))
            gc.collect()
        conn.send(("end", _peak_rss_mib()))
    except (EOFError, OSError):
        return  # the main process stopped us or went away: nothing to report to
    except Exception as exc:  # a bug here: say so (not as a traceback on stderr)
        _last_word(conn, ("fatal", f"plot process failed: {one_line(exc)}",
                          traceback.format_exc()))
    finally:
        conn.close()


# ---------------------------------------------------------------------------------------------
# the main process's side of the plot processes
# ---------------------------------------------------------------------------------------------
class _Process:
    """The main process's view of one plot process: its pipe, its pid (the first one is a
    child of the main process, the second a child of the first), the file it draws."""

    def __init__(self, conn, process=None):
        self.conn, self.process = conn, process
        self.pid = None if process is None else process.pid
        self.current: str | None = None  # the file it is drawing
        self.open = True  # its pipe may still bring messages
        self.peak_mib: float | None = None

    def stop(self) -> None:
        """Ask it to end (SIGTERM: its ``finally`` blocks run)."""
        if self.pid is not None:
            try:
                os.kill(self.pid, signal.SIGTERM)
            except OSError:
                pass

    def exit_text(self) -> str:
        code = None if self.process is None else self.process.exitcode
        if code is None:
            return "the plot process ended unexpectedly"
        if code < 0:
            return f"the plot process was killed by signal {-code}"
        return f"the plot process exited with code {code}"


class PlotWorkers:
    """Up to :data:`MAX_PROCESSES` plot processes drawing ``files`` of one run of ``sc``.

    Raises OSError or ValueError when processes cannot be forked (use :class:`InlinePlotter`).
    """

    def __init__(self, sc, files, processes: int = MAX_PROCESSES):
        import multiprocessing

        context = multiprocessing.get_context("fork")
        self.sc = sc
        self.files = tuple(name for name in _ORDER if name in files)
        self.counter = context.Value("i", 0)
        self.finished: dict[str, PlotProblem | None] = {}
        self.last_word = "no answer"
        self.sender: threading.Thread | None = None
        self.out_dir: Path | None = None
        self.closed = False
        pipes = [context.Pipe(duplex=True)
                 for _ in range(max(1, min(processes, MAX_PROCESSES, len(self.files))))]
        mine = [pipe[0] for pipe in pipes]
        theirs = [pipe[1] for pipe in pipes]
        try:
            first = context.Process(target=_first_process, name="pushtrain-plot", daemon=True,
                                    args=(theirs, self.counter, sc.map is not None, mine))
            first.start()
        except BaseException:
            for conn in mine + theirs:
                conn.close()
            raise
        for conn in theirs:
            conn.close()
        self.procs = [_Process(mine[0], first)] + [_Process(conn) for conn in mine[1:]]
        log.debug("started plot process %d (it forks %d more)", first.pid, len(mine) - 1)

    # -- sending the run ---------------------------------------------------------------------
    def submit(self, out_dir, result, path=None) -> None:
        """Send the run (into ``out_dir``, along the planned ``path``, if any) and its
        ``result`` to the first plot process, which forks the second; they start drawing.
        Returns at once (a thread sends)."""
        import numpy as np

        data = np.ascontiguousarray(result.data)
        self.out_dir = Path(out_dir)
        header = {"run": run_of(self.sc, out_dir, result, path), "files": self.files,
                  "rows": len(data), "dtype": data.dtype}
        self.sender = threading.Thread(target=_send, args=([self.procs[0].conn], header, data),
                                       name="pushtrain-plot-sender", daemon=True)
        self.sender.start()

    # -- waiting for files -------------------------------------------------------------------
    def wait(self, names) -> list[PlotProblem]:
        """Wait until each of ``names`` is written or has failed; the problems, in the order
        of ``names``."""
        from multiprocessing.connection import wait

        while any(name not in self.finished for name in names):
            live = [p for p in self.procs if p.open]
            if not live:
                self._give_up(f"no plot process left ({self.last_word})")
                break
            ready = wait([p.conn for p in live], timeout=SILENCE_LIMIT_S)
            if not ready:
                self._stop_all()
                self._give_up(f"no word from the plot processes in {SILENCE_LIMIT_S:g} s; "
                              "stopped them")
                break
            for p in live:
                if p.conn in ready:
                    self._receive(p)
        return [self.finished[name] for name in names if self.finished[name] is not None]

    def _receive(self, p: _Process) -> None:
        try:
            message = p.conn.recv()
        except (EOFError, OSError):
            self._lost(p)
            return
        kind = message[0]
        if kind == "ready":
            p.pid = message[1]
        elif kind == "start":
            p.current = message[1]
        elif kind == "done":
            name, wall, cpu = message[1:]
            log.info("%s drawn in %.3f s (CPU %.3f s) by plot process %s", name, wall, cpu,
                     p.pid)
            self.finished[name], p.current = None, None
        elif kind == "failed":
            name, text, trace = message[1:]
            log.debug("drawing %s failed (plot process %s):\n%s", name, p.pid, trace)
            self.finished[name], p.current = PlotProblem(name, text), None
        elif kind == "fatal":
            text, trace = message[1:]
            log.debug("plot process %s: %s\n%s", p.pid, text, trace)
            self.last_word = text
            self._lost(p, text)
        elif kind == "end":
            p.peak_mib = message[1]
            p.open = False

    def _lost(self, p: _Process, why: str | None = None) -> None:
        """``p``'s pipe closed or it gave up: its current file failed."""
        p.open = False
        if why is None:
            if p.process is not None:
                p.process.join(timeout=2.0)
            why = self.last_word = p.exit_text()
        if p.current is not None:
            self.finished[p.current] = PlotProblem(p.current, why)
            p.current = None

    def _give_up(self, why: str) -> None:
        for name in self.files:
            self.finished.setdefault(name, PlotProblem(name, why))

    def _stop_all(self) -> None:
        for p in self.procs:
            p.open = False
            p.stop()

    # -- the end -----------------------------------------------------------------------------
    def close(self) -> None:
        """End the plot processes and log their peak memory: with every file finished, they
        end on their own; otherwise (the run failed or was interrupted) they are stopped.
        Closing again does nothing."""
        if self.closed:
            return
        self.closed = True
        done = all(name in self.finished for name in self.files)
        for p in self.procs:  # their last words: pids, files, the peak memory at the end
            while p.open and p.conn.poll(5.0 if done else 0.0):
                self._receive(p)
        if not done:
            for p in self.procs:
                p.stop()
        if self.sender is not None:
            self.sender.join(timeout=5.0)
        for p in self.procs:
            p.conn.close()
        first = self.procs[0].process  # it waits for the second before it ends
        first.join(timeout=10.0)
        if first.is_alive():
            for p in self.procs[::-1]:
                if p.pid is not None:
                    try:
                        os.kill(p.pid, signal.SIGKILL)
                    except OSError:
                        pass
            first.join(timeout=5.0)
        if not done and self.out_dir is not None:  # the files of a process killed mid-write
            for p in self.procs:
                if p.pid is not None:
                    remove_partials(self.out_dir, p.pid)
        peaks = [f"{p.peak_mib:.1f}" for p in self.procs if p.peak_mib is not None]
        if peaks:
            log.info("peak resident memory [MiB]: main process %.1f, plot processes %s",
                     _peak_rss_mib(), ", ".join(peaks))


def _send(conns, header: dict, data: np.ndarray) -> None:
    """Send ``header`` and the raw bytes of ``data`` through each pipe (a process that died is
    skipped: the main process learns of it from its pipe)."""
    import numpy as np

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
def plotter(sc, files, *, processes: int | None = None):
    """What draws the matplotlib ``files`` (PNGs, GIF) of a run of ``sc``, closed at the end of
    the block: :class:`PlotWorkers` (``processes`` of them; default 2, or 1 on one core), or
    :class:`InlinePlotter` when processes cannot be forked or ``processes`` is 0; None when no
    such file is asked for (report.html is drawn by :func:`draw_page`). Start it early: the
    plot processes get ready while the main one works."""
    files = tuple(name for name in files if name != HTML_FILE)
    if not files:
        yield None
        return
    if processes is None:
        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 1
        processes = max(1, min(MAX_PROCESSES, cores))
    used = InlinePlotter(sc, files)
    import multiprocessing

    if processes > 0 and "fork" not in multiprocessing.get_all_start_methods():
        log.info("no fork on this platform: the plots are drawn in this process")
    elif processes > 0:
        try:
            used = PlotWorkers(sc, files, processes)
        except (OSError, ValueError) as exc:
            log.warning("cannot start plot processes (%s): drawing in this one", exc)
    try:
        yield used
    finally:
        used.close()
