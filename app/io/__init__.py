"""A study's results: the results.json format and its typed views, the results folder, the stored
proofs, the ParaView fields, report.md and the summary printed at the end of a run."""
