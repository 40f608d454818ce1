"""`outermost`: a context manager whose set-up and tear-down run only around the outermost
of nested (or concurrent) blocks; `fitting._blas` and `fitting._gc` are built on it."""

import contextlib
import threading
from collections.abc import Callable


def outermost(enter: Callable[[], object], leave: Callable[[object], None],
              enabled: Callable[[], bool], doc: str):
    """A context manager (documented by `doc`) that calls `enter` when the first block
    opens and ``leave(what enter returned)`` when the last one closes; while
    ``enabled()`` is false, a block does nothing."""
    lock = threading.Lock()
    state = {"depth": 0, "token": None}

    @contextlib.contextmanager
    def block():
        if not enabled():
            yield
            return
        with lock:
            if state["depth"] == 0:
                state["token"] = enter()
            state["depth"] += 1
        try:
            yield
        finally:
            with lock:
                state["depth"] -= 1
                if state["depth"] == 0:
                    leave(state["token"])

    block.__doc__ = doc
    return block
