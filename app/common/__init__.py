"""What every stage of app/ may use: user-facing errors and exit statuses, logging, progress lines,
PETSc options, library warnings explained, stage timings and the pydantic base of the schemas."""
