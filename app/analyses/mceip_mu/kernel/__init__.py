"""The trusted kernel of the MCEIP-mu proofs (docs/proofs.md): the rounding-error model
(:mod:`.rounding`), the closing tests with witnesses (:mod:`.closing`), verified isolated
eigenpairs (:mod:`.windows`), the proof log (:mod:`.prooflog`) and its checker (:mod:`.checker`).
Nothing here imports the prover (app/analyses/mceip_mu/prover/): a proof is what these modules
re-verify."""
