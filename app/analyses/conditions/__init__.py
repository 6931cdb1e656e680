"""The necessary condition (19) and the sufficient condition (17)-(18) of divergence.

- :mod:`.full_size`: both conditions on the full-size pencils (SLEPc, inertia counts).
- :mod:`.contact_spectrum`: the values of (19) from the contact DOFs (docs/method.md section 2),
  the path above ``EigSettings.necessary_contact_min_dofs``; :mod:`.interior_modes` the interior
  eigenpairs it needs, :mod:`.value_bounds` the bounds it reports once its budget is spent.
- :mod:`.eliminated`: the values of (19) for a system with static DOFs (the mixed element's
  pressure), from the contact DOFs or, where they decline, the dense eliminated pencils.
"""
