"""MCEIP-mu (paper eqs. (21)-(23)), the critical friction coefficients.

- :mod:`.state`: the MCEIP-mu result of one state (candidate search, then the proof).
- :mod:`.proven`: the proven condensed MCEIP-mu of a pencil (``mceip_mu``: prover, then checker).
- :mod:`.prover`: the branch and bound that builds a proof log (guided by floating-point
  heuristics, never trusted).
- :mod:`.kernel`: the trusted kernel: rounding model, closing tests with witnesses, verified
  eigenpairs, the proof log and its independent checker. It imports nothing from the prover.
- :mod:`.candidates`: the dense candidate search (semismooth Newton).
- :mod:`.quadratic`: the quadratic problem of a curved obstacle, its branch and bound and proof.
"""
