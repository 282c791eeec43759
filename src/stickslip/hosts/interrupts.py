"""Ctrl-C told apart from an FMU's failure.

Python runs its SIGINT handler in the main thread, wherever the interpreter is: also inside an FMU's Python slave
during an FMI call. The KeyboardInterrupt it raises there is caught by the FMU's library (PythonFMU, pythonfmu3),
which reports it as the call's error status ("[doStep] KeyboardInterrupt()"). Within :func:`counting`, SIGINT
raises KeyboardInterrupt as Python's default handler does and is counted (:func:`interrupted`), so that a failed
FMI call during which one arrived is re-raised as KeyboardInterrupt (:meth:`stickslip.hosts.fmpy_host.Instance.call`), not
reported as the FMU's error. A KeyboardInterrupt that a library swallowed where it was raised (a bare ``except``,
a compiled module whose failed initialisation is taken for a missing module) still ends the command: at the next
:func:`check` (each FMI call, each progress step).
"""

import contextlib
import functools
import signal
import sys
import threading

_count = 0  # SIGINTs received within counting()


class Interrupted(KeyboardInterrupt):
    """The KeyboardInterrupt of a Ctrl-C that ended a command's work, saying what the work kept (its message, which
    the command line prints; a plain KeyboardInterrupt's text, which Python may fill with its own, is not printed)."""


def interrupted():
    """Whether a SIGINT arrived within :func:`counting`."""
    return _count > 0


def check():
    """KeyboardInterrupt if a SIGINT arrived within :func:`counting`: within it every Ctrl-C ends the command, also
    one whose KeyboardInterrupt was swallowed where it was raised."""
    if interrupted():
        raise KeyboardInterrupt


def _count_and_raise(signum, frame):
    global _count
    _count += 1
    raise KeyboardInterrupt


@contextlib.contextmanager
def counting():
    """SIGINT counted (from zero) and raised as KeyboardInterrupt while the context lasts; nothing changes outside the main
    thread (only it can set signal handlers) or where SIGINT is not Python's default handler (a caller's own)."""
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        yield
        return
    global _count
    _count = 0
    signal.signal(signal.SIGINT, _count_and_raise)
    hook, sys.unraisablehook = sys.unraisablehook, functools.partial(_unless_interrupt, sys.unraisablehook)
    try:
        yield
    finally:
        sys.unraisablehook = hook
        signal.signal(signal.SIGINT, signal.default_int_handler)


def _unless_interrupt(hook, unraisable):
    """``hook(unraisable)`` unless it is a KeyboardInterrupt (raised where Python cannot pass it on, as in a weak
    reference's callback, and counted: :func:`check` acts on it), which Python would print as a traceback."""
    if not isinstance(unraisable.exc_value, KeyboardInterrupt):
        hook(unraisable)


@contextlib.contextmanager
def ignored():
    """SIGINT ignored while the context lasts (in the main thread): processes started then inherit it ignored (a
    pool's workers, which the process that handles Ctrl-C ends itself)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
