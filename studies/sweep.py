"""Robustness sweeps: many co-simulations over a grid or a Monte Carlo sample of parameters.

:func:`sweep` is the whole job: read a base scenario and a sweep spec
(:mod:`~pushtrain.studies.sweep_spec`), expand and validate every run, plan and build FMUs in the
client (:mod:`~pushtrain.studies.sweep_runs`), execute the runs with :func:`run_sweep` and write
the report (:mod:`~pushtrain.studies.sweep_report`).

:func:`run_sweep` executes runs on a Dask ``distributed`` client or serially in this process
(the same task function either way, so both give identical numbers; see
:mod:`~pushtrain.studies.sweep_task`). A task that raises or ends in a failure status is a
recorded failure row, not a lost sweep. Rows are written as CSV chunks and combined into
``results.csv``; a sweep re-run into the same folder resumes (:mod:`~pushtrain.studies.
sweep_results`). This is the one module that imports dask/distributed.

Python API::

    from pushtrain.studies.sweep import sweep
    outcome = sweep("examples/joint_bias_5deg.toml", "examples/sweeps/joint_bias.toml",
                    "runs/bias_sweep", workers=2)        # or serial=True, client=..., scheduler=...
    outcome.rows, outcome.failures, outcome.files

Units: lengths [m], times [s], angles in degrees only in ``*_deg`` columns.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import pickle
import signal
import threading
import time
from pathlib import Path
from typing import Callable, Sequence

from pushtrain.errors import SweepError
from pushtrain.mission.scenario import Scenario, load_scenario

from .sweep_results import (
    ChunkWriter,
    SweepOutcome,
    check_manifest,
    check_out_folder,
    columns_of,
    combine,
    existing_rows,
    finish_row,
)
from .sweep_runs import SweepRun, bias_swept, prepare_runs
from .sweep_spec import (
    DEFAULT_MAX_TOTAL,
    DEFAULT_METRICS,
    STATUS_LOST,
    SweepSpec,
    check_size,
    load_sweep_spec,
)
from .sweep_task import execute, execute_batch, failure_row, run_task

__all__ = ["scheduler_problem", "dask_client", "completed", "run_sweep", "local_client", "sweep"]

log = logging.getLogger(__name__)


# ------------------------------------------------------------------------------------ execution
def run_sweep(
    runs: Sequence[SweepRun],
    task_fn: Callable,
    out_dir,
    *,
    metrics: Sequence[str] = DEFAULT_METRICS,
    steady_window: float = 10.0,
    chunk_size: int = 8,
    client=None,
    serial: bool = False,
    shared: dict | None = None,
    max_runs: int | None = None,
    manifest: dict | None = None,
    on_row: Callable[[dict, int, int], None] | None = None,
) -> SweepOutcome:
    """Execute ``runs`` (those without rows in ``out_dir`` yet) and combine every row.

    Parameters
    ----------
    runs : sequence of SweepRun
        From :func:`expand_runs`, with ``payload`` (and maybe ``extras``/``failure``) filled in.
    task_fn : callable
        ``task_fn(payload, shared) -> Result``; a module-level function (pickled by reference
        for the workers). It may raise: the run is then a failure row with status ``error``.
    out_dir : path-like
        Output folder: ``chunks/chunk-NNNNNN.csv``, ``results.csv`` and ``sweep.json``.
    metrics : sequence of str
        Metric columns to keep (see :data:`METRICS`).
    steady_window : float
        Averaging window of ``steady_lat_m`` [s].
    chunk_size : int
        Rows per chunk file.
    client : distributed.Client, optional
        Run on this Dask client (required unless ``serial``).
    serial : bool
        Run the same tasks one after another in this process.
    shared : dict, optional
        Data every task needs (e.g. FMU bytes): scattered once to all workers (broadcast) and
        passed to ``task_fn`` as its second argument.
    max_runs : int, optional
        Execute at most this many new runs, then stop (the sweep can be resumed later).
    manifest : dict, optional
        A description of the sweep (spec, base scenario); its fingerprint is stored in
        ``sweep.json`` and must match when resuming into the same folder.
    on_row : callable, optional
        ``on_row(row, done, total)`` after each new row (progress display).

    Returns
    -------
    SweepOutcome

    Raises
    ------
    SweepError
        ``out_dir`` holds a different sweep; neither a client nor ``serial`` given.
    """
    if client is None and not serial:
        raise SweepError("run_sweep", [("client", None, "a distributed.Client, or serial=True")])
    out = Path(out_dir)
    check_out_folder(out)
    chunk_dir = out / "chunks"
    chunk_dir.mkdir(parents=True, exist_ok=True)
    check_manifest(out, manifest)
    param_paths = list(dict.fromkeys(p for run in runs for p in run.params))
    extras = list(dict.fromkeys(k for run in runs for k in run.extras))
    columns = columns_of(param_paths, list(metrics), extras)
    existing = existing_rows(chunk_dir)
    todo = [run for run in runs if run.key not in existing]
    skipped = len(runs) - len(todo)
    if max_runs is not None:
        todo = todo[:max(0, int(max_runs))]
    log.info("sweep: %d runs, %d already done, %d to run now", len(runs), skipped, len(todo))

    writer = ChunkWriter(chunk_dir, columns, chunk_size)
    new_rows: dict[str, dict] = {}
    interrupted = False

    def collect(raw: dict, run: SweepRun) -> None:
        row = finish_row(raw, run)
        new_rows[run.key] = row
        writer.add(row)
        if on_row is not None:
            on_row(row, len(new_rows), len(todo))

    try:
        _execute_all(todo, task_fn, client, serial, shared or {}, steady_window, collect)
    except KeyboardInterrupt:
        interrupted = True
        log.info("sweep interrupted: %d new rows kept; run again to resume", len(new_rows))
        raise
    finally:
        writer.flush()
        outcome = combine(out, runs, existing, new_rows, columns, skipped)
        outcome.interrupted = interrupted
    return outcome


def _execute_all(todo, task_fn, client, serial, shared, steady_window, collect) -> None:
    """Rows for the runs known to fail first, then every other run, serially or on Dask."""
    for run in (run for run in todo if run.failure is not None):
        collect(failure_row(*run.failure) | {"task_time_s": 0.0}, run)
    pending = [run for run in todo if run.failure is None]
    if serial:
        for run in pending:
            collect(execute(task_fn, run.index, run.key, run.payload, shared, steady_window), run)
    else:
        _run_distributed(client, pending, task_fn, shared, steady_window, collect)


def _run_distributed(client, runs, task_fn, shared, steady_window, collect) -> None:
    from distributed import as_completed

    if not runs:
        return
    shared_f = {name: client.scatter(value, broadcast=True, hash=False)
                for name, value in shared.items()}
    workers = max(1, len(client.scheduler_info().get("workers", {})))
    by_key = {}
    futures = []
    for batch in batches(runs, workers):
        items = pickle.dumps([(run.index, run.key, run.payload) for run in batch],
                             protocol=pickle.HIGHEST_PROTOCOL)
        fut = client.submit(execute_batch, task_fn, items, shared_f, steady_window,
                            key=f"pushtrain-runs-{batch[0].key}-{os.getpid()}-{id(runs)}",
                            pure=False)
        by_key[fut.key] = batch
        futures.append(fut)
    try:
        for fut in as_completed(futures):
            batch = by_key[fut.key]
            try:
                raws = fut.result()
            except Exception as exc:  # the worker died or the task was cancelled
                raws = [failure_row(STATUS_LOST, f"{type(exc).__name__}: {exc}")
                        | {"task_time_s": math.nan} for _ in batch]
            for raw, run in zip(raws, batch, strict=True):
                collect(raw, run)
            fut.release()
    finally:
        client.cancel([f for f in futures if not f.done()])


TASKS_PER_WORKER = 4
"""Dask tasks per worker a sweep is cut into (at least): enough for the last ones to even out
the workers' loads, few enough that a task's own cost (about 3 ms of scheduling and messages)
stays small beside its runs (a 60 s run takes about 20 ms)."""
MAX_BATCH = 64
"""Most runs in one Dask task (a lost worker loses at most this many; rows arrive per task)."""


def batches(runs: list, workers: int) -> list[list]:
    """``runs`` cut in order into at least ``TASKS_PER_WORKER x workers`` tasks of at most
    :data:`MAX_BATCH` runs (one run per task for small sweeps)."""
    size = max(1, min(MAX_BATCH, len(runs) // (TASKS_PER_WORKER * max(1, workers))))
    return [runs[i:i + size] for i in range(0, len(runs), size)]


# ------------------------------------------------------------------------------------ the job
def _quiet_worker() -> None:
    """On each worker of our own LocalCluster: no pushtrain log output, and SIGINT ignored.

    Ctrl-C in a terminal reaches the whole process group; the client alone handles it (it
    closes the cluster), so the workers do not each print a KeyboardInterrupt traceback.
    """
    logging.getLogger("pushtrain").addHandler(logging.NullHandler())
    logging.getLogger("pushtrain").propagate = False
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def _quiet_worker_plugin():
    """A WorkerPlugin running :func:`_quiet_worker` on every worker, also on restarted ones."""
    from distributed import WorkerPlugin

    class QuietWorker(WorkerPlugin):
        name = "pushtrain-quiet-worker"

        def setup(self, worker):
            _quiet_worker()

    return QuietWorker()


LOCAL_WORKER_CONFIG = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "2s",
}
"""Dask settings of the workers of our own LocalCluster. A worker runs the co-simulation in a
thread; Dask's statistical profiler samples that thread's stack every 10 ms from another thread,
and the event loop wakes every 20 ms to time itself and every 0.5 s to poll system counters,
each time taking the interpreter lock from the co-simulation. With the profiler off a worker
spent 1.10 instead of 1.42 times the serial CPU time per run, with the slower ticks 1.05
(benchmarks/bench_sweep.py prints this ratio)."""


@contextlib.contextmanager
def local_client(n_workers: int):
    """A client of a LocalCluster of ``n_workers`` single-threaded worker processes with
    :data:`LOCAL_WORKER_CONFIG`, whose workers ignore SIGINT (see :func:`_quiet_worker`).

    The workers are started with SIGINT ignored in this process, which they inherit; a Ctrl-C
    during those seconds of start-up is therefore lost. The plugin covers restarted workers.
    """
    import dask
    from distributed import Client, LocalCluster

    main = threading.current_thread() is threading.main_thread()
    previous = signal.getsignal(signal.SIGINT)
    if main:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with dask.config.set(LOCAL_WORKER_CONFIG):  # the nannies pass it on to their workers
            cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                                   dashboard_address=":0", silence_logs=logging.ERROR)
    finally:
        if main:
            signal.signal(signal.SIGINT, signal.default_int_handler if previous is None
                          else previous)
    with cluster, Client(cluster) as client:
        client.register_plugin(_quiet_worker_plugin())
        yield client


SCHEDULER_TIMEOUT_S = 10.0
"""Seconds a scheduler's host may take to accept a connection before it is refused."""
SCHEDULER_GREETING_S = 3.0
"""Seconds a program that accepted the connection has to greet as a Dask comm does (its first
message, the handshake, is sent at once) and then to answer who it is."""
GREETING_MAX_BYTES = 1 << 16
"""The largest first message taken for a Dask handshake (a real one is about 100 bytes)."""


def scheduler_problem(address: str) -> str | None:
    """What is wrong with a Dask scheduler ``address`` (its form, nothing accepting connections
    there, or something that is not a Dask scheduler answering), or None. Bounded in time: at
    most :data:`SCHEDULER_TIMEOUT_S` to connect, then :data:`SCHEDULER_GREETING_S` for each of
    the greeting and the identity (Dask's own errors were tracebacks: a ValueError for ``foo``,
    an OSError after 30 s for a port nobody listens on, a silent hang on a port where another
    program listens and a huge allocation for one that answers garbage)."""
    import socket

    from distributed.comm.addressing import parse_address, parse_host_port
    from distributed.comm.registry import backends

    allowed = "the address of a running Dask scheduler, e.g. tcp://host:8786"
    try:
        protocol, location = parse_address(address)
        if protocol not in backends:
            raise ValueError(f"unknown protocol {protocol!r} (known: {', '.join(backends)})")
        if protocol not in ("tcp", "tls"):
            return None
        host, port = parse_host_port(location)
        if not host or not 0 < port < 65536:
            raise ValueError("a host name and a port 1..65535 are needed")
    except ValueError as exc:
        return f"{allowed}; {exc}"
    try:
        sock = socket.create_connection((host, port), timeout=SCHEDULER_TIMEOUT_S)
    except OSError as exc:
        return (f"{allowed}; nothing accepts connections at {host}:{port} "
                f"({exc.strerror or exc}): start the scheduler there (dask scheduler) or leave "
                "--scheduler out to run on a local cluster")
    if protocol == "tls":
        sock.close()
        return None
    with sock:
        found = _greeting_problem(sock)
    if found is None:
        found = _identity_problem(address)
    if found is None:
        return None
    return (f"{allowed}; a program accepts connections at {host}:{port} but {found}: give the "
            "scheduler's address (dask scheduler prints it) or leave --scheduler out to run on a "
            "local cluster")


def _greeting_problem(sock) -> str | None:
    """None if ``sock`` (just connected) receives a Dask comm's handshake message within
    :data:`SCHEDULER_GREETING_S`; else what it received instead."""
    import socket
    import struct

    from distributed.protocol import loads
    from distributed.protocol.utils import unpack_frames

    deadline = time.monotonic() + SCHEDULER_GREETING_S

    def receive(n: int) -> bytes:
        data = b""
        while len(data) < n:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError
            sock.settimeout(left)
            chunk = sock.recv(n - len(data))
            if not chunk:
                raise EOFError(data)
            data += chunk
        return data

    try:
        (size,) = struct.unpack("Q", receive(8))
        if not 0 < size <= GREETING_MAX_BYTES:
            return (f"its first message is not a Dask comm's (a length of {size} bytes; a Dask "
                    "handshake has about 100)")
        frames, _ = unpack_frames(receive(size), partial=True)
        message = loads(frames)
    except (TimeoutError, socket.timeout):
        return (f"said nothing in {SCHEDULER_GREETING_S:g} s (a Dask scheduler greets at once "
                "on a new connection)")
    except EOFError as exc:
        got = exc.args[0] if exc.args else b""
        return ("closed the connection" + (f" after sending {got[:40]!r}" if got else
                                           " without sending anything"))
    except OSError as exc:
        return f"the connection failed: {exc.strerror or exc}"
    except Exception as exc:  # any decoding error: not Dask's protocol
        return (f"its first message is not a Dask comm's (it does not decode: "
                f"{type(exc).__name__}: {str(exc)[:80]})")
    if not isinstance(message, dict) or "compression" not in message:
        return "its first message is not a Dask handshake"
    return None


def _identity_problem(address: str) -> str | None:
    """None if the Dask comm at ``address`` says it is a scheduler within
    :data:`SCHEDULER_GREETING_S`; else what it is."""
    import asyncio

    from distributed.comm import connect

    async def identity():
        comm = await connect(address, timeout=SCHEDULER_GREETING_S)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    try:
        answer = asyncio.run(asyncio.wait_for(identity(), 2 * SCHEDULER_GREETING_S))
    except (asyncio.TimeoutError, TimeoutError):
        return f"did not say who it is within {2 * SCHEDULER_GREETING_S:g} s"
    except Exception as exc:
        return f"the Dask identity request failed ({type(exc).__name__}: {exc})"
    kind = answer.get("type") if isinstance(answer, dict) else None
    if kind != "Scheduler":
        return f"it is a Dask {kind or 'program'}, not a scheduler"
    return None


@contextlib.contextmanager
def dask_client(scheduler: str | None = None, workers: int | None = None):
    """A Dask client: of the scheduler at ``scheduler``, else of our own LocalCluster
    (:func:`local_client`) of ``workers`` processes (default: the cores this process may
    use). For the studies beside the sweep (the atlas), which so share its Dask settings."""
    if scheduler:
        from distributed import Client

        with Client(scheduler) as client:
            yield client
        return
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    with local_client(workers or max(1, cores or 1)) as client:
        yield client


def completed(futures):
    """The ``futures`` as they complete (distributed's ``as_completed``)."""
    from distributed import as_completed

    yield from as_completed(futures)


def _run_on_dask(runs, out_dir, kwargs, *, client, scheduler, workers) -> SweepOutcome:
    """:func:`run_sweep` on ``client``, on a client of ``scheduler``, or on a LocalCluster."""
    from distributed import Client

    if client is not None:
        return run_sweep(runs, run_task, out_dir, client=client, **kwargs)
    if scheduler is not None:
        with Client(scheduler) as own:
            return run_sweep(runs, run_task, out_dir, client=own, **kwargs)
    with local_client(workers or os.cpu_count() or 1) as own:
        return run_sweep(runs, run_task, out_dir, client=own, **kwargs)


def sweep(scenario, spec, out_dir, *, serial: bool = False, client=None,
          scheduler: str | None = None, workers: int | None = None, max_runs: int | None = None,
          fmus: dict | None = None, ship_fmu: bool | None = None, plots: bool = True,
          max_total: int | None = DEFAULT_MAX_TOTAL, on_row=None, on_start=None) -> SweepOutcome:
    """Run a sweep and write its report.

    Parameters
    ----------
    scenario : Scenario or path-like
        The base scenario.
    spec : SweepSpec or path-like
        The sweep specification.
    out_dir : path-like
        Output folder; a folder of an interrupted sweep resumes it.
    serial : bool
        Run every task in this process (same numbers as on a cluster).
    client : distributed.Client, optional
        An existing client to use.
    scheduler : str, optional
        Address of an existing scheduler (``tcp://host:8786``); FMUs are shipped as bytes.
    workers : int, optional
        Worker processes of the LocalCluster started otherwise (default: the number of cores).
    max_runs : int, optional
        Run at most this many new runs (resume later).
    fmus : dict, optional
        ``{n: path}`` FMU files instead of building them.
    ship_fmu : bool, optional
        Ship the FMU bytes to the workers (default: only with ``scheduler`` or ``client``).
    plots : bool
        Write the PNG plots besides ``report.json``.
    max_total : int or None
        Refuse a spec that makes more runs than this (checked before any run is made; None: no
        limit).
    on_row : callable, optional
        ``on_row(row, done, total)`` after each finished run.
    on_start : callable, optional
        ``on_start(n_runs)`` once the runs are prepared (before anything runs).

    Returns
    -------
    SweepOutcome
        With ``report`` (the report dict) and ``files`` (results, report, plots, chunks).

    Raises
    ------
    SweepError
        A bad spec, more runs than ``max_total``, invalid runs, or ``out_dir`` holding another
        sweep.
    """
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    spec = spec if isinstance(spec, SweepSpec) else load_sweep_spec(spec)
    check_size(spec, max_total)
    if ship_fmu is None:
        ship_fmu = not serial and (client is not None or scheduler is not None)
    runs, shared, manifest = prepare_runs(sc, spec, fmus=fmus, ship_fmu=ship_fmu)
    if on_start is not None:
        on_start(len(runs))
    kwargs = dict(metrics=spec.kept_metrics, steady_window=spec.steady_window,
                  chunk_size=spec.chunk_size, shared=shared, max_runs=max_runs,
                  manifest=manifest, on_row=on_row)
    t0 = time.perf_counter()
    if serial:
        outcome = run_sweep(runs, run_task, out_dir, serial=True, **kwargs)
    else:
        outcome = _run_on_dask(runs, out_dir, kwargs, client=client, scheduler=scheduler,
                               workers=workers)
    _write_report(outcome, spec, runs, elapsed=time.perf_counter() - t0, plots=plots)
    return outcome


def _write_report(outcome: SweepOutcome, spec: SweepSpec, runs, *, elapsed: float,
                  plots: bool) -> None:
    from .sweep_report import write_report

    parameters = [{"path": p.path, "label": p.label} for p in spec.parameters]
    extra = {"mode": spec.mode, "new_runs": outcome.new, "resumed_runs": outcome.skipped,
             "elapsed_s": round(elapsed, 3)}
    if bias_swept(spec):
        forms = {"last_trailer": "exact sin(eps_eff)/(D K_y) (last trailer localized)",
                 "robot": "estimated pose (steady_lateral_error_estimated_pose)"}
        used = sorted({run.payload["scenario"]["sensors"]["localize"] for run in runs})
        extra["prediction_form"] = "; ".join(forms[u] for u in used)
    outcome.report = write_report(outcome.out_dir, outcome.rows, parameters, n_runs=outcome.n_runs,
                                  name=spec.name, description=spec.description, plots=plots,
                                  extra=extra)
    outcome.files.update(report=outcome.report["files"]["report"],
                         plots=outcome.report["files"]["plots"])
