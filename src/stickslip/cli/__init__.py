"""Command line: ``stickslip <command> ...`` (the commands: :mod:`.commands`).

This module is the console script's entry point and imports nothing: :func:`main` takes Ctrl-C from its first line,
before the command's modules (NumPy, SciPy, FMPy, Matplotlib, the package's own) load.
"""

import os
import sys

#: the exit code after Ctrl-C (128 + SIGINT, as a shell reports a process that SIGINT ended)
INTERRUPTED = 130


def main(argv=None):
    """Entry point of the ``stickslip`` script: run the command ``argv`` (default ``sys.argv[1:]``) names; returns
    the exit code (0 success, 1 failure, 2 usage, :data:`INTERRUPTED` after Ctrl-C, with one line on stderr, at
    any moment of the command, its loading included)."""
    try:
        from ..hosts import interrupts

        with interrupts.counting():
            from .commands import dispatch

            code = dispatch(argv)
            interrupts.check()  # a Ctrl-C that a library swallowed and nothing checked for since
            return code
    except KeyboardInterrupt as exc:  # Ctrl-C: one line, the shell's status for SIGINT
        said = str(exc) if type(exc) is not KeyboardInterrupt else ""  # an Interrupted's account of what was kept
        print(f"{_command(argv)}: interrupted" + (f" ({said})" if said else ""), file=sys.stderr)
        return INTERRUPTED
    except Exception as exc:
        if not _raised_by_ctrl_c(exc):
            raise
        # Ctrl-C broke the loading of a compiled module (an ImportError from its KeyboardInterrupt): the same line,
        # then an exit without Python's finalization, which such a half-made module can crash
        print(f"{_command(argv)}: interrupted", file=sys.stderr)
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(INTERRUPTED)


def _raised_by_ctrl_c(exc):
    """Whether a KeyboardInterrupt is among the causes of ``exc`` (its ``__cause__`` and ``__context__`` chain)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def _command(argv):
    """``stickslip <command>`` of the command that ``argv`` (default ``sys.argv[1:]``) names, as far as it is known
    before its parser is built: the first argument that is no option (``stickslip`` alone if none)."""
    words = [word for word in (sys.argv[1:] if argv is None else argv) if not word.startswith("-")]
    return " ".join(["stickslip", *words[:1]])
