"""The reduced pencils (10)-(16) of a classified state (docs/method.md section 2).

- :mod:`.reduced`: the pencils and their condensed forms on PETSc matrices.
- :mod:`.state`: one state's pencils, built lazily, and the per-system caches of the analyses.
- :mod:`.curvature`, :mod:`.curved_split`: the terms of a curved rigid obstacle (section 8) and
  the split pencils of its zero-reaction nodes.
- :mod:`.kept_contact`: the kept contact unknowns and the maps of the change of variables.
"""
