"""The MCEIP-mu prover: the two claims (:mod:`.claims`), the branch and bound (:mod:`.branch`),
its leaves (:mod:`.leaves`), the LPs of its Farkas vectors (:mod:`.lp`), the floating-point
guides (:mod:`.heuristics`) and the progress record of a running proof (:mod:`.live`). What it
produces is re-verified by app/analyses/mceip_mu/kernel/."""
