"""The command line ``python -m app run|validate|render|check`` (the ``contact-divergence``
console script)."""
