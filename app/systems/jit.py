"""The form compiler's and JIT compiler's parameters, fixed by the app.

DOLFINx and FFCx merge their defaults with ``dolfinx_jit_parameters.json`` and
``ffcx_parameters.json`` read from the current directory and from ``~/.config``. A file of that
name in the folder a study is run from (a downloaded study folder, say) could otherwise set C
compiler flags, the folder compiled code is written to, or the scalar type of every form. Every
function space, form and expression of the app is therefore built with ``FORM_PARAMS`` and
``JIT_PARAMS`` below, which give every parameter a value, and the files are not read at all
(:func:`app.common.runtime.ignore_jit_settings_files`: a FIFO or a malformed file of that name
cannot hang or stop a run).

The JIT cache stays where DOLFINx puts it (``$XDG_CACHE_HOME/fenics``, default
``~/.cache/fenics``) when that folder can be written; else it is this user's folder in the
temporary folder, with a warning (app/common/cache.py). ``timeout`` is how long a process waits for another process that is
compiling the same form (two runs of a sweep, or two test workers, on a fresh cache): DOLFINx's
10 s is too short on a loaded machine, where the wait then ends in an error. FFCx claims a form's
C file before it compiles it; a process killed while compiling leaves the claim, and every later
process compiling that form waits for it. FFCx says so only in INFO records (``verbosity`` 20
below lets them through), so :func:`params` attaches the filter :class:`WaitNotice` to FFCx's
logger (:func:`app.common.runtime.filter_ffcx_log`), which turns the first of them into one
warning naming the claim and its age and drops FFCx's other INFO records.
"""
from __future__ import annotations

import logging
import os
import time

from app.common import runtime
from app.common.cache import cache_dir

#: FFCx's parameters (ffcx.parameters.FFCX_DEFAULT_PARAMETERS, FFCx 0.5), all given
FORM_PARAMS: dict = {"epsilon": 1e-14, "scalar_type": "double", "tabulate_tensor_void": False,
                     "table_rtol": 1e-6, "table_atol": 1e-9, "assume_aligned": -1, "padlen": 1,
                     "verbosity": 20}

#: DOLFINx's JIT parameters (dolfinx.jit.DOLFINX_DEFAULT_JIT_PARAMETERS, DOLFINx 0.5), all given
#: but ``cache_dir``, which :func:`params` adds (app/common/cache.py)
JIT_PARAMS: dict = {"cffi_debug": False, "cffi_extra_compile_args": ["-O2", "-g0"], "cffi_verbose": False,
                    "cffi_libraries": None, "timeout": 600}


log = logging.getLogger(__name__)


class WaitNotice(logging.Filter):
    """A filter on FFCx's logger: its "Waiting for X.c.cached to appear." (logged once a second
    while another process holds the claim ``X.c``) becomes one warning per claim, with the
    claim's age and what to do; FFCx's other records below WARNING are dropped, as they were at
    its default ``verbosity`` (FFCx calls ``logging.basicConfig()`` on import, so they would
    otherwise be printed)."""

    PREFIX, SUFFIX = "Waiting for ", " to appear."

    def __init__(self):
        super().__init__()
        self.seen: set[str] = set()

    def filter(self, record: logging.LogRecord) -> bool:
        """Pass FFCx's warnings and errors; note a wait; drop the rest."""
        if record.levelno >= logging.WARNING:
            return True
        text = record.getMessage()
        if text.startswith(self.PREFIX) and text.endswith(self.SUFFIX):
            self._notice(text[len(self.PREFIX):-len(self.SUFFIX)])
        return False

    def _notice(self, ready: str) -> None:
        if ready in self.seen:
            return
        self.seen.add(ready)
        claim = ready[:-len(".cached")] if ready.endswith(".cached") else ready
        try:
            age = f"{time.time() - os.path.getmtime(claim):.0f} s old"
        except OSError:
            age = "age unknown"
        log.warning("waiting for another process to compile a form into the JIT cache (its claim %s is %s); "
                    "if no other FEniCSx program is running, the claim was left by a killed process: delete "
                    "that file (this run waits up to %d s)", claim, age, JIT_PARAMS["timeout"])


def params() -> dict:
    """Keyword arguments for ``dolfinx.fem.form``, ``FunctionSpace``, ``VectorFunctionSpace`` and
    ``Expression``: fresh copies (DOLFINx writes ``scalar_type`` into the dict it is given).
    Raises :class:`app.common.cache.CacheUnusable` when no cache folder can be written."""
    runtime.filter_ffcx_log(WaitNotice)
    runtime.ignore_jit_settings_files()
    return {"form_compiler_params": dict(FORM_PARAMS), "jit_params": dict(JIT_PARAMS, cache_dir=cache_dir("fenics"))}
