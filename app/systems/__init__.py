"""Registry of system types: what a scene's ``system.type`` may name.

Each :class:`SystemType` provides the pydantic schema of its ``system:`` section, and the module
holding ``build(cfg, comm, stages) -> System`` and ``path(scene, comm, stages, progress) ->
(system, states, path_info)`` (the loading path: the equilibrium states the analyses examine).
Modules are imported on first use, so validating a scene never loads PETSc or DOLFINx.

Data flow: scene -> ``SYSTEM_TYPES[type].schema`` -> ``build`` -> ``path`` -> per-state analyses.
The original types ``two_particles`` and ``block`` are still dispatched by :mod:`app.study`
(a later refactor moves them here); new types register below and :mod:`app.study` asks this
registry for every type it does not know.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any

from app.systems.gmsh_schema import GmshBody
from app.systems.matrices_schema import Matrices


@dataclass(frozen=True)
class SystemType:
    """One system type: its scene schema and the module with ``build`` and ``path``."""
    name: str
    schema: type
    module: str
    summary: str

    def _impl(self):
        return importlib.import_module(self.module)

    def build(self, cfg: Any, comm, stages):
        """The :class:`app.system.base.System` of ``cfg`` (MPI collective)."""
        return self._impl().build(cfg, comm, stages)

    def path(self, scene, comm, stages, progress):
        """``(system, states, path_info)``: the system and the equilibrium states of its loading."""
        return self._impl().path(scene, comm, stages, progress)


SYSTEM_TYPES: dict[str, SystemType] = {}


def register(system_type: SystemType) -> None:
    """Add a system type (its schema's ``type`` literal must equal ``system_type.name``)."""
    if system_type.name in SYSTEM_TYPES:
        raise ValueError(f"system type {system_type.name!r} is already registered")
    SYSTEM_TYPES[system_type.name] = system_type


def get(name: str) -> SystemType:
    """The registered type ``name`` (KeyError if there is none)."""
    return SYSTEM_TYPES[name]


def schemas() -> tuple[type, ...]:
    """Schemas of the registered types, for the ``system`` union of :class:`app.config.Scene`."""
    return tuple(t.schema for t in SYSTEM_TYPES.values())


register(SystemType("matrices", Matrices, "app.systems.matrices",
                    "K (and M) from Matrix Market or PETSc binary files, contact DOF pairs"))
register(SystemType("gmsh", GmshBody, "app.systems.gmsh_body",
                    "a 2D body from a Gmsh .geo/.msh file, a straight obstacle, a loading program"))
