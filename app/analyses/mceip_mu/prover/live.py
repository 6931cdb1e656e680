"""What the MCEIP-mu proof of this process is doing now, for the progress line of a long state.

The prover writes plain attributes (one per node: the phase, the tree's size, the lower end of the
interval it works on); a progress thread reads them (:meth:`LiveStatus.text`). Nothing here
enters a result or a proof.
"""
from __future__ import annotations


class LiveStatus:
    """The phase (``"search"``, ``"onset proof"``, ...), proof-tree nodes so far, and the mu the
    best-first exploration has reached (every family below it is closed, pending the checker)."""

    def __init__(self) -> None:
        self.reset()

    def reset(self, phase: str = "") -> None:
        """Start the phase ``phase`` with no tree node and no mu reached (``""``: idle)."""
        self.phase, self.nodes, self.mu = phase, 0, None

    def text(self) -> str:
        """``"onset proof, 230 tree nodes, at mu = 3.75"`` (empty when idle)."""
        if not self.phase:
            return ""
        parts = [self.phase]
        if self.nodes:
            parts.append(f"{self.nodes} tree nodes")
        if self.mu is not None:
            parts.append(f"at mu = {self.mu:.4g}")
        return ", ".join(parts)


#: the status of this process's current proof
LIVE = LiveStatus()
