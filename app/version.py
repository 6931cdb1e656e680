"""The app's version (kept equal to pyproject.toml's; ``python -m app --version`` prints it)."""

__version__ = "0.1.0"
