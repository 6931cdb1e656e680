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


def deviator(e):
    """UFL in-plane deviator ``e - tr(e) I / 2`` of a 2x2 tensor."""
    import ufl
    return e - 0.5 * ufl.tr(e) * ufl.Identity(2)


def mixed_stress(u, p, mu):
    """UFL in-plane stress ``2 mu dev eps(u) + p I`` of the mixed element (``p = kappa div u``, the
    in-plane mean stress)."""
    import ufl
    return 2.0 * mu * deviator(strain(u)) + p * ufl.Identity(2)


def mixed_forms(u, p, v, q, mu, inv_kappa, thickness):
    """The mixed (displacement-pressure) stiffness blocks ``[[a_uu, a_up], [a_pu, a_pp]]`` (UFL).

        a_uu = t 2 mu dev eps(u) : dev eps(v),   a_up = t p div v,   a_pu = t q div u,
        a_pp = -t (1/kappa) p q,

    the stationarity of ``t int mu |dev eps|^2 + p div u - p^2 / (2 kappa)``, whose elimination of
    ``p`` gives back ``2 mu eps : eps + lambda (tr eps)^2`` (``kappa = lambda + mu``); symmetric,
    indefinite, and valid for the incompressible ``1/kappa = 0`` (docs/method.md section 10)."""
    import ufl
    dx = ufl.dx
    a_uu = thickness * 2.0 * mu * ufl.inner(deviator(strain(u)), deviator(strain(v))) * dx
    a_up = thickness * p * ufl.div(v) * dx
    a_pu = thickness * q * ufl.div(u) * dx
    a_pp = -thickness * inv_kappa * p * q * dx
    return [[a_uu, a_up], [a_pu, a_pp]]


def mixed_mass(mass, p, q):
    """The mixed element's mass blocks ``[[mass, None], [None, 0 p q]]`` (UFL): the displacement's
    ``mass`` form and an explicit zero pressure block (the pressure carries no mass; the block keeps
    the pressure's diagonal in the matrix's pattern)."""
    import dolfinx.fem
    import ufl
    zero = dolfinx.fem.Constant(p.ufl_function_space().mesh, 0.0)
    return [[mass, None], [None, zero * p * q * ufl.dx]]


def mixed_von_mises(u, p, mu, two_nu, plane: str):
    """UFL von Mises stress of the mixed element: the in-plane stress :func:`mixed_stress` and
    ``s_zz = 2 nu p`` in plane strain (``lambda tr eps`` with ``p = (lambda + mu) tr eps``), 0 in
    plane stress; ``two_nu`` is ``2 nu`` per cell."""
    import ufl
    s = mixed_stress(u, p, mu)
    szz = two_nu * p if plane == "strain" else 0.0
    sxx, syy, sxy = s[0, 0], s[1, 1], s[0, 1]
    return ufl.sqrt(0.5 * ((sxx - syy) ** 2 + (syy - szz) ** 2 + (szz - sxx) ** 2) + 3.0 * sxy ** 2)
