"""Von Mises stress of a 2D linear elastic displacement field (UFL), for the field outputs."""
from __future__ import annotations


def von_mises(u, mu, lmbda, plane: str):
    """UFL von Mises stress of the 2D displacement ``u`` with Lamé parameters ``mu``, ``lmbda``
    (numbers or DG0 functions: a material per cell) of the 2D model (app/system/elasticity.py
    ``lame_parameters``). Plane stress: s_zz = 0; plane strain: s_zz = lambda tr(eps)."""
    import ufl
    eps = ufl.sym(ufl.grad(u))
    s = 2.0 * mu * eps + lmbda * ufl.tr(eps) * ufl.Identity(2)
    szz = lmbda * ufl.tr(eps) if plane == "strain" else 0.0
    sxx, syy, sxy = s[0, 0], s[1, 1], s[0, 1]
    return ufl.sqrt(0.5 * ((sxx - syy) ** 2 + (syy - szz) ** 2 + (szz - sxx) ** 2) + 3.0 * sxy ** 2)
