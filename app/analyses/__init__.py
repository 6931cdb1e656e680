"""The analyses of one classified equilibrium state (paper sections 3-4), grouped by problem.

- :mod:`.runner`: every analysis the scene asks for at one state; :mod:`.zero_nodes` the same for
  a state with zero-reaction nodes (the paper's set Z); :mod:`.outcomes` their typed outcomes.
- :mod:`.pencils`: the reduced pencils (10)-(16) of a state (:mod:`.pencils.reduced`), built
  lazily per state (:mod:`.pencils.state`), with a curved obstacle's terms
  (:mod:`.pencils.curvature`, :mod:`.pencils.curved_split`) and the kept contact unknowns
  (:mod:`.pencils.kept_contact`).
- :mod:`.conditions`: the necessary condition (19) and the sufficient condition (17)-(18).
- :mod:`.mceip_mu`: MCEIP-mu (21)-(23): the per-state result (:mod:`.mceip_mu.state`), the
  prover (:mod:`.mceip_mu.prover`), its trusted kernel and checker (:mod:`.mceip_mu.kernel`),
  the quadratic problem of a curved obstacle (:mod:`.mceip_mu.quadratic`).
- :mod:`.mceip_lambda2`: MCEIP-lambda^2 (12)-(14): proofs of no solution, else a search.
- :mod:`.snes_vi`: the MCP searches of Propositions 1-2 (27)-(34) with PETSc's SNES VI, used by
  both MCEIPs; :mod:`.enumerate`: the exhaustive enumeration (24)-(26) of either MCEIP.
"""
