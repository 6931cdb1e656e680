"""The public Python API: load a scene, run its study, read typed results.

Example (the paper's block; about 10 s on one core):

```python
import app
scene = app.load_scene("app/scenes/villechaise_block.yaml")
r = app.run_study(scene)
print(r.final.min_mu())           # 1.7048: MCEIP-mu (21)-(23) at the final state
r.first_instability().counts()    # '7 stick / 11 slip / 3 free'
```

[`run_study`][app.api.run_study] computes and returns; it writes nothing (no results folder, no
pictures, no ParaView files: the scene's `outputs` section is for the command line,
`python -m app run`). Save a result with `json.dump(r.to_json(), f)`: that is the CLI's
`results.json`. Under `mpirun` every rank calls [`run_study`][app.api.run_study] (it is
collective on `comm`) and gets the same result.
"""
from __future__ import annotations

import pathlib
from typing import TYPE_CHECKING, Any, Mapping

from mpi4py import MPI

from app.io.result import (
    CriticalMu,
    MceipResult,
    MceipSolution,
    NecessaryResult,
    Node,
    StateResult,
    StudyResult,
    SufficientResult,
)
from app.scene.schema import Scene, SceneError, parse_scene
from app.scene.schema import load_scene as _load_scene_file

if TYPE_CHECKING:
    from app.analyses.mceip_mu.proven import MuProof

__all__ = ["CriticalMu", "MceipResult", "MceipSolution", "MuProof", "NecessaryResult", "Node", "Scene", "SceneError",
           "StateResult", "StudyResult", "SufficientResult", "load_scene", "mceip_mu", "run_study"]


def mceip_mu(A0, A1, cap: float, pairs=None, seconds: float | None = None, want_all: bool = True,
             onset_nodes: int = 20000, all_nodes: int = 4000) -> "MuProof":
    """Proven critical friction coefficients of a condensed pencil ``A0 + mu A1`` (eqs. (21)-(23)).

    For pencils from other codes: the same prover and independent checker the studies use
    (`app.analyses.mceip_mu`, docs/proofs.md). ``pairs``: index pairs that may not both slip
    (zero-reaction nodes). The budgets are ``onset_nodes`` and ``all_nodes`` proof-tree nodes (the
    same answer on any machine); ``seconds`` is only a wall-clock safety stop (``None``: none; a
    claim it ends says "stopped by the time limit"). Returns a `MuProof`: ``onset`` and
    ``all`` claims (each ``proven`` only when the checker accepted it), the solutions with proven
    enclosures, the proof log (``log.to_json()``) and timings.
    """
    from app.analyses.mceip_mu.proven import mceip_mu as _mceip_mu
    return _mceip_mu(A0, A1, cap, pairs=pairs, seconds=seconds, want_all=want_all, onset_nodes=onset_nodes,
                     all_nodes=all_nodes)


def __getattr__(name: str):
    """``MuProof``, imported on first use."""
    if name == "MuProof":
        from app.analyses.mceip_mu.proven import MuProof
        return MuProof
    raise AttributeError(f"module 'app.api' has no attribute {name!r}")


def load_scene(scene: str | pathlib.Path | Mapping[str, Any]) -> Scene:
    """A validated scene from a YAML file path or from a dictionary with the same keys.

    Raises `SceneError` whose message is one line naming the key, the value and what is
    allowed (the keys are listed in ``docs/scene-keys.md``).
    """
    if isinstance(scene, Mapping):
        return parse_scene(dict(scene), source="scene")
    return _load_scene_file(scene)


def run_study(scene: Scene, comm: MPI.Comm = MPI.COMM_WORLD, progress: bool = False) -> StudyResult:
    """Run the scene's loading study and analyses (collective on ``comm``); writes nothing.

    Scene -> system (two particles, or the FE block: Gmsh + DOLFINx) -> loading path ->
    classification of every equilibrium state -> the scene's analyses once per distinct
    classification (app/study/run.py). Raises ``app.common.errors.UnreachableLoad`` when the
    prescribed path cannot reach the requested normal force. A scene with a ``sweep`` or
    ``refinement`` section is a batch of studies: run it with ``python -m app run``.
    ``progress``: the command line's progress lines on standard error (rank 0), at least every
    5 s while a stage runs; none by default.

    No signal handler, ``sys`` hook or environment variable is installed: the calling program's
    own stay as they are (`app.common.runtime.install` with ``command_line=False``). The study
    catches the warnings raised inside it and, where it first uses a library, puts a filter on
    FFCx's logger, stops DOLFINx and FFCx from reading their settings files and keeps SIGINT as it
    was through Gmsh's import; these three stay after it returns (`app.common.runtime`).
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"run_study needs a Scene (from app.load_scene), not {type(scene).__name__}")
    for key in ("sweep", "refinement"):
        if getattr(scene, key, None) is not None:
            raise SceneError(f"scene '{scene.name}': has a '{key}' section: it is a batch of studies, "
                             f"run it with: python -m app run SCENE")
    from app.common import runtime
    from app.common.progress import Progress
    from app.study.run import study  # PETSc, and DOLFINx for a block, only when running
    runtime.install(command_line=False)
    return study(scene, comm, Progress(enabled=bool(progress), comm=comm), outdir=None)
