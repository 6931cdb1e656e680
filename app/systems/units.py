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

#: the values real solids take, per unit system: Young's modulus from soft hydrogels (about
#: 100 Pa) to diamond (1.05-1.2 TPa; none stiffer), density from aerogels (about 0.2 kg/m^3) to
#: osmium (22,600 kg/m^3)
REAL_SOLIDS: dict[str, dict[str, tuple[float, float]]] = {
    "mm-N-MPa-tonne-s": {"stress": (1e-4, 1.5e6), "density": (1e-13, 2.5e-8)},
    "m-N-Pa-kg-s": {"stress": (1e2, 1.5e12), "density": (0.1, 2.5e4)}}


def implausible_material(key: str, E: float, density: float | None, units: str) -> list[str]:
    """Warnings for a material (scene key ``key``) whose Young's modulus or density no real solid
    has in the unit system ``units``: a value typed in the wrong unit (E in Pa with lengths in mm)."""
    out = []
    u = CONTINUUM_UNITS[units]
    for name, value, kind in (("E", E, "stress"), ("density", density, "density")):
        lo, hi = REAL_SOLIDS[units][kind]
        if value is not None and not lo <= value <= hi:
            out.append(f"{key}.{name} = {value:g} {u[kind]} is outside the range of real solids ({lo:g} to "
                       f"{hi:g} {u[kind]}) in the scene's units ({units}): was it given in another unit?")
    return out
