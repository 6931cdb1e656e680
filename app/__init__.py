"""Divergence instabilities of elastic bodies in frictional contact (FEniCSx, PETSc SNES VI, SLEPc).

The public API (:mod:`app.api`, re-exported here)::

    import app
    r = app.run_study(app.load_scene("app/scenes/villechaise_block.yaml"))
    print(r.final.min_mu())   # 1.7048

The method and its notation: ``docs/method.md``; the scene keys: ``docs/scene-keys.md``.
The names are imported on first use, so ``python -m app`` (app/cli/main.py) still sets its
environment (one BLAS thread per MPI rank) before numpy or MPI are loaded.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

from app.version import __version__  # noqa: F401 - ``app.__version__``, printed by ``python -m app --version``

__all__ = ["CriticalMu", "MceipResult", "MceipSolution", "MuProof", "NecessaryResult", "Node", "Scene", "SceneError",
           "StateResult", "StudyResult", "SufficientResult", "load_scene", "mceip_mu", "run_study"]

if TYPE_CHECKING:
    from app.api import (
        CriticalMu,
        MceipResult,
        MceipSolution,
        MuProof,
        NecessaryResult,
        Node,
        Scene,
        SceneError,
        StateResult,
        StudyResult,
        SufficientResult,
        load_scene,
        mceip_mu,
        run_study,
    )


def __getattr__(name: str) -> Any:
    """The public names of :mod:`app.api`, imported on first use (PEP 562)."""
    if name in __all__:
        from app import api
        return getattr(api, name)
    raise AttributeError(f"module 'app' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(list(globals()) + __all__)
