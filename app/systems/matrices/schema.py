"""Scene schema of ``system.type: matrices``: a discrete system given as matrix files.

For users of other finite element codes: the stiffness K (and the mass M for the dynamic
analyses) as Matrix Market (``.mtx``, ``.mm``), NumPy (``.npy``) or PETSc binary files (any other
name), the contact nodes as DOF pairs, and either

* ``state``: the static reactions of one equilibrium state (analyses only), or
* ``forces``: phases of applied force increments; the quasi-static path is then solved with the
  block's frictional contact solver (app/loading/contact.py) from zero displacement.

Contact entries are ``[T, N, sign_N]`` or ``[T, N, sign_T, sign_N]``: the tangential and normal
DOF (0-based rows of K) and the signs that turn them into the paper's axes, ``u_T = sign_T u[T]``,
``u_N = sign_N u[N]`` with N the body's outward normal (pointing into the obstacle): a node whose
DOF N points away from the obstacle has ``sign_N = -1``. ``gaps`` are the initial normal gaps
(>= 0; default 0: touching). Reactions in ``state`` are in the paper's axes: ``[r_T, r_N]`` with
``r_N <= 0`` compressive. Files are read (and checked: square, symmetric, sizes, indices) when the
scene is validated, once per file.
"""
from __future__ import annotations

import pathlib
from typing import Annotated, Any, Literal, Optional, Union

import numpy as np
from pydantic import Field, ValidationInfo, field_validator, model_validator

from app.systems.schema import (
    MAGNITUDE_MAX,
    Finite,
    NonNegFloat,
    ResourcePathError,
    StrictModel,
    SystemPathError,
    context_limits,
    file_version,
    no_field_outputs,
    resolve_file,
)

_MATRIX_CACHE: dict[tuple, Any] = {}
_VECTOR_CACHE: dict[tuple, np.ndarray] = {}
_MM = (".mtx", ".mm")
SYMMETRY_RTOL = 1e-10          # |K - K^T| <= SYMMETRY_RTOL * max |K|
DYNAMIC_ANALYSES = ("necessary", "sufficient", "mceip_lambda2")


def _load(path: pathlib.Path, kind: str, limits=None):
    """Contents of a matrix or vector file, by its suffix: Matrix Market (``.mtx``, ``.mm``; may be
    sparse), NumPy ``.npy``, anything else PETSc binary (read without PETSc: its ``.info`` sidecar
    is ignored). The header is checked against ``limits`` first (app/systems/matrices/files.py)."""
    from app.systems.matrices import files as matrix_files
    from app.systems.schema import Limits
    limits = limits if limits is not None else Limits()
    cap, how = limits.memory_cap()
    matrix_files.check_header(matrix_files.header(path, kind), path, limits.max_dofs, cap, how)
    suffix = path.suffix.lower()
    if suffix in _MM:
        import scipy.io
        return scipy.io.mmread(str(path))
    if suffix == ".npy":
        return np.load(str(path), allow_pickle=False)
    return matrix_files.read_petsc(path, kind)


def _refuse(key: str, value: Any, path: pathlib.Path, err: Exception, what: str):
    """The one-line error of a file that cannot be read: a limit (exit 4 for memory) or the reader's reason."""
    from app.systems.matrices.files import MatrixFileError, kind_of
    if isinstance(err, MatrixFileError):
        cls = ResourcePathError if err.resource else SystemPathError
        return cls(key, value, str(err) if path.name in str(err) else f"{path.name}: {err}")
    return SystemPathError(key, value, f"cannot read {path.name} as a {kind_of(path)} {what} ({_reason(err)}); "
                           "formats: .mtx/.mm Matrix Market, .npy NumPy, anything else PETSc binary")


def _reason(err: Exception) -> str:
    """A reader's error on one line, for the user's message."""
    return f"{type(err).__name__}: {' '.join(str(err).split())[:120]}"


def _in_range(key: str, value: Any, path: pathlib.Path, data: np.ndarray, zero_ok: bool = False) -> None:
    """Entries within the magnitudes the app computes with (1e-100 ... 1e100, as the scene's numbers):
    beyond, products and sums of entries overflow or underflow double precision."""
    scale = float(np.max(np.abs(data))) if data.size else 0.0
    if scale > MAGNITUDE_MAX or (scale < 1 / MAGNITUDE_MAX and not (zero_ok and scale == 0)):
        raise SystemPathError(key, value, f"{path.name}: largest entry {scale:.3g} in magnitude, outside "
                              f"{1 / MAGNITUDE_MAX:g} ... {MAGNITUDE_MAX:g}: rescale the units")


def read_matrix(key: str, value: str, path: pathlib.Path, limits=None):
    """Sparse CSR copy of a matrix file (cached per file version), its header checked against
    ``limits`` (the scene's ``settings.limits``) first. Raises :class:`SystemPathError`."""
    import scipy.sparse as sp
    k = file_version(path)
    if k in _MATRIX_CACHE:
        return _MATRIX_CACHE[k]
    try:
        A = _load(path, "matrix", limits)
        if not sp.issparse(A) and np.ndim(A) != 2:
            raise ValueError(f"an array of {np.ndim(A)} dimensions: a matrix has 2")
    except Exception as err:   # noqa: BLE001 - any reader failure is the user's file
        raise _refuse(key, value, path, err, "matrix") from None
    if np.iscomplexobj(A.data if sp.issparse(A) else A):
        raise SystemPathError(key, value, f"{path.name}: complex entries; a real matrix is needed")
    A = sp.csr_matrix(A, dtype=float)
    A.eliminate_zeros()
    A.sort_indices()
    if A.ndim != 2 or A.shape[0] != A.shape[1] or A.shape[0] == 0:
        raise SystemPathError(key, value, f"{path.name}: shape {A.shape[0]} x {A.shape[1]}: a square, "
                              "non-empty matrix is needed")
    if not np.all(np.isfinite(A.data)):
        raise SystemPathError(key, value, f"{path.name}: entries that are not finite numbers")
    _in_range(key, value, path, A.data)
    _MATRIX_CACHE[k] = A
    return A


def read_vector(key: str, value: Any, path: Optional[pathlib.Path], limits=None) -> np.ndarray:
    """A force vector: inline list, or a Matrix Market / .npy / PETSc binary file (cached)."""
    if path is None:
        return np.asarray(value, dtype=float)
    import scipy.sparse as sp
    k = file_version(path)
    if k in _VECTOR_CACHE:
        return _VECTOR_CACHE[k]
    try:
        v = _load(path, "vector", limits)
        v = v.toarray() if sp.issparse(v) else np.asarray(v)
    except Exception as err:   # noqa: BLE001
        raise _refuse(key, value, path, err, "vector") from None
    if v.ndim == 2 and 1 in v.shape:
        v = v.ravel()
    if v.ndim != 1 or np.iscomplexobj(v) or not np.all(np.isfinite(v)):
        raise SystemPathError(key, value, f"{path.name}: a real vector (one column) of finite numbers is needed, "
                              f"got shape {v.shape}")
    v = v.astype(float)
    _in_range(key, value, path, v, zero_ok=True)
    _VECTOR_CACHE[k] = v
    return v


class ForcePhase(StrictModel):
    """One phase of applied forces: ``force`` (the increment of the whole phase) in ``steps`` equal steps."""

    force: Union[list[Finite], str] = Field(description="force increment of the phase: a vector file or a list")
    steps: Annotated[int, Field(ge=1, le=100000)] = Field(1, description="equal increments of the phase")

    @field_validator("force", mode="before")
    @classmethod
    def _force(cls, v: Any, info: ValidationInfo) -> Any:
        if isinstance(v, str):
            path = resolve_file("", v, info)
            read_vector("", v, path, context_limits(info))     # header checked against the limits, then read
            return str(path)
        if not isinstance(v, (list, tuple)) or not v:
            raise ValueError("allowed: a vector file path (relative to the scene file) or a list of numbers, "
                             "one per DOF")
        return v


class StaticState(StrictModel):
    """Reactions of one equilibrium state, paper axes: [r_T, r_N] per contact node, r_N <= 0."""

    reactions: Annotated[list[tuple[Finite, Finite]], Field(min_length=1)] = Field(
        description="[r_T, r_N] per contact node, paper axes (r_N <= 0)")
    u_T: Optional[list[Finite]] = Field(None, description="tangential displacements (reported only)")


def _contact_entry(i: int, e: Any) -> tuple[int, int, int, int]:
    allowed = ("allowed: [T, N, sign_N] or [T, N, sign_T, sign_N] with DOF indices (integers >= 0) and "
               "signs -1 or 1")
    if not isinstance(e, (list, tuple)) or len(e) not in (3, 4) or any(
            isinstance(x, bool) or not isinstance(x, int) for x in e):
        raise SystemPathError(f"{i}", e, allowed)
    T, N, *signs = e
    if len(signs) == 1:
        signs = [1] + signs
    if T < 0 or N < 0 or any(s not in (-1, 1) for s in signs):
        raise SystemPathError(f"{i}", e, allowed)
    if T == N:
        raise SystemPathError(f"{i}", e, "the tangential and normal DOF must differ")
    return int(T), int(N), int(signs[0]), int(signs[1])


class Matrices(StrictModel):
    """A discrete elastic system from matrix files (K SPD, M SPD) with contact DOF pairs."""

    type: Literal["matrices"]
    K: str = Field(description="stiffness matrix file (.mtx/.mm, .npy or PETSc binary), symmetric positive definite")
    M: Optional[str] = Field(None, description="mass matrix file; needed by necessary, sufficient, mceip_lambda2")
    contact: Annotated[list[Any], Field(min_length=1)] = Field(
        description="contact nodes: [T, N, sign_N] or [T, N, sign_T, sign_N] (0-based DOF indices)")
    gaps: Optional[list[NonNegFloat]] = Field(None, description="initial normal gaps (>= 0), one per contact node")
    positions: Optional[list[Finite]] = Field(None, description="a coordinate per contact node for plots (default 0, 1, ...)")
    state: Optional[StaticState] = Field(None, description="the reactions of one equilibrium state (analyses only)")
    forces: Optional[Annotated[list[ForcePhase], Field(min_length=1, max_length=1000)]] = Field(
        None, description="or: phases of applied forces (a loading path)")
    description: str = Field("", description="a text for results.json and the summary")

    def load_states(self) -> tuple[int, str]:
        """(equilibrium states, the key that sets them) for the pre-flight (app/scene/limits.py)."""
        if self.forces is None:
            return 1, "system.state"
        return 1 + sum(ph.steps for ph in self.forces), "system.forces[].steps"

    def file_sizes(self) -> tuple[int, int, str]:
        """(DOFs, contact nodes, the key that sets them) from K (read at validation) for the pre-flight."""
        return self.stiffness().shape[0], len(self.contact), "system.K"

    @field_validator("K", "M", mode="before")
    @classmethod
    def _file(cls, v: Any, info: ValidationInfo) -> Any:
        if v is None:
            return v
        path = resolve_file("", v, info)
        read_matrix("", v, path, context_limits(info))     # read and checked now: errors at validation
        return str(path)

    @field_validator("contact", mode="before")
    @classmethod
    def _contact(cls, v: Any) -> Any:
        if not isinstance(v, (list, tuple)) or not v:
            raise ValueError("allowed: a non-empty list of [T, N, sign_N] or [T, N, sign_T, sign_N]")
        return [list(_contact_entry(i, e)) for i, e in enumerate(v)]

    @model_validator(mode="after")
    def _consistent(self) -> "Matrices":
        K = self.stiffness()
        n = K.shape[0]
        for i, e in enumerate(self.contact):
            if max(e[0], e[1]) >= n:
                raise SystemPathError(f"contact.{i}", e, f"DOF index out of range: K has {n} rows (0 ... {n - 1})")
        seen: dict[int, int] = {}
        for i, e in enumerate(self.contact):
            for d in e[:2]:
                if d in seen:
                    raise SystemPathError(f"contact.{i}", e, f"DOF {d} is already used by contact entry {seen[d]}: "
                                          "every DOF may appear in one contact entry only")
                seen[d] = i
        diff = abs(K - K.T)
        scale = float(abs(K).max())
        worst = float(diff.max()) if diff.nnz else 0.0
        if worst > SYMMETRY_RTOL * scale:
            i, j = np.unravel_index(int(np.argmax(diff.toarray())) if n <= 4000 else 0, (n, n))
            raise SystemPathError("K", pathlib.Path(self.K).name, f"not symmetric: |K - K^T| up to {worst:.3g} (e.g. at "
                                  f"[{i}, {j}]), more than {SYMMETRY_RTOL:g} x max |K| = {scale:.3g}")
        from app.systems.matrices.spd import not_spd
        why = not_spd(K)
        if why:
            raise SystemPathError("K", pathlib.Path(self.K).name, f"not positive definite: {why}; fix every rigid-body "
                                  "motion by Dirichlet conditions (remove their rows and columns) before exporting K")
        if self.M is not None:
            M = self.mass()
            if M.shape != K.shape:
                raise SystemPathError("M", pathlib.Path(self.M).name, f"shape {M.shape[0]} x {M.shape[1]} differs from K's {n} x {n}")
            mdiff = abs(M - M.T)
            if mdiff.nnz and float(mdiff.max()) > SYMMETRY_RTOL * float(abs(M).max()):
                raise SystemPathError("M", pathlib.Path(self.M).name, "not symmetric")
            why = not_spd(M)
            if why:
                raise SystemPathError("M", pathlib.Path(self.M).name, f"not positive definite: {why}; a mass matrix "
                                      "has positive eigenvalues (kinetic energy) on the DOFs of K")
        nc = len(self.contact)
        for key in ("gaps", "positions"):
            vals = getattr(self, key)
            if vals is not None and len(vals) != nc:
                raise SystemPathError(key, vals, f"{len(vals)} values for {nc} contact nodes: one per contact node")
        if (self.state is None) == (self.forces is None):
            raise SystemPathError("state", None, "give exactly one of 'state' (the reactions of one equilibrium "
                                  "state: analyses only) or 'forces' (phases of applied forces: a loading path)")
        if self.state is not None:
            r = np.array(self.state.reactions, dtype=float)
            if len(r) != nc:
                raise SystemPathError("state.reactions", self.state.reactions,
                                      f"{len(r)} pairs for {nc} contact nodes: one [r_T, r_N] per contact node")
            scale = max(float(np.max(np.abs(r))), 1e-300)
            if np.any(r[:, 1] > 1e-12 * scale):
                i = int(np.argmax(r[:, 1]))
                raise SystemPathError(f"state.reactions.{i}", list(r[i]), "r_N > 0: normal reactions are "
                                      "compressive, r_N <= 0 (paper axes: N is the body's outward normal)")
            if self.gaps is not None:
                bad = [i for i, g in enumerate(self.gaps) if g > 0 and r[i, 1] < -1e-12 * scale]
                if bad:
                    raise SystemPathError(f"gaps.{bad[0]}", self.gaps[bad[0]], "a node with a gap carries no "
                                          "normal reaction (Signorini)")
            if self.state.u_T is not None and len(self.state.u_T) != nc:
                raise SystemPathError("state.u_T", self.state.u_T, f"one value per contact node ({nc})")
        if self.forces is not None:
            for i, ph in enumerate(self.forces):
                f = self.force(i)
                if f.shape != (n,):
                    raise SystemPathError(f"forces.{i}.force", ph.force if isinstance(ph.force, str) else
                                          f"<{len(ph.force)} values>", f"{f.size} values: K has {n} rows")
        return self

    # Data, read once per file version (cached) --------------------------------------------------
    def stiffness(self):
        """K as a scipy CSR matrix."""
        return read_matrix("K", self.K, pathlib.Path(self.K))

    def mass(self):
        """M as a scipy CSR matrix (None when not given)."""
        return None if self.M is None else read_matrix("M", self.M, pathlib.Path(self.M))

    def force(self, i: int) -> np.ndarray:
        """Force increment of phase ``i`` (one value per DOF)."""
        f = self.forces[i].force
        return read_vector(f"forces.{i}.force", f, pathlib.Path(f) if isinstance(f, str) else None)

    def contact_nodes(self) -> list[tuple[int, int, int, int]]:
        """(T, N, sign_T, sign_N) of every contact node."""
        return [tuple(e) for e in self.contact]

    @classmethod
    def check_scene(cls, scene: Any) -> None:
        """Scene-level checks (called by :class:`app.scene.schema.Scene`): M for the dynamic analyses,
        reactions inside the Coulomb cone, no block loading, no mesh outputs."""
        cfg = scene.system
        dyn = [a for a in scene.analyses if a in DYNAMIC_ANALYSES]
        if dyn and cfg.M is None:
            raise SystemPathError("system.M", None, f"the analyses {', '.join(dyn)} need a mass matrix: give M "
                                  "(a file) or remove them")
        if scene.loading is not None:
            raise SystemPathError("loading", scene.loading.model_dump(), "not allowed for a matrices system: "
                                  "give system.forces (phases of applied forces) or system.state")
        no_field_outputs(scene, "needs a mesh: not applicable, a matrices system has no mesh (use plots and report)")
        if cfg.state is not None:
            r = np.array(cfg.state.reactions, dtype=float)
            excess = np.abs(r[:, 0]) - scene.mu * (-r[:, 1])
            scale = max(float(np.max(np.abs(r))), 1e-300)
            if np.any(excess > 1e-8 * scale):
                i = int(np.argmax(excess))
                raise SystemPathError(f"system.state.reactions.{i}", list(r[i]), f"outside the Coulomb cone "
                                      f"|r_T| <= mu (-r_N) with mu = {scene.mu}")

