"""Wall-time record of the stages a study ran (results.json "stages")."""
from __future__ import annotations

import contextlib
import logging
import time
from dataclasses import dataclass, field

log = logging.getLogger(__name__)


@dataclass
class Stages:
    """Ordered record of named stages; a stage run several times is summed and counted."""

    records: dict[str, dict] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    @contextlib.contextmanager
    def __call__(self, name: str):
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
        return name in self.records

    def as_list(self) -> list[dict]:
        return [dict(r) for r in self.records.values()]
