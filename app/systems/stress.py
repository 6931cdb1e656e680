"""In-plane stress of 2D linear elasticity (UFL): the stiffness forms (app/systems/block/operators.py,
app/systems/gmsh/operators.py) and the von Mises stress of the field outputs."""
from __future__ import annotations


def strain(u):
    """UFL small strain ``sym(grad u)``."""
    import ufl
    return ufl.sym(ufl.grad(u))


def stress(u, mu, lmbda):
    """UFL in-plane stress ``2 mu eps + lambda tr(eps) I`` of the 2D displacement ``u`` with the
    Lamé parameters of the 2D model (numbers, Constants or DG0 functions: a material per cell;
    app/systems/elasticity.py ``lame_parameters``)."""
    import ufl
    eps = strain(u)
    return 2.0 * mu * eps + lmbda * ufl.tr(eps) * ufl.Identity(2)


def von_mises(u, mu, lmbda, plane: str):
    """UFL von Mises stress of the 2D displacement ``u`` with Lamé parameters ``mu``, ``lmbda``
    (as :func:`stress`). Plane stress: s_zz = 0; plane strain: s_zz = lambda tr(eps)."""
    import ufl
    eps = strain(u)
    s = stress(u, mu, lmbda)
    szz = lmbda * ufl.tr(eps) if plane == "strain" else 0.0
    sxx, syy, sxy = s[0, 0], s[1, 1], s[0, 1]
    return ufl.sqrt(0.5 * ((sxx - syy) ** 2 + (syy - szz) ** 2 + (szz - sxx) ** 2) + 3.0 * sxy ** 2)
