"""The values of the necessary condition (19) for a system with static DOFs (the mixed element's
pressure, docs/method.md section 10): from the contact DOFs (:mod:`.contact_spectrum`, which
eliminates the pressure with the interior), and where they decline a classification, from the
reduced pencils with the pressure eliminated densely."""
from __future__ import annotations

import numpy as np
import scipy.linalg

from app.analyses.conditions import full_size
from app.analyses.conditions.contact_spectrum import values
from app.analyses.pencils.reduced import dense, eliminate_static
from app.loading.classify import FREE, SLIP

#: largest system whose values of (19) with the pressure eliminated are computed densely where the
#: contact DOFs decline a classification (a root outside the interpolated pieces)
ELIMINATED_DENSE_MAX = 4000


def eliminated_necessary(p, mu: float, eig, hints: dict):
    """The :class:`~app.analyses.outcomes.NecessaryOutcome` of (19) for a system with static DOFs
    (the mixed element's pressure) at the classification of the pencils ``p``: the full-size
    pencils hold the pressure block, and their symmetric parts are not (19)'s (docs/method.md
    section 10). From the contact DOFs; where they decline (a root outside the pieces), from the reduced
    pencils with the pressure eliminated densely (the reduction leaves the pressure rows as they
    are: ``K*_e = K*_uu - K*_up K_pp^-1 K*_pu``) up to :data:`ELIMINATED_DENSE_MAX` DOFs;
    RuntimeError above. MPI collective."""
    system = p.system
    known = values(system, p.cls, mu, hints, eig.necessary_value_work)   # MPI collective
    if any(v is None for v in known.values()):
        if system.n_dofs > ELIMINATED_DENSE_MAX:
            raise RuntimeError("the necessary condition (19) with the mixed element: the contact DOFs declined this "
                               f"classification (a root outside the interpolated pieces) and "
                               f"the system has {system.n_dofs} DOFs, above the {ELIMINATED_DENSE_MAX} of the dense "
                               "elimination")
        known = {**{k: (*v, None) for k, v in _dense_eliminated(p, mu).items()},
                 **{k: v for k, v in known.items() if v is not None}}
    return full_size.necessary(None, None, None, None, mu, eig, known=known)


def _dense_eliminated(p, mu: float) -> dict[str, tuple[float, float]]:
    """``{"K": (smallest eigenvalue of sym K*_e(mu), scale), "M": ...}`` from the dense reduced
    pencils with the static DOFs eliminated (LAPACK). The scale is the contact-DOF values' (:func:`build`
    with ``static``): the largest diagonal entry of the interior's massive DOFs as they are and of
    the kept contact DOFs eliminated. MPI collective (the pencils gathered on every rank, which all
    compute the same)."""
    system, cls = p.system, p.cls
    Ks, Ms = p.star(mu)
    K, M = dense(Ks), dense(Ms)                                       # MPI collective
    static = p.space.positions(system.static_dofs)                    # MPI collective
    kept_contact = [d for nd, st in zip(system.nodes, cls.status)
                    for d in ((nd.dof_T, nd.dof_N) if st == FREE else (nd.dof_T,) if st == SLIP else ())]
    contact = p.space.positions(np.sort(np.asarray(kept_contact, dtype=np.int64)))    # MPI collective
    Ke, Mk, keep = eliminate_static(K, M, static)
    at = np.isin(keep, contact)
    out = {}
    for name, A, whole in (("K", Ke, K), ("M", Mk, M)):
        S = 0.5 * (A + A.T)
        d = np.abs(np.diag(whole)[keep])
        d[at] = np.abs(np.diag(S))[at]
        out[name] = (float(scipy.linalg.eigvalsh(S, subset_by_index=[0, 0])[0]), float(d.max()))
    return out
