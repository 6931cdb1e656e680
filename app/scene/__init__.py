"""Scene files: the YAML schema validated by pydantic into frozen objects, the sections beside the
system, the cases of a sweep and the resource pre-flight."""
