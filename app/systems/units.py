"""Names of the units of a scene's consistent unit system (``units``, app/scene/schema.py), as the
systems report them (results.json ``units``, axis labels): labels only, no conversion."""
from __future__ import annotations

CONTINUUM_UNITS: dict[str, dict[str, str]] = {
    "mm-N-MPa-tonne-s": {"length": "mm", "force": "N", "stress": "MPa", "stiffness": "N/mm", "mass": "tonne",
                         "density": "tonne/mm^3", "time": "s", "lambda2": "1/s^2", "mu": "1"},
    "m-N-Pa-kg-s": {"length": "m", "force": "N", "stress": "Pa", "stiffness": "N/m", "mass": "kg",
                    "density": "kg/m^3", "time": "s", "lambda2": "1/s^2", "mu": "1"}}
"""Units of a meshed body (block, Gmsh body): with stress and density."""

DISCRETE_UNITS: dict[str, dict[str, str]] = {
    name: {k: v for k, v in u.items() if k not in ("stress", "density")} for name, u in CONTINUUM_UNITS.items()}
"""Units of a system given as matrices: no stress, no density."""
