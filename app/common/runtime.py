"""The app's process-wide patches of the Python runtime and of its libraries, behind one door.

A few changes of the app act on the whole process rather than on its own objects: signal
handlers, hooks of :mod:`sys` and :mod:`warnings`, environment variables, a filter on a library's
logger, functions of a library replaced. Each one is made by a function of this module, and
tests/test_runtime.py fails when app/ makes one anywhere else (the exceptions it lists give
their reasons). The patches, who gets each, and what each relies on:

1. MPI environment defaults (:func:`install` with ``command_line=True``; the command line only):
   under ``mpirun``, ``OPENBLAS_NUM_THREADS=1`` and ``OMPI_MCA_mpi_yield_when_idle=1`` unless
   already set. Read when numpy loads OpenBLAS and at ``MPI_Init``, so set first thing in
   ``main()`` (app/__init__.py imports neither). Not by the API: by the time a program calls
   :func:`app.run_study`, :mod:`app.api` has imported mpi4py (MPI is started), and the
   environment of a user's program is its own. No version check: a variable another BLAS or MPI
   does not read changes nothing.
2. SIGINT and SIGTERM during a run (:func:`catch_signals`; the command line only, once the run
   starts): the handler :func:`_terminate` raises a KeyboardInterrupt, put off where one would do
   harm (:func:`_deferring`), and ``sys.unraisablehook`` is :func:`_during_run`. It relies on FFCx
   0.5.x compiling in ``ffcx/codegeneration/jit.py`` (the claim of a C file in the shared JIT
   cache); with another FFCx it is installed all the same, with a DEBUG line (a signal during a
   compilation is then raised at once, as without the app). The interpreter's wakeup descriptor
   (:func:`signal.set_wakeup_fd`) is the pipe of the watchdog thread of app/common/hard_stop.py,
   which stops the run itself, cleanups run and one line written, when the handler has not taken
   a SIGINT or SIGTERM within a second (the main thread inside a long C call). Not by the API: a user's program
   owns its signal handlers, and a Ctrl-C there is Python's usual KeyboardInterrupt.
3. After an interrupt (:func:`quiet_after_interrupt`; the command line only): a signal sent
   again is ignored and ``sys.unraisablehook`` sends destructor failures to the debug log.
4. Warnings shown (:func:`showing_warnings`; both, for the length of a study, through
   :func:`app.common.library_warnings.explained`): ``warnings.showwarning`` replaced inside
   ``warnings.catch_warnings()``, so it is back when the study ends. FFCx 0.5 calls
   ``logging.captureWarnings(True)`` when first imported, which replaces it too: FFCx is imported
   first. No version check: importing FFCx first is harmless with any version.
5. FFCx's logger filtered (:func:`filter_ffcx_log`; both, on first use: every form of the app is
   built with :func:`app.systems.jit.params`, which calls it): relies on FFCx 0.5.x's INFO record
   "Waiting for X.c.cached to appear." and its ``logging.basicConfig()`` on import. With another
   FFCx the filter is attached all the same (its records of WARNING and above still pass), with
   a DEBUG line.
6. The compilers' settings files not read (:func:`ignore_jit_settings_files`; both, on first
   use, from :func:`app.systems.jit.params`): DOLFINx 0.5.x's and FFCx 0.5.x's
   ``_load_parameters`` replaced. With another version a function of that name is replaced all
   the same (the app gives every parameter itself), with a DEBUG line; a missing one is an error
   (the files might then be read elsewhere: the app fails closed).
7. Gmsh's import keeps SIGINT (:func:`import_gmsh`; both, on first use): relies on Gmsh 4.8.x
   setting SIGINT to its default action when imported and again in ``gmsh.finalize``. With
   another Gmsh it is applied all the same (it only keeps SIGINT as it was), with a DEBUG line.
8. Open MPI's progress engine does not yield the CPU while rank 0 works alone
   (:func:`mpi_progress_not_yielding`; both, around the work of
   :func:`app.common.waiting.alone_on_rank_zero`, the previous setting back afterwards). With
   ``mpi_yield_when_idle`` on (patch 1), every MPI call that finds nothing to do calls
   ``sched_yield``, and MUMPS probes for messages between the nodes of its tree even on one
   process: rank 0's triangular solves (SLEPc's shift-and-invert of the interior blocks of (19))
   spent a quarter of their time in that system call, 18 s per solve at 10^6 DOFs against
   11.5 s without it. The other ranks sleep meanwhile, so nothing waits for rank 0's cores.
   Relies on Open MPI 4.x's ``opal_progress_set_yield_when_idle`` in ``libopen-pal.so.40``, taken
   only when already loaded; with another MPI nothing is changed, with a DEBUG line.

The API (:func:`app.api.run_study`) calls :func:`install` with ``command_line=False``, which
applies nothing at once: it gets 4 to 8, each where its library is first used, and none of 1 to
3. Not patches, so not here: the command line's logging set-up (app/common/logs.py: handlers,
levels and a filter on its own handler through the logging API, as any program's ``main``
configures its logging; the API leaves logging to the user's program), the settings pyvista
documents for drawing off screen (app/plot/canvas.py), and what the drawing processes
(app/plot/worker.py ignores SIGINT) and the Gmsh sandbox (app/systems/gmsh/child.py), each an
interpreter of its own, set for themselves.

Applying a patch again changes nothing: a function sees whether its patch is there already (a
filter of the same type, a replaced function, a module imported) or sets the same values again
(the signal handlers, the environment defaults), so this module keeps no state of its own.
"""
from __future__ import annotations

import contextlib
import ctypes
import importlib.metadata
import logging
import os
import signal
import sys
import threading
import warnings
from collections.abc import Callable, Iterator

from app.common import hard_stop, interrupt

log = logging.getLogger(__name__)

#: the series of FFCx and DOLFINx the patches of the form compilers were written against
FENICS_SERIES = "0.5."
#: the series of Gmsh the import patch was written against
GMSH_SERIES = "4.8."


def installed_version(distribution: str, module: str) -> str:
    """The installed version of ``distribution``: its package metadata, else the ``__version__``
    of ``module`` if imported (Debian's python3-gmsh has no metadata), else ``"unknown"``."""
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return str(getattr(sys.modules.get(module), "__version__", "unknown"))


def pinned(distribution: str, module: str, series: str, *, patch: str, otherwise: str) -> bool:
    """Whether ``distribution`` is of ``series`` (a version prefix such as ``"0.5."``); if not,
    one DEBUG line: ``patch`` relies on it and ``otherwise`` says what is done instead."""
    found = installed_version(distribution, module)
    if found.startswith(series):
        return True
    log.debug("%s relies on %s %sx, found %s: %s", patch, distribution, series, found, otherwise)
    return False


def install(*, command_line: bool) -> None:
    """Apply the patches an entry point applies before its work: with ``command_line=True``
    (``python -m app``: first thing in app/cli/main.py's ``main``, before numpy and MPI load) the
    MPI environment defaults; with ``command_line=False`` (:func:`app.api.run_study`) nothing at
    once. The library patches (4 to 7 in the module docstring) are applied for both where their
    library is first used; the signal handlers (:func:`catch_signals`) by the command line only,
    when its run starts."""
    if command_line:
        _mpi_environment_defaults()


def _mpi_environment_defaults() -> None:
    """Under ``mpirun`` (Open MPI's ``OMPI_COMM_WORLD_SIZE`` above 1), the defaults of patch 1;
    a user's own setting wins."""
    if int(os.environ.get("OMPI_COMM_WORLD_SIZE", "1")) > 1:
        # one BLAS thread per MPI rank (set before numpy loads OpenBLAS)
        os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
        # A rank waiting in a collective (while another proves a classification, say) yields its
        # core instead of spinning: on a machine with as many cores as ranks, a spinning rank
        # takes the CPU from the Gmsh child, the drawing processes or any other program, and a
        # run that takes seconds can take minutes. Read by Open MPI at MPI_Init.
        os.environ.setdefault("OMPI_MCA_mpi_yield_when_idle", "1")


@contextlib.contextmanager
def mpi_progress_not_yielding() -> Iterator[None]:
    """Context: Open MPI's progress engine does not call ``sched_yield`` when idle (patch 8 of
    the module docstring); its previous setting back afterwards. Nothing where the process has no
    Open MPI 4.x loaded."""
    setter = _opal_yield_setter()
    if setter is None:
        yield
        return
    before = setter(False)
    try:
        yield
    finally:
        setter(before)


#: Open MPI 4.x's library of portability and progress, and its setter of ``yield_when_idle``
OPAL_LIBRARY = "libopen-pal.so.40"
OPAL_YIELD_SETTER = "opal_progress_set_yield_when_idle"


def _opal_yield_setter() -> Callable[[bool], bool] | None:
    """``opal_progress_set_yield_when_idle`` (returns the previous setting) of the Open MPI this
    process has loaded, or None (one DEBUG line) where there is none."""
    try:
        lib = ctypes.CDLL(OPAL_LIBRARY, mode=os.RTLD_NOLOAD | os.RTLD_LAZY)    # never loads a library
        fn = getattr(lib, OPAL_YIELD_SETTER)
    except (OSError, AttributeError):
        log.debug("no %s in %s: Open MPI's progress engine left as it is", OPAL_YIELD_SETTER, OPAL_LIBRARY)
        return None
    fn.argtypes, fn.restype = [ctypes.c_bool], ctypes.c_bool
    return fn


# ---- signals (the command line's runs) --------------------------------------------------------

def catch_signals(rank: int = 0) -> None:
    """From here on SIGTERM and SIGINT stop the run with one line (:func:`_terminate`), within
    about a second even inside a long C call (the watchdog of app/common/hard_stop.py; ``rank``:
    the MPI rank, rank 0 writes the line)."""
    pinned("fenics-ffcx", "ffcx", FENICS_SERIES, patch="putting off a signal during FFCx's JIT compilation",
           otherwise="installed all the same (a signal during a compilation is raised at once)")
    interrupt.clear()
    interrupt.TAKEN.clear()
    sys.unraisablehook = _during_run
    signal.signal(signal.SIGTERM, _terminate)
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:     # not when started with SIGINT ignored
        signal.signal(signal.SIGINT, _terminate)
    # the interpreter's C-level handler writes each signal to the watchdog's pipe at once, even
    # while the main thread is inside a long C call (app/common/hard_stop.py)
    dog = hard_stop.watchdog(rank, lambda signum: signal.getsignal(signum) is _terminate)
    signal.set_wakeup_fd(dog.wakeup_fd, warn_on_full_buffer=False)


def quiet_after_interrupt() -> None:
    """Once a signal has stopped the run (app/cli/main.py then prints its one line): the signal
    sent again is ignored, and destructor failures go to the debug log (:func:`_after_interrupt`)."""
    for s in (signal.SIGINT, signal.SIGTERM):         # a deferred signal sent again is not raised here
        if signal.getsignal(s) is _terminate:
            signal.signal(s, signal.SIG_IGN)
    # An object the interrupt left half-built (an .npz file being opened, say) may fail in its
    # destructor when the process ends ("Exception ignored in ... __del__"): expected after an
    # interrupt, so such reports go to the debug log instead of beside the one line.
    sys.unraisablehook = _after_interrupt


def _deferring(frame) -> bool:
    """Whether a signal arriving in ``frame`` must wait: inside an import (the system types
    import DOLFINx when they build; the exception would surface from a C extension's
    initialisation as an ImportError with a traceback), inside FFCx's JIT compilation, which
    claims a C file in the user's shared JIT cache before compiling and releases it only when the
    compile ends or fails with an ``Exception`` (a KeyboardInterrupt there would leave the claim,
    and every later program compiling that form would wait for it until its timeout), or inside a
    finaliser (a ``__del__`` or a :class:`weakref.finalize` callback, run whenever the garbage
    collector frees an object), where Python reports an exception as "ignored" and drops it."""
    f = frame
    while f is not None:
        code = f.f_code
        name = code.co_filename
        if name.startswith("<frozen importlib") or name.endswith(os.path.join("ffcx", "codegeneration", "jit.py")):
            return True
        if code.co_name == "__del__" or (name.endswith("weakref.py") and code.co_name == "__call__"):
            return True
        f = f.f_back
    return False


def _during_run(unraisable) -> None:
    """``sys.unraisablehook`` during a run: the KeyboardInterrupt of a received signal that Python
    could not raise (it landed in a finaliser :func:`_deferring` did not recognise) goes to the
    debug log, not beside the one line of the interrupt; :func:`app.common.interrupt.checkpoint`
    raises it again in the run's normal flow. Anything else is reported as Python does."""
    if isinstance(unraisable.exc_value, KeyboardInterrupt) and interrupt.RECEIVED:
        log.debug("interrupt landed in %r; raised again at the next checkpoint", unraisable.object)
        return
    sys.__unraisablehook__(unraisable)


def _after_interrupt(unraisable) -> None:
    """``sys.unraisablehook`` once a run is interrupted (see :func:`quiet_after_interrupt`)."""
    log.debug("after the interrupt: %r in %r", unraisable.exc_value, unraisable.object)


def _terminate(signum, frame):
    """SIGTERM and SIGINT during a run: a KeyboardInterrupt, turned into one line by
    app/cli/main.py.

    Where it must wait (:func:`_deferring`) the signal is sent again a tenth of a second later
    instead, until the import or the compilation is done. A Ctrl-C also reaches the C compiler
    FFCx runs (the terminal signals the whole process group): the compilation then fails with an
    ordinary exception before the signal is raised, and the command line reports the interrupt.
    The signal is recorded in :mod:`app.common.interrupt`, whose checkpoints raise it again if
    the KeyboardInterrupt is swallowed on its way."""
    interrupt.record(signum)
    if interrupt.raised():           # on its way up, or swallowed: app.common.interrupt.checkpoint raises it again
        return
    if _deferring(frame):
        again = threading.Timer(0.1, os.kill, (os.getpid(), signum))
        again.daemon = True
        again.start()
        return
    raise interrupt.keyboard_interrupt()


# ---- the libraries (both entry points, where each library is first used) ---------------------

@contextlib.contextmanager
def showing_warnings(show: Callable) -> Iterator[None]:
    """Every warning raised in the block, repeated ones included, goes to ``show`` (called as
    ``warnings.showwarning`` is); the warnings machinery is as before after the block."""
    try:
        # FFCx (DOLFINx's form compiler, imported with DOLFINx) calls logging.captureWarnings(True)
        # when first imported, which replaces warnings.showwarning: import it before replacing it
        import ffcx  # noqa: F401
    except ImportError:          # pragma: no cover - a dependency of DOLFINx
        pass
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = show
        yield


def filter_ffcx_log(kind: type[logging.Filter]) -> None:
    """A ``kind()`` filter on FFCx's logger ``ffcx``, unless one of that type is there already
    (:class:`app.systems.jit.WaitNotice`)."""
    ffcx_log = logging.getLogger("ffcx")
    if any(isinstance(f, kind) for f in ffcx_log.filters):
        return
    pinned("fenics-ffcx", "ffcx", FENICS_SERIES, patch=f"the filter {kind.__name__} on FFCx's logger",
           otherwise="attached all the same (FFCx's warnings and errors still pass)")
    ffcx_log.addFilter(kind())


def _no_settings_files() -> tuple[dict, dict]:
    """The (user, current folder) parameters of the settings files: none (see :func:`ignore_jit_settings_files`)."""
    return {}, {}


def ignore_jit_settings_files() -> None:
    """DOLFINx 0.5 and FFCx 0.5 read ``~/.config/{dolfinx,ffcx}/*_parameters.json`` and
    ``./{dolfinx_jit,ffcx}_parameters.json`` on the first compilation (their ``_load_parameters``),
    catching only FileNotFoundError: a FIFO of that name in a study folder received from someone
    waits for ever, and a malformed file, a folder, or a HOME that is a file is a traceback. The
    app gives every parameter itself (:data:`app.systems.jit.FORM_PARAMS`, ``JIT_PARAMS``), so
    the files are not read at all: both functions are replaced by :func:`_no_settings_files`."""
    import dolfinx.jit
    import ffcx.parameters
    for module, distribution in ((dolfinx.jit, "fenics-dolfinx"), (ffcx.parameters, "fenics-ffcx")):
        current = getattr(module, "_load_parameters", None)
        if current is _no_settings_files:
            continue
        patch = f"not reading the settings files of {module.__name__}"
        if current is None:        # fail closed: the files could then be read where this cannot see
            raise RuntimeError(f"{module.__name__}._load_parameters is gone ({distribution} "
                               f"{installed_version(distribution, module.__name__)}): this app is pinned to "
                               f"{distribution} {FENICS_SERIES}x and cannot keep it from reading settings files")
        pinned(distribution, module.__name__, FENICS_SERIES, patch=patch,
               otherwise="its _load_parameters replaced all the same")
        module._load_parameters = _no_settings_files


def import_gmsh():
    """The gmsh module, imported without touching the process's SIGINT handler.

    Gmsh 4.8's module sets SIGINT to its default action when it is imported (``oldsig =
    signal.signal(SIGINT, SIG_DFL)``) and puts ``oldsig`` back in :func:`gmsh.finalize`. In a run
    that would let a Ctrl-C during meshing kill the process outright (no message, the staging
    folder left behind) and lose a Ctrl-C that arrived just before the import; in a user's program
    it would replace the program's own handler. Restoring the handler after the import would
    leave that window open while libgmsh loads (a tenth of a second), so during the import the
    module sees a ``signal.signal`` that changes nothing for SIGINT; ``oldsig`` is then cleared
    so that ``finalize`` leaves the handler alone too."""
    loaded = sys.modules.get("gmsh")
    if loaded is not None:
        return loaded
    real = signal.signal

    def keep_sigint(signum, handler):
        return signal.getsignal(signum) if signum == signal.SIGINT else real(signum, handler)

    signal.signal = keep_sigint
    try:
        import gmsh
    finally:
        signal.signal = real
    pinned("gmsh", "gmsh", GMSH_SERIES, patch="keeping SIGINT through Gmsh's import",
           otherwise="applied all the same (SIGINT kept as it was; oldsig cleared if the module has one)")
    if hasattr(gmsh, "oldsig"):
        gmsh.oldsig = None
    return gmsh
