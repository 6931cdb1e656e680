"""Direct solvers: the one place where LU/Cholesky and MUMPS options are set.

Every factorisation in the app (the stiffness K of the loading path, the bordered MCP Jacobians,
the shift-and-invert spectral transformations, the inertia counts) is configured here, so the
choice of factor package and its MUMPS controls exist once.

- :func:`configure_direct` turns an existing KSP (e.g. ``snes.getKSP()`` or
  ``eps.getST().getKSP()``) into a direct solve.
- :func:`lu_solver` creates, configures and sets up a KSP for a matrix; the caller owns it and
  calls ``destroy()`` (or uses :func:`lu` as a context manager, which does).

PETSc options: every KSP, SNES and EPS the app creates has one of the options prefixes of
:data:`PREFIXES` and reads PETSc's options database (``setFromOptions``) after the app's own
settings, so ``python -m app run scene.yaml -cd_necessary_eps_monitor`` works as in any FEniCSx
code; only the command line fills that database (:mod:`app.common.petsc_options`), never a scene
file. :func:`owned` is the context manager that destroys a PETSc object on every path.

Also here: :func:`set_linesearch` (a SNES line search default through the options database,
removed at once), :func:`one_blas_thread` (one BLAS thread around dense numpy/LAPACK work) and
:func:`flush_subnormals` (around the large factorisations of well-conditioned matrices) and
:func:`set_up`, :func:`eps_solve` and :func:`snes_solve` (a factorisation, an eigensolve, a SNES VI
run, with the interpreter released, so that progress and signals go on).
"""
from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import functools
import platform
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Literal, Optional

from petsc4py import PETSc

from app.common import hard_stop
from app.common.petsc_options import PREFIXES

Factor = Literal["lu", "cholesky"]


def with_prefix(obj, prefix: str):
    """Give the PETSc/SLEPc solver ``obj`` the options prefix ``prefix`` (one of :data:`PREFIXES`)
    and the monitor :func:`_python_turn`; returns ``obj``. Call right after ``create()``, so that
    its inner solvers (a SNES's KSP, an EPS's ST) inherit the prefix; :func:`from_options` after the
    app's settings."""
    assert prefix in PREFIXES, prefix
    obj.setOptionsPrefix(prefix)
    obj.setMonitor(_python_turn)
    return obj


def _python_turn(*_) -> None:
    """A monitor that does nothing: at every iteration of the solver the interpreter runs, and with
    it the signal handlers. A Ctrl-C or SIGTERM during a long KSP, SNES or EPS solve (whose C code
    holds the interpreter until it returns) is raised there as the KeyboardInterrupt of the command
    line's handler (app/common/runtime.py), which petsc4py passes out of ``solve()``. Monitors set by
    options (``-cd_necessary_eps_monitor``) are kept beside it."""


def from_options(obj):
    """``obj.setFromOptions()``: options of the command line override the app's settings."""
    obj.setFromOptions()
    return obj


@contextmanager
def owned(obj) -> Iterator:
    """``with owned(PETSc.KSP().create(comm)) as ksp:``: ``obj`` destroyed on leaving the block,
    errors included (petsc4py 3.18 only queues a dropped object as garbage: it is never freed)."""
    try:
        yield obj
    finally:
        obj.destroy()


def configure_direct(ksp: PETSc.KSP, *, factor: Factor = "lu", mumps: Optional[bool] = None,
                     inertia: bool = False, shift: Optional[float] = None,
                     ordering: Optional[str] = None) -> PETSc.KSP:
    """Make ``ksp`` a direct solve (``preonly`` + ``factor``); returns ``ksp``.

    ``mumps``: use MUMPS; ``None`` (default) means "MUMPS when the KSP's communicator has more
    than one rank" (PETSc's own serial factorisation is faster on the small serial problems).
    ``inertia``: MUMPS controls for reporting the inertia of an LDL^T factorisation (ICNTL(13) = 1,
    no ScaLAPACK root; ICNTL(24) = 1, null pivot detection); sets the factor up, so the
    operators must already be set. ``shift``/``ordering`` apply to PETSc's own factorisation only
    (a NONZERO pivot shift, e.g. 1e-14; an ordering such as ``"qmd"``).
    """
    ksp.setType("preonly")
    pc = ksp.getPC()
    pc.setType(factor)
    use_mumps = ksp.getComm().getSize() > 1 if mumps is None else mumps
    if use_mumps:
        pc.setFactorSolverType("mumps")
        if inertia:
            pc.setFactorSetUpSolverType()
            F = pc.getFactorMatrix()
            F.setMumpsIcntl(13, 1)
            F.setMumpsIcntl(24, 1)
    else:
        if shift is not None:
            pc.setFactorShift(PETSc.Mat.FactorShiftType.NONZERO, shift)
        if ordering is not None:
            pc.setFactorOrdering(ordering)
    return ksp


@contextmanager
def mumps_null_pivots(prefix: str) -> Iterator[None]:
    """Context: MUMPS factorisations made inside it by a solver with options prefix ``prefix`` (e.g.
    an EPS's ``"cd_necessary_st_"``) detect null pivots (ICNTL(24) = 1), without which PETSc 3.18
    cannot report their inertia; for solvers whose KSP gets its operators only when set up (a
    SLEPc ST), where :func:`configure_direct` cannot reach the factor. Through the options
    database, unless the command line set the option, and removed again on exit."""
    name = f"{prefix}mat_mumps_icntl_24"
    opts = PETSc.Options()
    if opts.hasName(name):
        yield
        return
    opts.setValue(name, 1)
    try:
        yield
    finally:
        opts.delValue(name)


def set_linesearch(snes: PETSc.SNES, kind: str) -> None:
    """Make ``kind`` (e.g. ``"basic"``: full Newton steps) the line search of ``snes`` unless the
    command line chose one (``-<prefix>snes_linesearch_type``). petsc4py 3.18 has no SNESLineSearch
    object, so this goes through the options database under the SNES's own prefix, and the
    option is removed at once (nothing is left in the database)."""
    name = f"{snes.getOptionsPrefix() or ''}snes_linesearch_type"
    opts = PETSc.Options()
    if opts.hasName(name):
        return
    opts.setValue(name, kind)
    try:
        snes.setFromOptions()
    finally:
        opts.delValue(name)


def set_up(solver) -> None:
    """``solver.setUp()`` for a KSP (its factorisation) or an EPS (its spectral transformation's
    factorisation), called through PETSc's or SLEPc's C function with ctypes, which releases the
    interpreter for the call: petsc4py's own ``setUp()`` holds it until the C code returns, so
    during a long factorisation (6 s at 10^6 DOFs) no other thread ran, the progress lines
    stopped, and a Ctrl-C waited. Released, the progress thread goes on and the signal watchdog
    (:mod:`app.common.hard_stop`) can stop the run within a second of the signal. Nothing here
    calls back into Python (monitors run in ``solve``, not in ``setUp``). A PETSc error raises
    :class:`PETSc.Error` with PETSc's code, as petsc4py's call does."""
    _released(solver, "SetUp")


def eps_solve(eps) -> None:
    """``eps.solve()`` with the interpreter released (as :func:`set_up`): one restart of a
    shift-and-invert Krylov-Schur solve is some 30 triangular solves, 10 s at 10^6 DOFs, between
    two calls of its monitor. The monitors still run: slepc4py's trampoline takes the interpreter
    for them, and an exception raised there (the KeyboardInterrupt of a signal, taken in the
    monitor) is raised here again."""
    _released(eps, "Solve")


def snes_solve(snes, b, x) -> None:
    """``snes.solve(b, x)`` with the interpreter released (as :func:`eps_solve`): each Newton step
    of a SNES VI run on the full system factorises its reduced Jacobian (minutes at 10^6 DOFs, a
    new symbolic analysis at every change of the active set). The residual, Jacobian and
    convergence test callbacks take the interpreter, and a signal taken there is raised here."""
    _released(snes, "Solve", b, x)


def _released(obj, verb: str, *args) -> None:
    fn = _c_function(type(obj).__name__, verb)
    try:
        with hard_stop.released(calls_back=verb == "Solve"):      # a solve's callbacks take signals
            err = fn(ctypes.c_void_p(obj.handle), *(ctypes.c_void_p(None if a is None else a.handle) for a in args))
    except SystemError as exc:
        # a monitor raised: the C function returned with that exception set, which Python reports
        # as a SystemError caused by it
        if exc.__cause__ is not None:
            raise exc.__cause__ from None
        raise
    if err != 0:
        raise PETSc.Error(err)


@functools.lru_cache(maxsize=None)
def _c_function(kind: str, verb: str):
    """The C function ``<kind><verb>`` (``KSPSetUp``, ``EPSSetUp``, ``EPSSolve``, ``SNESSolve``) from
    the library petsc4py or slepc4py is linked to, looked up once per process."""
    if kind == "EPS":
        from slepc4py import SLEPc
        module = SLEPc
    elif kind in ("KSP", "SNES"):
        module = PETSc
    else:
        raise TypeError(f"a KSP, an EPS or a SNES, not {kind}")
    fn = getattr(ctypes.CDLL(module.__file__), f"{kind}{verb}")
    fn.argtypes = [ctypes.c_void_p] * (3 if (kind, verb) == ("SNES", "Solve") else 1)
    fn.restype = ctypes.c_int
    return fn


def lu_solver(A: PETSc.Mat, *, prefix: str, factor: Factor = "lu", mumps: Optional[bool] = True,
              inertia: bool = False, ordering: Optional[str] = None) -> PETSc.KSP:
    """A KSP on ``A``'s communicator that solves with the factors of ``A`` (MPI collective).

    Defaults to a MUMPS LU factorisation (``mumps=None``: MUMPS only in parallel, see
    :func:`configure_direct`; ``inertia``, ``ordering`` likewise), then reads the options under
    ``prefix`` (one of :data:`PREFIXES`) and factorises it here. The caller owns the KSP and must
    ``destroy()`` it; :func:`lu` is the context-manager form.
    """
    ksp = with_prefix(PETSc.KSP().create(A.getComm()), prefix)
    try:
        ksp.setOperators(A)
        configure_direct(ksp, factor=factor, mumps=mumps, inertia=inertia, ordering=ordering)
        from_options(ksp)
        set_up(ksp)
    except BaseException:
        ksp.destroy()
        raise
    return ksp


_CONTROLLER: list = []


def _controller():
    """The BLAS libraries' controller (threadpoolctl), inspected once per process, or None."""
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:              # pragma: no cover - threadpoolctl is a dependency
        return None
    if not _CONTROLLER:
        _CONTROLLER.append(ThreadpoolController())
    return _CONTROLLER[0]


def blas_threads_now() -> int:
    """The BLAS threads dense work runs with now (the largest of the loaded BLAS libraries; 1
    when none is known)."""
    c = _controller()
    if c is None:
        return 1
    counts = [lib.num_threads for lib in c.lib_controllers if lib.user_api == "blas"]
    return max(counts, default=1)


def blas_threads(n: int | None):
    """Context: ``n`` BLAS threads (None: unchanged), the previous number again afterwards (used
    by :func:`app.common.waiting.alone_on_rank_zero` while the other ranks wait)."""
    c = _controller() if n is not None else None
    if c is None:
        return contextlib.nullcontext()
    return c.limit(limits=int(n), user_api="blas")


def start_blas_workers(n: int) -> None:
    """Make sure ``n`` BLAS threads exist, the new ones started with subnormal numbers flushed.

    A thread inherits the floating-point environment (and the CPU mask) of the thread that starts
    it, and OpenBLAS keeps the threads it has started when fewer are asked for. Its threads
    started here flush subnormals for good, so that a factorisation inside
    :func:`flush_subnormals` runs at full speed on every thread (with a thread that does not,
    MUMPS's factorisation of ``K + t M`` at ``t = 1e12`` and 10^6 DOFs took 11.5 s on two threads
    and 5.5 s on one; 3.6 s on two that flush). Called by
    :func:`app.common.waiting.alone_on_rank_zero`, the one place where work runs on more than one
    BLAS thread under ``mpirun`` (the app sets one per rank): the values of (19) and
    MCEIP-lambda^2's reduction, floating-point analyses (``rigorous: false``), never MCEIP-mu's
    provers, whose rounding bounds are taken with gradual underflow."""
    import numpy as np
    with flush_subnormals(), blas_threads(n):
        a = np.ones((256, 256))
        a @ a                         # OpenBLAS starts its threads by the first threaded call at the latest


def one_blas_thread():
    """Context: one BLAS thread around small batched dense work (OpenBLAS threads make stacks
    of 20 x 20 solves 10-20x slower on this kind of machine, and the contact increments' dense
    2n x 2n LU factorisations 2-3x slower); all threads again afterwards. The BLAS libraries are
    inspected once per process (``threadpool_limits`` scans every loaded library on each call:
    2-4 ms)."""
    c = _controller()
    if c is None:
        return contextlib.nullcontext()
    return c.limit(limits=1, user_api="blas")


#: byte offset of ``__mxcsr`` in glibc's x86-64 ``fenv_t`` (bits/fenv.h), and its flush-to-zero
#: (FTZ, bit 15) and denormals-are-zero (DAZ, bit 6) bits
_MXCSR_OFFSET = 28
_FTZ_DAZ = 0x8040


@contextmanager
def flush_subnormals() -> Iterator[None]:
    """Context: subnormal floating-point numbers are flushed to zero in this thread (x86-64 SSE
    FTZ and DAZ, set through glibc's ``fegetenv``/``fesetenv``; nothing elsewhere), the previous
    floating-point environment restored afterwards.

    A sparse factor of a well-conditioned matrix (a consistent mass matrix, ``M - sigma I``,
    ``K + t M`` for large ``t``) decays exponentially away from the diagonal, and at 10^6 DOFs
    nested dissection's fill reaches entries far below 1e-308 of the diagonal: arithmetic on
    subnormal numbers is some 100x slower on x86 and made MUMPS's Cholesky factorisation of the
    mass matrix 2.4x slower than that of the stiffness matrix with the same pattern and flop
    count (15.0 s against 6.3 s on one thread). Flushing them changes each affected entry by less
    than 2.3e-308 in absolute value, far below the factorisation's rounding. BLAS threads already
    running keep their own setting. Not for code whose rounding bounds assume gradual underflow
    (the provers)."""
    libm = _libm() if platform.machine() in ("x86_64", "AMD64") else None
    if libm is None:
        yield
        return
    env = (ctypes.c_ubyte * 64)()            # fenv_t is 32 bytes on x86-64; room to spare
    if libm.fegetenv(env) != 0:
        yield
        return
    saved = bytes(env)
    mxcsr = int.from_bytes(saved[_MXCSR_OFFSET:_MXCSR_OFFSET + 4], "little") | _FTZ_DAZ
    env[_MXCSR_OFFSET:_MXCSR_OFFSET + 4] = list(mxcsr.to_bytes(4, "little"))
    libm.fesetenv(env)
    try:
        yield
    finally:
        libm.fesetenv((ctypes.c_ubyte * 64)(*saved))


@functools.lru_cache(maxsize=1)
def _libm():
    """The C library's libm (fegetenv, fesetenv), or None; looked up once per process."""
    try:
        lib = ctypes.CDLL(ctypes.util.find_library("m") or "libm.so.6")
        lib.fegetenv.argtypes = lib.fesetenv.argtypes = [ctypes.c_void_p]
        lib.fegetenv.restype = lib.fesetenv.restype = ctypes.c_int
    except (OSError, AttributeError):
        return None
    return lib


def to_scipy(A: PETSc.Mat):
    """A sequential PETSc AIJ matrix as a SciPy CSR matrix (a copy: ``A`` is left as it is, where
    petsc4py's ``convert`` without a target would convert it in place)."""
    import scipy.sparse
    ai, aj, av = A.getValuesCSR()
    return scipy.sparse.csr_matrix((av, aj, ai), shape=A.getSize())


@contextmanager
def lu(A: PETSc.Mat, **kwargs) -> Iterator[PETSc.KSP]:
    """``with lu(A) as ksp:`` -- :func:`lu_solver` whose KSP is destroyed on leaving the block."""
    ksp = lu_solver(A, **kwargs)
    try:
        yield ksp
    finally:
        ksp.destroy()
