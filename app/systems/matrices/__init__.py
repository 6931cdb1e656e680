"""``system.type: matrices``: a discrete system given as matrix files: schema, file readers, the
positive-definiteness check and the loading path."""
