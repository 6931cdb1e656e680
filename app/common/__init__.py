"""What every stage of app/ may use: user-facing errors and exit statuses, logging, progress lines,
PETSc options, library warnings explained, stage timings, the pydantic base of the schemas and the
process-wide patches of the runtime (runtime.py)."""
