"""`fitting._gc.paused_gc`: the cyclic collector off inside the block (nested blocks too),
back to how it was after; nothing when disabled."""

import gc

from fitting import _gc


def test_paused_gc_disables_and_restores():
    assert gc.isenabled()
    with _gc.paused_gc():
        assert not gc.isenabled()
        with _gc.paused_gc():
            assert not gc.isenabled()
        assert not gc.isenabled()  # the outer block holds
    assert gc.isenabled()
    gc.disable()  # a caller that had it off keeps it off
    try:
        with _gc.paused_gc():
            assert not gc.isenabled()
        assert not gc.isenabled()
    finally:
        gc.enable()


def test_disabled_does_nothing():
    _gc.ENABLED = False
    try:
        with _gc.paused_gc():
            assert gc.isenabled()
    finally:
        _gc.ENABLED = True
