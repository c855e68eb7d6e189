"""Command-line options whose values are parsed by pushtrain, not click (issue #29, case 19):
a bad value exits 2 naming the option, the value and what is allowed, never a traceback."""

from __future__ import annotations

import socket
from pathlib import Path

import pytest
from click.testing import CliRunner

from pushtrain.cli.main import cli

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _invoke(args):
    return CliRunner().invoke(cli, args)


@pytest.mark.parametrize("value, why", [
    ("abc", "'abc' is not a number"),  # was "could not convert string to float: 'abc'"
    ("5,,10", "'' is not a number"),
    ("5,nan", "'nan' is not finite and > 0"),
    ("-5", "'-5' is not finite and > 0"),
])
def test_slip_study_alphas_name_the_option(tmp_path, value, why):
    done = _invoke(["slip-study", "--alphas", value, "--out", str(tmp_path / "out")])
    assert done.exit_code == 2, done.output
    assert f"--alphas = {value!r}" in done.output and why in done.output, done.output
    assert "deg/s^2" in done.output
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("value, why", [
    ("x", "'x' is not a whole number"),
    ("1-x", "'1-x' is not a range of whole numbers"),
    ("0", "'0' is outside 1..50"),
    ("1-100000", "'1-100000' is outside 1..50"),  # was listed, then refused as 100000 numbers
    ("5-2", "'5-2' is an empty range"),
])
def test_slip_study_trailers_name_the_option(tmp_path, value, why):
    done = _invoke(["slip-study", "--trailers", value, "--out", str(tmp_path / "out")])
    assert done.exit_code == 2, done.output
    assert f"--trailers = {value!r}" in done.output and why in done.output, done.output
    assert len(done.output) < 400, done.output  # not a list of every number asked for


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize("address, why", [
    ("foo", "missing port number"),
    ("xyz://host:1", "unknown protocol 'xyz'"),
    ("tcp://host:abc", "'abc'"),
    (None, "nothing accepts connections"),  # a port nobody listens on (Dask waited 30 s)
])
def test_sweep_scheduler_names_the_option(tmp_path, address, why):
    address = address or f"tcp://127.0.0.1:{_free_port()}"
    done = _invoke(["sweep", str(EXAMPLES / "joint_bias_5deg.toml"), "--spec",
                    str(EXAMPLES / "sweeps" / "joint_bias.toml"), "--scheduler", address,
                    "--out", str(tmp_path / "out")])
    assert done.exit_code == 2, (done.output, done.exception)
    assert f"--scheduler = {address!r}" in done.output and why in done.output, done.output
    assert "tcp://host:8786" in done.output
    assert not (tmp_path / "out").exists()


def test_a_dask_scheduler_passes_the_check():
    import asyncio

    from distributed import Scheduler

    from pushtrain.cli.sweep import check_scheduler

    async def main():
        async with Scheduler(host="127.0.0.1", port=0, dashboard_address=":0") as scheduler:
            await asyncio.to_thread(check_scheduler, scheduler.address)

    asyncio.run(main())


def _serving(reply: bytes | None):
    """A loopback TCP server (127.0.0.1) that sends ``reply`` on every connection (None: says
    nothing) and keeps it open (``b""``: closes it at once); the socket, to close."""
    import threading

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)

    def serve():
        while True:
            try:
                conn, _ = server.accept()
            except OSError:
                return
            if reply == b"":
                conn.close()
                continue
            if reply is not None:
                conn.sendall(reply)
            threading.Timer(30.0, conn.close).start()

    threading.Thread(target=serve, daemon=True).start()
    return server


@pytest.mark.parametrize("reply, why", [
    pytest.param(None, "said nothing in 3 s", marks=pytest.mark.slow),  # hung past 180 s
    (b"\xff" * 64, "its first message is not a Dask comm's"),  # a multi-EiB allocation
    (b"SSH-2.0-OpenSSH_9.6\r\n", "its first message is not a Dask comm's"),
    (b"\x10" + b"\0" * 7 + b"\x07" * 16, "its first message is not a Dask comm's"),
    (b"", "closed the connection"),
], ids=["silent", "garbage", "ssh", "short-garbage", "closes"])
def test_a_port_that_is_not_a_dask_scheduler_is_named_within_seconds(tmp_path, reply, why):
    import time

    server = _serving(reply)
    address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
    try:
        t0 = time.monotonic()
        done = _invoke(["sweep", str(EXAMPLES / "joint_bias_5deg.toml"), "--spec",
                        str(EXAMPLES / "sweeps" / "joint_bias.toml"), "--scheduler", address,
                        "--out", str(tmp_path / "out")])
        took = time.monotonic() - t0
    finally:
        server.close()
    assert done.exit_code == 2, (done.output, done.exception)
    assert f"--scheduler = {address!r}" in done.output and why in done.output, done.output
    assert "a program accepts connections at 127.0.0.1" in done.output
    assert took < 20.0, took  # a bound against a hang, not a timing: 3 s each step
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("out", ["/proc/pushtrain-sweep/x", "N" * 300])
def test_a_sweep_out_that_cannot_be_written_is_exit_2_before_any_run(tmp_path, monkeypatch, out):
    monkeypatch.chdir(tmp_path)
    done = _invoke(["sweep", str(EXAMPLES / "joint_bias_5deg.toml"), "--spec",
                    str(EXAMPLES / "sweeps" / "joint_bias.toml"), "--workers", "0",
                    "--out", out])
    assert done.exit_code == 2, (done.output, done.exception)
    assert "--out" in done.output and "cannot be written" in done.output, done.output
    assert "runs (" not in done.output  # refused before the runs are counted and made
