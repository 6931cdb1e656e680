"""A Ctrl-C (SIGINT) or SIGTERM received by a command-line run, kept so that it stops the run
even when the KeyboardInterrupt raised for it is swallowed.

The command line's handler (app/common/runtime.py) raises a KeyboardInterrupt wherever the signal
lands. Code that runs Python on behalf of a C extension may swallow it: pybind11 builds the
message of a call that matches no overload from the arguments' ``repr``, and an exception raised
there is lost; DOLFINx 0.5's ``create_mesh`` first tries an overload that fails by design. Such a
run went on and exited 0 as if no Ctrl-C had come. The handler therefore records the signal here
(:func:`record`), and :func:`checkpoint`, called where the run goes on in its normal flow (a
stage begins, a state of the path is analysed, before the results are committed), raises the
KeyboardInterrupt again. Nothing is recorded outside a command-line run.
"""
from __future__ import annotations

import contextlib
from typing import Callable, Iterator

#: the signals received during this run, in order (cleared by :func:`clear`)
RECEIVED: list[int] = []
#: whether a KeyboardInterrupt has been raised for them (then a repeated signal raises none)
RAISED: list[bool] = []
#: how many times the handler took each signal since the run's handlers were installed (never
#: cleared by :func:`clear`: app/common/hard_stop.py tells by it whether the main thread is taking
#: signals at all)
TAKEN: dict[int, int] = {}
#: what a hard stop (app/common/hard_stop.py) must undo, innermost last: (cleanup, what the stopped
#: command keeps, or None: nothing), see :func:`cleanup_on_hard_stop`
CLEANUPS: list[tuple[Callable[[], None], str | None]] = []


def record(signum: int) -> None:
    """Note that ``signum`` arrived (the handler took it)."""
    TAKEN[signum] = TAKEN.get(signum, 0) + 1
    if signum not in RECEIVED:
        RECEIVED.append(signum)


def message(signum: int, left: str | None = None) -> str:
    """The one line of a run stopped by ``signum`` (``left``: what the command keeps)."""
    return (f"error: interrupted by {'SIGTERM' if signum == 15 else 'SIGINT (Ctrl-C)'}; "
            f"{left or 'the run stopped and wrote no results'}")


@contextlib.contextmanager
def cleanup_on_hard_stop(cleanup: Callable[[], None], left: str | None = None) -> Iterator[None]:
    """While the block runs, a hard stop (a signal the main thread could not take within a second,
    app/common/hard_stop.py) calls ``cleanup`` (drop the staging folder, release the lock) before
    the process ends; ``left`` says what the stopped command keeps, for its one line. The normal
    path (a KeyboardInterrupt) cleans up by itself and never calls it."""
    entry = (cleanup, left)
    CLEANUPS.append(entry)
    try:
        yield
    finally:
        CLEANUPS.remove(entry)


def raised() -> bool:
    """Whether a KeyboardInterrupt was raised for a received signal."""
    return bool(RAISED)


def keyboard_interrupt() -> KeyboardInterrupt:
    """The KeyboardInterrupt for the first received signal (``"signal N"``), marked as raised."""
    RAISED[:] = [True]
    return KeyboardInterrupt(f"signal {RECEIVED[0]}")


def checkpoint() -> None:
    """Raise the KeyboardInterrupt of a received signal (again, if it was swallowed). Call it only
    in the normal flow of the run, never from a ``finally`` or ``except`` block."""
    if RECEIVED:
        raise keyboard_interrupt()


def clear() -> None:
    """Forget the received signals (a new run in the same process, or the interrupt reported)."""
    RECEIVED.clear()
    RAISED.clear()


class Stopped(KeyboardInterrupt):
    """The KeyboardInterrupt of a command that keeps part of its work (a sweep keeps the cases it
    completed): ``left`` says what is left, for the one line that reports the interrupt."""

    def __init__(self, interrupted: KeyboardInterrupt, left: str):
        super().__init__(*interrupted.args)
        self.left = left
