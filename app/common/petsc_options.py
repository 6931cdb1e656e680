"""PETSc options from the command line, and the options prefixes of the app's solvers.

``python -m app run scene.yaml -cd_necessary_eps_monitor`` works as in any FEniCSx code: app/cli/main.py
splits the PETSc-style options off the command line (:func:`split_petsc_options`) and puts them in
PETSc's options database for the run (:func:`command_line_options`); every KSP, SNES and EPS the app
creates has one of the prefixes of :data:`PREFIXES` and reads the database after the app's own
settings (:func:`app.linalg.with_prefix`, :func:`app.linalg.from_options`). Nothing else fills the
database: a scene file cannot set PETSc options.

This module does not import petsc4py, so that the CLI can initialise PETSc with the options.
"""
from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager

#: The options prefix of every PETSc/SLEPc solver the app creates, and what it solves
#: (README.md and docs/petsc.md list them; tests/test_petsc.py checks that the list is complete).
PREFIXES = {
    "cd_loading_": "SNES VI of each contact increment along the loading path (its KSP: cd_loading_ksp_, "
                   "cd_loading_pc_)",
    "cd_flex_": "KSP: LU factorisation of the stiffness K (contact flexibility, unit loads)",
    "cd_necessary_": "EPS: smallest eigenvalues of sym K*(mu) and sym M*(mu), condition (19) "
                     "(shift-and-invert: cd_necessary_st_ksp_)",
    "cd_sufficient_": "EPS: real eigenpairs of K* x = theta M* x, conditions (17)-(18)",
    "cd_lambda2_": "EPS: largest omega^2 of the free block K_ff x = omega^2 M_ff x (MCEIP-lambda^2)",
    "cd_dynamic_": "KSP: factorisation of K + t M for the dynamic contact Schur complement Z(t) "
                   "(MCEIP-lambda^2 on the contact DOFs)",
    "cd_shifted_": "KSP: MUMPS partial LDL^T factorisation of K - sigma I and M - sigma I, Schur complement "
                   "onto the contact DOFs (the values of condition (19))",
    "cd_static_": "KSP: MUMPS partial LDL^T factorisation eliminating the mixed element's pressure from the "
                  "contact block of K (the values of condition (19))",
    "cd_inertia_": "KSP: LDL^T inertia counts (proven bounds of MCEIP-lambda^2, shifts of condition (19))",
    "cd_mcp_": "SNES VI of the bordered MCP search of MCEIP-lambda^2 (12)-(14) (its KSP: cd_mcp_ksp_)",
    "cd_mcp_free_": "KSP: LU of the free block in the bordered MCP's Schur complement",
    "cd_spd_check_": "KSP: MUMPS inertia of a user's K and M (matrices system: both must be SPD)",
}


def _petsc_style(token: str) -> bool:
    """A PETSc option name: one dash, a letter, then letters, digits and at least one underscore
    (``-cd_necessary_eps_monitor``, ``-log_view``), never an option of app/cli/main.py."""
    return (len(token) > 2 and token[0] == "-" and token[1].isalpha()
            and "_" in token and token[1:].replace("_", "").isalnum())


def _is_value(token: str) -> bool:
    """A PETSc option's value: not an option (negative numbers are values) and not a scene file."""
    if token.lower().endswith((".yaml", ".yml")):
        return False
    if not token.startswith("-"):
        return True
    try:
        float(token)
        return True
    except ValueError:
        return False


def split_petsc_options(argv: list[str]) -> tuple[list[str], list[str]]:
    """``(app arguments, PETSc options)`` of a command line: each PETSc-style option with the
    value that follows it, if any (a scene file ``*.yaml`` is never taken as a value). Raises
    ValueError (one line) for a ``-cd_`` option whose prefix is not one of :data:`PREFIXES`."""
    rest: list[str] = []
    petsc: list[str] = []
    i = 0
    while i < len(argv):
        token = argv[i]
        if token == "--":
            rest.extend(argv[i:])
            break
        if not _petsc_style(token):
            rest.append(token)
            i += 1
            continue
        name = token[1:]
        if name.startswith("cd_") and not name.startswith(tuple(PREFIXES)):
            raise ValueError(f"{token}: unknown options prefix; the app's prefixes are "
                             + ", ".join(PREFIXES) + " (for example -cd_necessary_eps_monitor)")
        petsc.append(token)
        if i + 1 < len(argv) and _is_value(argv[i + 1]):
            petsc.append(argv[i + 1])
            i += 1
        i += 1
    return rest, petsc


@contextmanager
def command_line_options(options: list[str]) -> Iterator[None]:
    """PETSc's options database holds ``options`` (from :func:`split_petsc_options`) inside the
    block. Before PETSc starts, petsc4py is initialised with them (so that start-up options such
    as ``-log_view`` work too) and with ``-skip_petscrc``: no ``.petscrc`` or ``petscrc`` file is
    read (one in the folder a study is run from is not the user's); ``PETSC_OPTIONS`` still is.
    If PETSc is already running (the CLI called in-process), the options are inserted and removed
    again on leaving the block."""
    if "petsc4py.PETSc" not in sys.modules:
        # MPI first, by mpi4py (MPI_Init_thread, MPI_THREAD_MULTIPLE: a sweep's rank 0 dispatches
        # from a thread); PETSc started first would call plain MPI_Init
        import petsc4py
        from mpi4py import MPI  # noqa: F401
        # -skip_petscrc: PETSc would read .petscrc and petscrc in the current folder (a study
        # folder received from someone) and inject their options (-mat_view ascii:FILE writes FILE)
        petsc4py.init([sys.argv[0] or "python", "-skip_petscrc", *options])
        yield
        return
    if not options:
        yield
        return
    from petsc4py import PETSc as _PETSc
    db = _PETSc.Options()
    before = set(db.getAll())
    db.insertString(" ".join(options))
    try:
        yield
    finally:
        for name in set(db.getAll()) - before:
            db.delValue(name)
