"""The MCEIP-mu proofs of a run, stored beside results.json so that they can be re-checked.

``proofs/state_<k>.npz`` holds, for the first state ``k`` of each distinct classification whose
condensed MCEIP-mu was proven (or partly proven), the pencil ``A0``, ``A1`` and the proof log
(JSON text, format in docs/proofs.md). :func:`check_folder` re-verifies every log with the
independent checker and compares what it accepts with what results.json claims. A curved
obstacle's quadratic pencil (``A2`` too) is proven again from the stored pencil by the exact
proof of :mod:`app.analyses.mceip_mu_quadratic_proof` (log format ``mceip-mu-quadratic/1``), or its
branch-and-bound log (``mceip-mu-quadratic-bb/1``) is re-verified by
:mod:`app.analyses.mceip_mu_quadratic_check`.
"""
from __future__ import annotations

import io
import json
import os
import pathlib
import zipfile
from dataclasses import dataclass

import numpy as np

from app.io.results import file_mode  # one-way: results.py does not import this module

FOLDER = "proofs"


def _stored(results: dict):
    """``(state, proof)`` of each classification whose MCEIP-mu proof is stored (the private
    ``_proof`` key of its ``mceip_mu`` analysis, which results.json leaves out), each proof once."""
    seen: set[int] = set()
    for st in results.get("states", []):
        a = (st.get("analyses") or {}).get("mceip_mu") or {}
        proof = a.get("_proof")
        if proof and id(proof) not in seen:
            seen.add(id(proof))
            yield st, proof


def npz_bytes(arrays: dict, compressed: set) -> bytes:
    """The bytes of an ``.npz`` file (what :func:`numpy.load` reads) holding ``arrays``, the members
    named in ``compressed`` deflated and the others stored: a dense pencil's doubles shrink by 5 %
    at most under zlib, which cost 25 s of the 27 s of writing the proofs at 10^6 DOFs."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", allowZip64=True) as zf:
        for name, a in arrays.items():
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED if name in compressed else zipfile.ZIP_STORED
            with zf.open(info, "w", force_zip64=True) as f:
                np.lib.format.write_array(f, np.asanyarray(a), allow_pickle=False)
    return buf.getvalue()


def count_proofs(results: dict) -> int:
    """The number of files :func:`write_proofs` writes."""
    return sum(1 for _ in _stored(results))


def write_proofs(results: dict, outdir: pathlib.Path, written_one=None) -> list[pathlib.Path]:
    """Write one ``.npz`` per proven classification; ``written_one()`` is called after each file
    (progress). Returns the files written."""
    written: list[pathlib.Path] = []
    for st, proof in _stored(results):
        folder = outdir / FOLDER
        folder.mkdir(exist_ok=True)
        path = folder / f"state_{int(st['index'])}.npz"
        arrays = {"A0": proof["A0"], "A1": proof["A1"], "log": np.array(json.dumps(proof["log"]))}
        if "A2" in proof:
            arrays["A2"] = proof["A2"]
        data = npz_bytes(arrays, compressed={"log"})
        # exclusive create: a file of that name (not this run's) is never overwritten
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, file_mode())
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        written.append(path)
        if written_one is not None:
            written_one()
    return written


@dataclass
class StateCheck:
    """The re-check of one stored proof against results.json."""

    state: int
    s: int
    onset_claimed: bool
    onset_accepted: bool
    all_claimed: bool
    all_accepted: bool
    values_match: bool
    errors: list[str]

    @property
    def ok(self) -> bool:
        """Whether the re-check agrees with results.json: every claim it makes (the proven onset, the
        complete list) accepted by the checker, and its values inside the checker's enclosures."""
        return (self.onset_accepted or not self.onset_claimed) and (self.all_accepted or not self.all_claimed) \
            and self.values_match


def check_folder(folder: pathlib.Path) -> list[StateCheck]:
    """Re-verify every stored proof of a results folder (raises ``FileNotFoundError`` when the
    folder has no results.json)."""
    from app.analyses.mceip_mu.checker import check_log
    from app.analyses.mceip_mu.prooflog import ProofLog
    from app.io.document import from_document
    results = from_document(json.loads((folder / "results.json").read_text(encoding="utf-8")))
    by_index = {int(st["index"]): st for st in results.get("states", [])}
    out: list[StateCheck] = []
    for path in sorted((folder / FOLDER).glob("state_*.npz"), key=lambda p: int(p.stem.split("_")[1])):
        k = int(path.stem.split("_")[1])
        a = ((by_index.get(k) or {}).get("analyses") or {}).get("mceip_mu") or {}
        with np.load(path, allow_pickle=False) as z:
            A0, A1 = z["A0"], z["A1"]
            raw = json.loads(str(z["log"]))
            if "A2" in z.files:
                out.append(_check_quadratic(k, A0, A1, z["A2"], raw, a))
                continue
            log = ProofLog.from_json(raw)
        rep = check_log(A0, A1, log)
        onset_claimed = bool((a.get("onset") or {}).get("proven"))
        all_claimed = bool(a.get("certified"))
        match = True
        if all_claimed and rep.all_ok:
            claimed = sorted(float(d["value"]) for d in a.get("solutions", []) if d.get("certified"))
            match = len(claimed) == len(rep.solutions) and all(
                lo <= v <= hi or abs(v - 0.5 * (lo + hi)) <= 1e-9 * max(1.0, abs(v))
                for v, (_, lo, hi) in zip(claimed, rep.solutions))
        if onset_claimed and rep.onset_ok:
            v = (a.get("onset") or {}).get("value")
            if v is not None and rep.onset is not None:
                match = match and rep.onset[0] <= float(v) <= rep.onset[1]
            elif (v is None) != (rep.onset is None):
                match = False
        out.append(StateCheck(k, log.s, onset_claimed, rep.onset_ok, all_claimed, rep.all_ok, match, rep.errors[:3]))
    return out


def _check_quadratic(k: int, A0, A1, A2, log: dict, a: dict) -> StateCheck:
    """Verify a stored quadratic proof again and compare the proven list in ``[0, cap]`` with the
    certified solutions of results.json: a per-support proof is proven again from the pencil
    (exact arithmetic, no time limit), a branch and bound's log is re-verified by its checker."""
    from app.analyses.mceip_mu_quadratic import QUADRATIC_BB_FORMAT, QUADRATIC_FORMAT
    s = A0.shape[0]
    claimed = bool(a.get("certified"))
    onset_claimed = bool((a.get("onset") or {}).get("proven"))
    if log.get("format") == QUADRATIC_BB_FORMAT:
        from app.analyses.mceip_mu_quadratic_check import check_log
        rep = check_log(A0, A1, A2, log)
        ok, onset_ok, errors, solutions, onset = rep.complete, rep.onset_proven, rep.errors[:3], rep.solutions, rep.onset
        if not rep.errors and not ok:
            errors.append(f"the log leaves mu >= {rep.open_from:.6g} open")
    elif log.get("format") == QUADRATIC_FORMAT:
        from app.analyses.mceip_mu_quadratic_proof import prove_quadratic
        proof = prove_quadratic(A0, A1, A2, float(log["cap"]), max_s=int(log["max_s"]), pairs=log.get("pairs", []))
        ok = onset_ok = proof is not None and proof.proven
        errors = [] if ok else ["the exact proof does not decide every support" if proof else
                                f"s = {s} is above the stored max_s = {log['max_s']}"]
        solutions, onset = (proof.solutions, proof.onset) if ok else ([], None)
    else:
        return StateCheck(k, s, onset_claimed, False, claimed, False, False,
                          [f"proof format {log.get('format')!r}, expected {QUADRATIC_FORMAT!r} or {QUADRATIC_BB_FORMAT!r}"])
    match = True
    if ok and claimed:
        values = sorted(float(d["value"]) for d in a.get("solutions", []) if d.get("certified"))
        got = sorted(solutions, key=lambda p: p.enclosure[0])
        match = len(values) == len(got) and all(p.enclosure[0] <= v <= p.enclosure[1] for v, p in zip(values, got))
    if onset_ok and onset_claimed:
        v = (a.get("onset") or {}).get("value")
        if (v is None) != (onset is None) or (v is not None and not onset.enclosure[0] <= float(v) <= onset.enclosure[1]):
            match = False
    return StateCheck(k, s, onset_claimed, onset_ok, claimed, ok, match, errors)
