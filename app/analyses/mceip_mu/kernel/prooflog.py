"""The proof log of MCEIP-mu: a tree of closed families with their witnesses (docs/proofs.md).

A node ``(F <= P <= U, [a, b])`` says "no solution with a support between ``F`` and ``U`` and mu
in ``[a, b]`` other than the listed ones"; :func:`app.analyses.mceip_mu.kernel.checker.check_log`
re-runs every node's test from the pencil and checks that the children of each node cover it.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field

FORMAT = "mceip-mu-proof/2"
FORMATS_READ = ("mceip-mu-proof/1", FORMAT)   # version 1: no forced sets (a leaf is its own)


@dataclass
class Node:
    r"""One node of the proof tree: the family of supports ``P`` with ``F <= P <= U`` (indices into
    the slip nodes; ``F``, the forced set, is empty for "every support in ``U``") and mu in ``[a, b]``.

    ``kind``: ``"cop"`` (sign argument on ``U``, witness ``d``, ``theta``), ``"rlt"`` (products
    of constraints, witness ``M``, ``theta``: :func:`rlt_closes`), ``"farkas"`` (a Farkas
    vector ``w``, :func:`farkas_closes`), ``"bisect"`` (children on ``[a, m]`` and ``[m, b]``),
    ``"branch"`` (on an index ``i`` of ``U \ F``: ``i`` not in the support, child ``(U \ {i}, F)``,
    or in it, child ``(U \ partners(i), F + {i})``), ``"pairsplit"`` (children ``U \ {a}`` and
    ``U \ {b}`` for a pair ``(a, b)`` inside ``U``), ``"drop"`` (children ``U \ {i}`` for every
    ``i`` plus the exact-support leaf of ``U``), ``"leaf"`` (``F = U``, the exact support ``U``:
    ``windows`` each with one verified eigenpair, ``pieces`` of ``[a, b]`` each closed by a Farkas
    vector, and the checker's own nonsingularity cover of the rest), ``"pair"`` (``F`` holds both halves
    of a pair: no allowed support), ``"empty"`` (``U`` empty or ``F`` not inside ``U``: no
    support at all), ``"open"`` (not closed: the proof is unfinished)."""

    id: int
    U: list[int]
    a: float
    b: float
    kind: str
    children: list[int] = field(default_factory=list)
    d: list[float] | None = None
    theta: float | None = None
    windows: list[dict] = field(default_factory=list)     # {"mu", "h", "x"} (x on U)
    F: list[int] = field(default_factory=list)
    w: list[float] | None = None
    pieces: list[dict] = field(default_factory=list)      # leaf: {"a", "b", "w"} Farkas pieces
    M: list[list[float]] | None = None                     # rlt: the multiplier matrix (on U)

    def as_dict(self) -> dict:
        """The node as JSON data (docs/proofs.md): its id, ``U``, ``a``, ``b``, kind and only the fields
        its kind uses."""
        out = {"id": self.id, "U": self.U, "a": self.a, "b": self.b, "kind": self.kind}
        if self.F:
            out["F"] = self.F
        if self.children:
            out["children"] = self.children
        if self.d is not None:
            out["d"] = self.d
            out["theta"] = self.theta
        if self.windows:
            out["windows"] = self.windows
        if self.w is not None:
            out["w"] = self.w
        if self.pieces:
            out["pieces"] = self.pieces
        if self.M is not None:
            out["M"] = self.M
            out["theta"] = self.theta
        return out

    @classmethod
    def from_dict(cls, d: dict, version: int = 2) -> "Node":
        """The node read from :meth:`as_dict`'s data of format ``version`` (1: a leaf or pair node had no
        ``F``, its forced set is then all of ``U``)."""
        U = [int(i) for i in d["U"]]
        kind = str(d["kind"])
        F = [int(i) for i in d.get("F", [])]
        if version == 1 and kind in ("leaf", "pair"):
            F = list(U)                 # version 1: a leaf is the exact support U
        return cls(int(d["id"]), U, float(d["a"]), float(d["b"]), kind,
                   [int(c) for c in d.get("children", [])], d.get("d"), d.get("theta"),
                   list(d.get("windows", [])), F, d.get("w"), list(d.get("pieces", [])), d.get("M"))


@dataclass
class ProofLog:
    """The witnesses of one pencil's proof: the node tree, its roots (``onset`` and ``all``) and
    the exact power-of-two scale the pencil was divided by (``A / 2^k``: exact, no rounding)."""

    s: int
    cap: float
    scale_exp: int
    pairs: list[tuple[int, int]]
    nodes: list[Node]
    onset_root: int | None           # root of "no solution in [0, onset_below]"
    onset_below: float | None
    all_roots: list[int]             # roots tiling [0, cap] for "every solution in [0, cap] listed"
    onset_witness: dict | None = None   # {"U", "mu", "h", "x"}: a verified solution just above onset_below
    bound_root: int | None = None       # when the onset is not proven: root of "no solution in [0, bound]"
    bound: float | None = None

    def prune(self) -> None:
        """Keep only the nodes reachable from the roots (restarts leave unused ones)."""
        byid = {n.id: n for n in self.nodes}
        keep, stack = set(), [r for r in [self.onset_root, self.bound_root, *self.all_roots] if r is not None]
        while stack:
            j = stack.pop()
            if j in keep or j not in byid:
                continue
            keep.add(j)
            stack.extend(byid[j].children)
        self.nodes = [n for n in self.nodes if n.id in keep]

    def to_json(self) -> dict:
        """The log as JSON data in the current format (:data:`FORMAT`, docs/proofs.md)."""
        return {"format": FORMAT, "s": self.s, "cap": self.cap, "scale_exp": self.scale_exp,
                "pairs": [list(p) for p in self.pairs], "onset_root": self.onset_root,
                "onset_below": self.onset_below, "all_roots": self.all_roots,
                "onset_witness": self.onset_witness, "bound_root": self.bound_root, "bound": self.bound,
                "nodes": [n.as_dict() for n in self.nodes]}

    @classmethod
    def from_json(cls, d: dict) -> "ProofLog":
        """The log read from JSON data of a format in :data:`FORMATS_READ`; ValueError for any other."""
        if d.get("format") not in FORMATS_READ:
            raise ValueError(f"proof log format {d.get('format')!r}, expected one of {FORMATS_READ}")
        version = FORMATS_READ.index(d["format"]) + 1
        return cls(int(d["s"]), float(d["cap"]), int(d["scale_exp"]), [tuple(p) for p in d["pairs"]],
                   [Node.from_dict(n, version) for n in d["nodes"]], d.get("onset_root"), d.get("onset_below"),
                   [int(r) for r in d.get("all_roots", [])], d.get("onset_witness"), d.get("bound_root"),
                   d.get("bound"))

    def dumps(self) -> str:
        """The log as compact JSON text (no spaces)."""
        return json.dumps(self.to_json(), separators=(",", ":"))


@dataclass
class CheckReport:
    """What :func:`check_log` accepted: the onset claim, the complete-list claim, the solutions."""

    onset_ok: bool
    all_ok: bool
    onset: tuple[float, float] | None                 # proven enclosure of the onset (None: none below cap)
    lower_bound: float                                # proven: no solution in [0, lower_bound]
    solutions: list[tuple[list[int], float, float]]   # (support, enclosure lo, hi) of verified solutions
    ill_conditioned: int
    errors: list[str]
