"""Progress of a command's phases (plan, co-simulate, save, plots) on stderr.

Each phase prints one line when it starts, stamped with the seconds since the command began,
so a piped or logged run shows what it is doing; the last line gives each phase's duration:

    [  0.3 s] planning the path (lattice) ...
    [  0.4 s] co-simulating ...
    [  0.5 s] saving the results ...
    [  0.6 s] writing report.html ...
    [  0.7 s] done: plan 0.12 s, co-simulate 0.10 s, save 0.14 s, page 0.10 s

(with ``--plots all`` or ``--gif`` a last phase waits for the plot processes: ``plotting
map.png, ...``). ``run.log`` also gets each phase's CPU time in this process.
"""

from __future__ import annotations

import logging
import sys
import threading
import time
from contextlib import contextmanager

import click

__all__ = ["Phases"]

log = logging.getLogger(__name__)


class Phases:
    """The phases of one command: :meth:`phase` times one and announces it, :meth:`done`
    prints the durations. ``stream`` defaults to stderr; ``clock`` returns seconds."""

    def __init__(self, stream=None, clock=time.perf_counter):
        self.stream, self.clock = stream, clock
        self.start = clock()
        self.times: dict[str, float] = {}
        self.cpu: dict[str, float] = {}  # this process's CPU time per phase [s], for run.log

    def _line(self, text: str) -> None:
        click.echo(f"[{self.clock() - self.start:5.1f} s] {text}",
                   file=self.stream or sys.stderr)

    @contextmanager
    def phase(self, name: str, what: str, tick_s: float | None = None):
        """Announce ``what`` (e.g. "co-simulating") and time the block as phase ``name``; with
        ``tick_s``, a line every ``tick_s`` seconds says the phase is still going and since
        when (a long plan is not silent)."""
        self._line(f"{what} ...")
        log.info("%s ...", what)
        t0, cpu0 = self.clock(), time.process_time()
        stop = threading.Event()
        ticker = None
        if tick_s:
            def tick():
                while not stop.wait(tick_s):
                    self._line(f"... still {what}, {self.clock() - t0:.0f} s so far")

            ticker = threading.Thread(target=tick, name="pushtrain-progress", daemon=True)
            ticker.start()
        try:
            yield
        finally:
            stop.set()
            if ticker is not None:
                ticker.join()
            self.times[name] = self.times.get(name, 0.0) + self.clock() - t0
            self.cpu[name] = self.cpu.get(name, 0.0) + time.process_time() - cpu0

    def summary(self) -> str:
        """``plan 0.58 s, co-simulate 2.02 s, ...`` (the phases timed so far, in order)."""
        return ", ".join(f"{name} {seconds:.2f} s" for name, seconds in self.times.items())

    def done(self) -> None:
        """Print the duration of every phase."""
        if self.times:
            self._line(f"done: {self.summary()}")
            log.info("phase times: %s", self.summary())
            log.info("phase CPU times (this process): %s", ", ".join(
                f"{name} {seconds:.3f} s" for name, seconds in self.cpu.items()))
