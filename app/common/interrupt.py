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

#: the signals received during this run, in order (cleared by :func:`clear`)
RECEIVED: list[int] = []
#: whether a KeyboardInterrupt has been raised for them (then a repeated signal raises none)
RAISED: list[bool] = []


def record(signum: int) -> None:
    """Note that ``signum`` arrived."""
    if signum not in RECEIVED:
        RECEIVED.append(signum)


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
