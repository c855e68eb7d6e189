"""The command line's exit codes and the interruptions that end a command (no imports: the
console scripts' guard uses them before any other module has loaded)."""

__all__ = ["EXIT_OK", "EXIT_NOT_REACHED", "EXIT_BAD_INPUT", "EXIT_INTERRUPTED", "EXIT_TERMINATED",
           "EXIT_HUNG_UP", "Terminated", "HungUp", "interruption", "terminate_as_interrupt"]

EXIT_OK = 0
"""The goal was reached, or a fixed-horizon run completed."""
EXIT_NOT_REACHED = 1
"""The run completed but did not reach the goal, no plan was found, or a plot was not drawn."""
EXIT_BAD_INPUT = 2
"""Bad input: a scenario field, a file, an option, an output folder."""
EXIT_INTERRUPTED = 130
"""Ctrl-C (128 + SIGINT, as a shell reports it); what was written so far is kept."""
EXIT_TERMINATED = 143
"""SIGTERM (128 + SIGTERM: ``kill``, ``docker stop``, a batch scheduler), handled as Ctrl-C is:
what was written so far is kept."""
EXIT_HUNG_UP = 129
"""SIGHUP (128 + SIGHUP: the terminal or the SSH session closed), handled as SIGTERM is."""


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread by :func:`terminate_as_interrupt`'s handler. A
    KeyboardInterrupt, so that whatever ends a command cleanly on Ctrl-C (the run folder's
    summary, the plot processes stopped, partial files removed) does so on SIGTERM too."""


class HungUp(Terminated):
    """SIGHUP (the terminal closed), raised as :class:`Terminated` is, with its own exit code."""


def interruption(exc: BaseException) -> tuple[int, str]:
    """(exit code, what happened) of an interruption: SIGHUP (:class:`HungUp`), SIGTERM
    (:class:`Terminated`) or Ctrl-C."""
    if isinstance(exc, HungUp):
        return EXIT_HUNG_UP, "hung up (SIGHUP)"
    if isinstance(exc, Terminated):
        return EXIT_TERMINATED, "terminated (SIGTERM)"
    return EXIT_INTERRUPTED, "interrupted (Ctrl-C)"


def _ending_signals():
    import signal

    return [signal.SIGTERM] + ([signal.SIGHUP] if hasattr(signal, "SIGHUP") else [])


def _raise_terminated(signum, frame):
    import signal

    for sig in _ending_signals():  # the first ends the command; the others wait for its end
        signal.signal(sig, signal.SIG_IGN)
    raise HungUp() if signum == getattr(signal, "SIGHUP", None) else Terminated()


def _default_in_child() -> None:
    """In a forked child (a plot process, until it sets its own handler): SIGTERM ends it as by
    default, not as the command's Terminated (a traceback from the child)."""
    import signal

    try:
        for sig in _ending_signals():
            if signal.getsignal(sig) is _raise_terminated:
                signal.signal(sig, signal.SIG_DFL)
    except ValueError:  # forked from another thread than the main one: it cannot be set
        pass


_FORK_HOOK = []


def terminate_as_interrupt() -> None:
    """From now on SIGTERM raises :class:`Terminated` and SIGHUP :class:`HungUp` in the main
    thread (once: a second signal while the command ends is ignored, so the clean-up is not cut
    short; SIGKILL still ends it). Forked children get the defaults back. Call from the main
    thread."""
    import os
    import signal

    for sig in _ending_signals():
        signal.signal(sig, _raise_terminated)
    if not _FORK_HOOK and hasattr(os, "register_at_fork"):
        os.register_at_fork(after_in_child=_default_in_child)
        _FORK_HOOK.append(True)
