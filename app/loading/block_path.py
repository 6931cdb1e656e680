"""Former home of the block's loading path, now :mod:`app.systems.block.path` (the registry of system
types); these names stay importable for scripts written before the move (benchmarks/)."""
from __future__ import annotations

from app.common.errors import UnreachableLoad
from app.systems.block.path import UNITS, block_path, build_block_system

__all__ = ["UNITS", "UnreachableLoad", "block_path", "build_block_system"]
