"""The MCEIP-mu proofs of a run, stored beside results.json so that they can be re-checked.

``proofs/state_<k>.npz`` holds, for the first state ``k`` of each distinct classification whose
condensed MCEIP-mu was proven (or partly proven), the pencil ``A0``, ``A1`` and the proof log
(JSON text, format in docs/proofs.md); a curved obstacle's quadratic pencil adds ``A2``.
:mod:`app.io.check` re-derives every claim of results.json from these files.
"""
from __future__ import annotations

import io
import json
import os
import pathlib
import zipfile

import numpy as np

from app.io.result import StudyResult
from app.io.results import file_mode  # one-way: results.py does not import this module

FOLDER = "proofs"


def _stored(study: StudyResult):
    """``(state index, proof)`` of each classification whose MCEIP-mu proof is kept (its
    ``mceip_mu`` analysis's ``proof``, in memory only), each proof once."""
    seen: set[int] = set()
    for st in study.states:
        a = st.analyses.mceip_mu
        proof = None if a is None else a.proof
        if proof and id(proof) not in seen:
            seen.add(id(proof))
            yield st.index, proof


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


def count_proofs(study: StudyResult) -> int:
    """The number of files :func:`write_proofs` writes."""
    return sum(1 for _ in _stored(study))


def write_proofs(study: StudyResult, outdir: pathlib.Path, written_one=None) -> list[pathlib.Path]:
    """Write one ``.npz`` per proven classification; ``written_one()`` is called after each file
    (progress). Returns the files written."""
    written: list[pathlib.Path] = []
    for index, proof in _stored(study):
        folder = outdir / FOLDER
        folder.mkdir(exist_ok=True)
        path = folder / f"state_{int(index)}.npz"
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
