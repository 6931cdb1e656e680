"""Registry of system types: what a scene's ``system.type`` may name.

Each :class:`SystemType` provides the pydantic schema of its ``system:`` section, and the module
holding ``build(cfg, comm, stages) -> System`` and ``path(scene, comm, stages, progress) ->
(system, states, path_info)`` (the loading path: the equilibrium states the analyses examine).
Modules are imported on first use, so validating a scene never loads PETSc or DOLFINx.

Data flow: scene -> ``SYSTEM_TYPES[type].schema`` -> ``build`` -> ``path`` -> per-state analyses
-> outputs. Nothing outside this package tests the system type: where the rest of the app needs
type-specific behaviour it asks for a capability, either of the registered :class:`SystemType`
(``contact_line``, ``position_axis``, ``preload``, ``walks_alone``; the first two usable on a
results.json alone) or of the
validated schema object (``has_fields``, ``refinable``, ``check_scene``, ``mesh_sizes``,
``refined``, ``table_columns``; absent means "not supported").
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any, Optional

from app.systems.block.schema import Block
from app.systems.gmsh.schema import GmshBody
from app.systems.matrices.schema import Matrices
from app.systems.particles.schema import TwoParticles


@dataclass(frozen=True)
class SystemType:
    """One system type: its scene schema and the module with ``build`` and ``path``.

    ``contact_line``: name of the contact side in the pictures (``"AB"``), None if it has none;
    ``position_axis``: axis label of the contact nodes' ``x`` (``{length}``: the length unit),
    None when the nodes are only numbered.
    """

    name: str
    schema: type
    module: str
    summary: str
    contact_line: Optional[str] = None
    position_axis: Optional[str] = None

    def _impl(self):
        return importlib.import_module(self.module)

    def build(self, cfg: Any, comm, stages):
        """The :class:`app.systems.base.System` of ``cfg`` (MPI collective)."""
        return self._impl().build(cfg, comm, stages)

    def preload(self) -> None:
        """Import the implementation (PETSc, DOLFINx, ...) now; under MPI their initialisation is
        collective, so a task farm does it on every rank before the first case."""
        self._impl()

    def path(self, scene, comm, stages, progress):
        """``(system, states, path_info)``: the system and the equilibrium states of its loading."""
        return self._impl().path(scene, comm, stages, progress)

    def walker(self, scene, comm, stages):
        """``(system, walk)`` of a type whose loading runs on one rank alone (no MPI inside; only
        when :meth:`walks_alone`, see app/systems/block/path.py): the system is built (MPI
        collective) and ``walk(progress, on_state)`` gives ``(states, path_info)``, calling
        ``on_state`` with each state as it is made (app/study/stream.py)."""
        return self._impl().walker(scene, comm, stages)

    def walks_alone(self) -> bool:
        """Whether the type's module defines ``walker``."""
        return hasattr(self._impl(), "walker")


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
    """Schemas of the registered types, for the ``system`` union of :class:`app.scene.schema.Scene`."""
    return tuple(t.schema for t in SYSTEM_TYPES.values())


register(SystemType("two_particles", TwoParticles, "app.systems.particles.path",
                    "the paper's two-particle system (section 5, Fig. 1): one state in impending slip"))
register(SystemType("block", Block, "app.systems.block.path",
                    "the elastic block of Villechaise and Zeghloul: Gmsh + DOLFINx, press CD then drag it",
                    contact_line="AB", position_axis="position along AB, x [{length}] (A at x = 0)"))
register(SystemType("matrices", Matrices, "app.systems.matrices.path",
                    "K (and M) from Matrix Market or PETSc binary files, contact DOF pairs"))
register(SystemType("gmsh", GmshBody, "app.systems.gmsh.path",
                    "a 2D body from a Gmsh .geo/.msh file, a straight obstacle, a loading program",
                    position_axis="tangential coordinate s along the obstacle [{length}]"))
