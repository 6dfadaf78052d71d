"""Ctrl-C: never lost, and held over a step that must not be cut in half.

Ctrl-C (SIGINT) ends a `dynid` command with one line and exit code 130 (dynid.cli). Within `interruptible()` (the
command line's `main`), the handler raises KeyboardInterrupt wherever the main thread is, as Python's own does, and
records that it came (`requested`). Python drops an exception raised inside a weakref callback or a `__del__` (they
cannot raise: it prints "Exception ignored in ..." and goes on), and the handler runs inside one whenever the main
thread happens to be there, as it often is while modules are imported or a Dask cluster starts: such a Ctrl-C was
lost, and the command ran to its end. It is delivered again now, as soon as the main thread is out of the callback,
and a block that ends without it having been raised again ends with KeyboardInterrupt; a command's outputs are not
put in place once a Ctrl-C came (dynid.outputs asks `requested`).

Some steps must not be cut in half: putting a command's outputs in place or removing its temporary files
(dynid.outputs), starting a Dask cluster's worker processes (dynid.cluster). `sigint_held` holds
the signal over such a step: one that comes meanwhile is recorded, not lost, and delivered as soon as the step
ends, the way the handler it replaced would have (KeyboardInterrupt).

With `children=True` it also blocks SIGINT in the calling thread for the step, so that the threads started in it,
and every process started from those, inherit it blocked: a signal mask survives fork and exec (the way CPython
starts multiprocessing's resource tracker). Such a process never gets the terminal's SIGINT, which reaches the whole
process group; dynid alone answers it, and ends them. (Ignoring the signal instead, SIG_IGN, is inherited too, but
it is this process's own disposition as well: a Ctrl-C while the processes started was dropped, and the command
went on to the end.)

Layer: beside errors; the standard library only (dynid.cli imports it before anything heavy).
"""

from __future__ import annotations

import _thread
import contextlib
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

_lock = threading.Lock()
_open = False  # within interruptible()
_requested = False  # a Ctrl-C came
_dropped = False  # and its KeyboardInterrupt was swallowed, not raised again since


def requested() -> bool:
    """Whether a Ctrl-C came within `interruptible()`, even one whose KeyboardInterrupt something swallowed."""
    return _requested


def _on_sigint(signum: int, frame: object) -> None:  # noqa: ARG001 - a signal handler's signature
    global _requested, _dropped
    _requested, _dropped = True, False
    raise KeyboardInterrupt


def _deliver_again() -> None:
    """On a thread of its own, once the main thread is out of the callback that dropped the KeyboardInterrupt (run
    from there, the handler would raise into it again): the SIGINT handler run again in the main thread. Should its
    KeyboardInterrupt be dropped again, this runs again."""
    time.sleep(0.001)
    with _lock:
        if _open and _dropped:
            _thread.interrupt_main(signal.SIGINT)


def _unraisable(previous: Callable[[Any], None]) -> Callable[[Any], None]:
    """sys.unraisablehook that has a dropped KeyboardInterrupt delivered again, and leaves the rest to `previous`."""
    def hook(unraisable: Any) -> None:
        global _dropped
        if isinstance(unraisable.exc_value, KeyboardInterrupt):
            _dropped = True
            _thread.start_new_thread(_deliver_again, ())  # does not wait for the thread, as threading's start does
        else:
            previous(unraisable)

    return hook


@contextlib.contextmanager
def interruptible() -> Iterator[None]:
    """Ctrl-C as KeyboardInterrupt, recorded, and never swallowed (see the module's docstring), for the block; a
    no-op off the main thread, and where SIGINT is ignored (a job started in the background) or has a handler of its own."""
    global _open, _requested, _dropped
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        yield
        return
    previous_hook = sys.unraisablehook
    _requested = _dropped = False
    _open = True
    signal.signal(signal.SIGINT, _on_sigint)
    sys.unraisablehook = _unraisable(previous_hook)
    try:
        yield
    finally:
        with _lock:  # no delivery from now on: one made already has tripped the handler, which signal.signal runs
            _open = False
        sys.unraisablehook = previous_hook
        try:
            signal.signal(signal.SIGINT, signal.default_int_handler)
        except KeyboardInterrupt:  # one that came just now, run before the handler was replaced: replace it still
            signal.signal(signal.SIGINT, signal.default_int_handler)
            raise
        dropped, _requested, _dropped = _dropped, False, False
        if dropped and not isinstance(sys.exc_info()[1], KeyboardInterrupt):
            raise KeyboardInterrupt  # a Ctrl-C came and was dropped: the command ends as interrupted all the same


@contextlib.contextmanager
def sigint_held(children: bool = False) -> Iterator[None]:
    """Hold Ctrl-C over the block (see the module's docstring); a no-op off the main thread, where Python runs no
    signal handler, and where SIGINT is ignored or not Python's (a handler it did not install)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.getsignal(signal.SIGINT)
    if previous is None or previous == signal.SIG_IGN:
        yield
        return
    came: list[int] = []

    def hold(signum: int, frame: object) -> None:  # noqa: ARG001 - a signal handler's signature
        came.append(signum)

    signal.signal(signal.SIGINT, hold)
    try:
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT}) if children else None
        try:
            yield
        finally:
            if mask is not None:
                # A SIGINT that came while blocked is pending: unblocking delivers it, and pthread_sigmask runs the
                # handler (`hold`) before it returns.
                signal.pthread_sigmask(signal.SIG_SETMASK, mask)
    finally:
        # signal.signal runs the handlers of signals already caught before it replaces `hold`: none is lost.
        signal.signal(signal.SIGINT, previous)
        if came:  # delivered whether the block ended well or not: the user asked to stop
            if callable(previous):
                previous(signal.SIGINT, None)  # Python's default_int_handler: KeyboardInterrupt, here
            else:  # SIG_DFL: what the signal would have done (end the process)
                signal.raise_signal(signal.SIGINT)
