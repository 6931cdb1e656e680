"""``python -m app export RESULTS --matrices``: a results folder's matrices for other tools.

For researchers who test complementarity eigenvalue solvers on finite-element instances, and for
users who want the system in their own code. From the results folder (read strictly, as
``check`` reads it: app/io/claims.py) the scene it stores is validated again and its system
built (no loading path: the states are in results.json). A scene that names files (a Gmsh
body's ``.geo``, matrices) is refused there: a path read from a results folder is never opened,
so the user gives the scene file (``--scene``), whose system must have the stored one's type,
contact nodes and DOFs. Then, in a new folder:

- ``K.mtx``, ``M.mtx``: the stiffness and mass matrices (Matrix Market, the system's DOFs);
- ``state_<k>/`` for the first state ``k`` of each distinct classification (the states that
  share it are listed in its ``answers.json``):

  - ``Kstar.mtx``, ``Mstar.mtx``: ``K*(mu)`` and ``M*(mu)`` of the paper's eq. (15) at the
    scene's mu, on the kept DOFs (docs/method.md section 2);
  - ``A0.mtx``, ``A1.mtx`` (and ``A2.mtx`` on a curved obstacle): the condensed MCEIP-mu pencil
    ``A0 + mu A1 (+ mu^2 A2)`` on the slip nodes, eqs. (21)-(23) (none without slip nodes);
  - ``answers.json``: what results.json says of that classification: the MCEIP-mu record
    (solutions, the proven onset and list, the certificate), the state's classification and mu;
- ``index.json``: the scene, the units, mu and the classifications exported.

``--states SEL`` exports only the classifications of the chosen states (the selectors of
``outputs.states``) and ``--pencils-only`` only their condensed pencils and answers (no
system-sized matrix): scripts/instance_library.py builds the library of docs/instances.md so.

``app.mceip_mu(A0, A1, cap)`` on the exported pencil re-proves the stored answers
(tests/test_export.py). The folder is written under a temporary name and renamed at the end:
nothing half-written is left, and an existing folder is never replaced. One process only.
"""
from __future__ import annotations

import json
import os
import pathlib
import shutil

import numpy as np
import scipy.io
import scipy.sparse

from app.analyses.pencils.curvature import attach as attach_curvature
from app.analyses.pencils.curvature import is_curved
from app.analyses.pencils.state import StatePencils
from app.common.stages import Stages
from app.io.claims import read_results
from app.io.document import json_clean
from app.io.result import StateResult, StudyResult
from app.linalg import to_scipy
from app.loading.classify import Classification
from app.loading.state import EquilibriumState
from app.scene.schema import load_scene, parse_scene
from app.systems import SYSTEM_TYPES


class ExportError(Exception):
    """A results folder that cannot be exported (one line)."""


def export_matrices(results: pathlib.Path, out: pathlib.Path, comm, scene_file: pathlib.Path | None = None,
                    states: list[str] | None = None, pencils_only: bool = False) -> list[str]:
    """Write the matrices of the results folder ``results`` into the new folder ``out`` (see the
    module's docstring); ``scene_file``: the scene to build the system from instead of the stored
    one; ``states``: only the classifications of the states these selectors choose (those of
    ``outputs.states``: an index, ``final``, ``first_mceip_mu``, ``all_distinct``); ``pencils_only``:
    only the condensed pencils and answers (no K, M, K*, M*). Returns the files written, relative
    to ``out``."""
    if comm.size != 1:
        raise ExportError("export runs on one process (without mpirun)")
    if os.path.lexists(out):
        raise ExportError(f"{out} exists: give a new folder with -o (an existing one is never replaced)")
    study = read_results(results)
    if scene_file is None:
        scene = parse_scene(study.scene_config, f"{results}/results.json scene_config", results, files=False)
    else:
        scene = load_scene(scene_file)
        stored, given = (study.scene_config.get("system") or {}).get("type"), SYSTEM_TYPES[scene.system.type].name
        if given != stored:
            raise ExportError(f"{scene_file}: system.type = {given!r}, but the results are of a {stored!r} system")
    firsts = _chosen(study, states)
    staging = out.parent / f".{out.name}.partial-{os.getpid()}"
    staging.mkdir(parents=False)
    try:
        files = _write(study, scene, staging, comm, firsts, pencils_only)
        os.rename(staging, out)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return files


def _chosen(study: StudyResult, selectors: list[str] | None) -> set[int] | None:
    """The first states of the classifications the selectors choose (None: all of them)."""
    if not selectors:
        return None
    from pydantic import ValidationError

    from app.io.select import analyses_of, select_states
    from app.scene.sections import Outputs
    sel = [int(x) if x.strip().lstrip("-").isdigit() else x.strip() for x in selectors]
    try:
        sel = Outputs.model_validate({"states": sel}).states
    except ValidationError as err:
        first = err.errors()[0]
        raise ExportError(f"--states {first.get('input')!r}: {first.get('msg')} (a state index, final, "
                          "first_mceip_mu or all_distinct)") from None
    found, notes = select_states(study.states, sel)
    if notes:
        raise ExportError(notes[0].replace("outputs.states", "--states"))
    return {analyses_of(study.states, i)[1] for i in found}


def _write(study: StudyResult, scene, folder: pathlib.Path, comm, firsts: set[int] | None = None,
           pencils_only: bool = False) -> list[str]:
    files: list[str] = []
    kind = SYSTEM_TYPES[scene.system.type]
    with kind.build(scene.system, comm, Stages()) as system:
        nodes = len(study.states[0].nodes) if study.states else len(system.nodes)
        if len(system.nodes) != nodes:
            raise ExportError(f"the scene's system has {len(system.nodes)} contact nodes, the results' {nodes}: "
                              "not the system of these results")
        if not pencils_only:
            _mtx(folder / "K.mtx", to_scipy(system.K), "the stiffness matrix K", files, folder)
            try:
                M = system.mass()
            except RuntimeError:             # a system given as matrices without M
                M = None
            if M is not None:
                _mtx(folder / "M.mtx", to_scipy(M), "the mass matrix M", files, folder)
        exported = [_classification(study, st, system, folder, files, pencils_only) for st in study.states
                    if st.analyses_shared_with is None and (firsts is None or st.index in firsts)]
        dofs = int(system.n_dofs)
    (folder / "index.json").write_text(json.dumps(json_clean({
        "scene": study.scene, "units": study.units.to_dict(), "mu": study.mu, "system": study.system,
        "dofs": dofs, "classifications": exported}), indent=1, allow_nan=False))
    files.append("index.json")
    return files


def _classification(study: StudyResult, st: StateResult, system, folder: pathlib.Path, files: list[str],
                    pencils_only: bool = False) -> dict:
    """The files of one distinct classification (first state ``st``); its line of index.json."""
    cls = attach_curvature(Classification(tuple(n.status for n in st.nodes), tuple(int(n.sign) for n in st.nodes)),
                           _state(st), system)
    sub = folder / f"state_{st.index}"
    sub.mkdir()
    p = StatePencils(system, cls)
    try:
        if not pencils_only:
            Ks, Ms = p.star(study.mu)
            _mtx(sub / "Kstar.mtx", to_scipy(Ks), f"K*(mu) of eq. (15) at mu = {study.mu}", files, folder)
            _mtx(sub / "Mstar.mtx", to_scipy(Ms), f"M*(mu) of eq. (15) at mu = {study.mu}", files, folder)
        s = len(cls.slip)
        if s:
            pencil = p.condensed_mu_quadratic() if is_curved(cls) else p.condensed_mu()
            for name, A in zip(("A0", "A1", "A2"), pencil):
                _mtx(sub / f"{name}.mtx", np.asarray(A), f"{name} of the condensed MCEIP-mu pencil, eqs. (21)-(23)",
                     files, folder)
    finally:
        p.destroy()
    sharing = [x.index for x in study.states if x.index == st.index or x.analyses_shared_with == st.index]
    mu = st.analyses.mceip_mu
    non_finite: dict[str, str] = {}
    answers = json_clean({"state": st.index, "states": sharing, "classification": st.classification.to_dict(),
                          "slip_nodes": s, "mu": study.mu, "quadratic": is_curved(cls),
                          "mceip_mu": None if mu is None else mu.to_dict()}, non_finite)
    if non_finite:
        answers["non_finite"] = non_finite          # JSON pointer -> +inf / -inf / nan (written as null)
    (sub / "answers.json").write_text(json.dumps(answers, indent=1, allow_nan=False))
    files.append(f"state_{st.index}/answers.json")
    return {"state": st.index, "states": len(sharing), "slip_nodes": s, "folder": f"state_{st.index}"}


def _state(st: StateResult) -> EquilibriumState:
    """The equilibrium state of a results.json state (its contact values and what its loading
    path recorded), for the curvature terms of a curved obstacle."""
    def values(name: str) -> np.ndarray:
        return np.array([getattr(n, name) for n in st.nodes], dtype=float)
    return EquilibriumState(index=st.index, load=st.load.to_dict(), u_T=values("u_T"), u_N=values("u_N"),
                            r_T=values("r_T"), r_N=values("r_N"), extra=dict(st.model_extra or {}))


def _mtx(path: pathlib.Path, A, comment: str, files: list[str], folder: pathlib.Path) -> None:
    scipy.io.mmwrite(str(path), A, comment=comment, precision=17)
    files.append(str(path.relative_to(folder)))
