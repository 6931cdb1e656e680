"""Wall-time record of the stages a study ran (results.json "stages")."""
from __future__ import annotations

import contextlib
import logging
import time
from dataclasses import dataclass, field

from app.common.interrupt import checkpoint

log = logging.getLogger(__name__)


@dataclass
class Stages:
    """Ordered record of named stages; a stage run several times is summed and counted.

    Not ``dolfinx.common.Timer``: DOLFINx's timers go into one process-wide table that
    ``list_timings`` aggregates by name with DOLFINx's own internal timers and that cannot be
    reset per study, while a sweep or a refinement study runs many studies in one process and
    each needs its own record, in the order the stages first ran, for its results.json."""

    records: dict[str, dict] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    @contextlib.contextmanager
    def __call__(self, name: str):
        """Time the block of a ``with`` as the stage ``name``: its wall time is added to the stage's
        record (made on first use) and its count incremented, also when the block raises. A
        received Ctrl-C is raised before the stage begins (:func:`app.common.interrupt.checkpoint`)."""
        checkpoint()
        t0 = time.perf_counter()
        try:
            yield
        finally:
            rec = self.records.setdefault(name, {"name": name, "seconds": 0.0, "count": 0})
            dt = time.perf_counter() - t0
            rec["seconds"] += dt
            rec["count"] += 1
            log.debug("stage '%s': %.3f s", name, dt)

    def ran(self, name: str) -> bool:
        """Whether a stage called ``name`` has run."""
        return name in self.records

    def as_list(self) -> list[dict]:
        """Copies of the records in the order the stages first ran, ``{"name", "seconds", "count"}``
        each (results.json "stages")."""
        return [dict(r) for r in self.records.values()]
