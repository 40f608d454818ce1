"""Ctrl-C and SIGTERM stop a command within about a second, whatever it is doing.

Python runs a signal handler only in the main thread, between two bytecodes. While the
main thread waits in compiled code (XLA compiling the fit's chunk, a chunk of solver steps
running), a Ctrl-C waits with it (`fitting._chunked` keeps a chunk to about a second), and
an interpreter that then finalises while XLA's threads are still busy can crash with
SIGSEGV (exit -11, not 130; `benchmarks/profiling/interrupt_latency.py` measures how a
command ends). So, when the command line is the process (`arm`):

- the handlers raise as before (`KeyboardInterrupt`; for SIGTERM, `terminate` raises
  `Terminated`): each `fitting.cli._output.atomic_file` being written removes its
  temporary file, and `main` calls `stop`, which prints one line and ends the process
  with `os._exit` (no finalisation racing XLA's threads);
- `signal.set_wakeup_fd` lets a watcher thread see the signal at once, even while the
  main thread is in compiled code. If the main thread has not called `stop` within
  `GRACE` seconds, the watcher does it for it: it removes the temporary files still open
  (`fitting.cli._output.remove_pending`), prints the line and exits with the same code.
  (A Ctrl-C that lands in a finaliser is swallowed by Python, the work goes on: so it
  can happen even when the main thread runs Python code.)

The watcher runs while XLA has let go of the interpreter lock, as it does while it
compiles or computes. In-process calls (``main([...])``, the tests) are not armed: they
get the exit code back as before.
"""

import os
import signal
import sys
import threading

from . import _output


#: Seconds the main thread has to stop by itself after a signal before the watcher stops
#: the process.
GRACE = 1.0

#: Exit code and word of each signal handled.
_CODES = {signal.SIGINT: (130, "interrupted"), signal.SIGTERM: (143, "terminated")}

_stopping = threading.Lock()
_stopped = threading.Event()


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C so that unfinished outputs are cleaned up."""


def terminate(signum, frame):
    """The SIGTERM handler: raise `Terminated`."""
    raise Terminated


def arm(command: str) -> None:
    """Start the watcher (module docstring) for the process running `command`. Call from
    the main thread, after the handlers are set."""
    # A KeyboardInterrupt raised inside a finaliser or callback is "ignored" by Python with
    # a traceback on stderr, and the work goes on: say nothing, the watcher stops it.
    default = sys.unraisablehook

    def hook(unraisable):
        if not isinstance(unraisable.exc_value, KeyboardInterrupt):
            default(unraisable)

    sys.unraisablehook = hook
    read, write = os.pipe()
    os.set_blocking(write, False)
    signal.set_wakeup_fd(write, warn_on_full_buffer=False)
    threading.Thread(target=_watch, args=(read, command), name="jaxfric-signals",
                     daemon=True).start()


def _watch(read: int, command: str) -> None:
    while True:
        byte = os.read(read, 1)
        if not byte:
            return
        if byte[0] in _CODES and not _stopped.wait(GRACE):
            stop(command, byte[0], hard=True)


def stop(command: str, signum: int, hard: bool) -> int:
    """Print ``jaxfric COMMAND: interrupted`` (or ``terminated``) and return the exit code
    (130, 143). With `hard` (an armed process), print it once whichever thread comes
    first, remove the temporary files still open and end the process with that code."""
    code, word = _CODES[signum]
    if not hard:
        print(f"jaxfric {command}: {word}", file=sys.stderr)
        return code
    with _stopping:
        if not _stopped.is_set():
            _stopped.set()
            _output.remove_pending()
            print(f"jaxfric {command}: {word}", file=sys.stderr)
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):  # a closed pipe: nothing more to say
                pass
        os._exit(code)
