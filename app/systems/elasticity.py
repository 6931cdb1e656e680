"""Lamé parameters of the 2D linear elasticity models (plane stress, plane strain), shared by the
meshed systems (app/systems/block/, app/systems/gmsh/); their UFL stresses: app/systems/stress.py."""
from __future__ import annotations


def lame_parameters(E: float, nu: float, plane: str = "stress") -> tuple[float, float]:
    """Lamé parameters (mu, lambda) of the 2D model.

    For plane stress lambda is replaced by lambda* = 2 mu lambda / (lambda + 2 mu)
    = E nu / (1 - nu^2).
    """
    if plane not in ("stress", "strain"):
        raise ValueError(f"plane must be 'stress' or 'strain', got {plane!r}")
    if not (E > 0 and -1.0 < nu < 0.5):
        raise ValueError(f"Need E > 0 and -1 < nu < 0.5, got E={E}, nu={nu}")
    mu = E / (2.0 * (1.0 + nu))
    lmbda = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    if plane == "stress":
        lmbda = 2.0 * mu * lmbda / (lmbda + 2.0 * mu)
    return mu, lmbda


def bulk_compliance(E: float, nu: float, plane: str = "stress") -> float:
    """``1 / kappa`` of the 2D model, ``kappa = lambda + mu`` its in-plane bulk modulus (with
    lambda* in plane stress): ``2 (1 + nu)(1 - 2 nu) / E`` in plane strain (0 for the
    incompressible nu = 1/2), ``2 (1 - nu) / E`` in plane stress. The mixed element's pressure
    block (app/systems/stress.py ``mixed_forms``)."""
    if plane not in ("stress", "strain"):
        raise ValueError(f"plane must be 'stress' or 'strain', got {plane!r}")
    if not (E > 0 and -1.0 < nu <= 0.5):
        raise ValueError(f"Need E > 0 and -1 < nu <= 0.5, got E={E}, nu={nu}")
    return 2.0 * (1.0 + nu) * (1.0 - 2.0 * nu) / E if plane == "strain" else 2.0 * (1.0 - nu) / E
