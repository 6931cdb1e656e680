"""The form compiler's and JIT compiler's parameters, fixed by the app.

DOLFINx and FFCx merge their defaults with ``dolfinx_jit_parameters.json`` and
``ffcx_parameters.json`` read from the current directory and from ``~/.config``. A file of that
name in the folder a study is run from (a downloaded study folder, say) could otherwise set C
compiler flags, the folder compiled code is written to, or the scalar type of every form. Every
function space, form and expression of the app is therefore built with ``FORM_PARAMS`` and
``JIT_PARAMS`` below, which give every parameter a value and so take priority over both files.

The JIT cache stays where DOLFINx puts it (``$XDG_CACHE_HOME/fenics``, default
``~/.cache/fenics``). ``timeout`` is how long a process waits for another process that is
compiling the same form (two runs of a sweep, or two test workers, on a fresh cache): DOLFINx's
10 s is too short on a loaded machine, where the wait then ends in an error.
"""
from __future__ import annotations

import os
from pathlib import Path

#: FFCx's parameters (ffcx.parameters.FFCX_DEFAULT_PARAMETERS, FFCx 0.5), all given
FORM_PARAMS: dict = {"epsilon": 1e-14, "scalar_type": "double", "tabulate_tensor_void": False,
                     "table_rtol": 1e-6, "table_atol": 1e-9, "assume_aligned": -1, "padlen": 1,
                     "verbosity": 30}

#: DOLFINx's JIT parameters (dolfinx.jit.DOLFINX_DEFAULT_JIT_PARAMETERS, DOLFINx 0.5), all given
JIT_PARAMS: dict = {"cache_dir": Path(os.getenv("XDG_CACHE_HOME", default=Path.home() / ".cache")) / "fenics",
                    "cffi_debug": False, "cffi_extra_compile_args": ["-O2", "-g0"], "cffi_verbose": False,
                    "cffi_libraries": None, "timeout": 600}


def params() -> dict:
    """Keyword arguments for ``dolfinx.fem.form``, ``FunctionSpace``, ``VectorFunctionSpace`` and
    ``Expression``: fresh copies (DOLFINx writes ``scalar_type`` into the dict it is given)."""
    return {"form_compiler_params": dict(FORM_PARAMS), "jit_params": dict(JIT_PARAMS)}
