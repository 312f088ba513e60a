"""ident: dynamic parameter identification of serial robot arms.

The heavy parts (Pinocchio, numba) are imported on first use, so ``import ident`` is cheap.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = ["Robot", "__version__"]

__version__ = "0.1.0"

_LAZY = {"Robot": "ident.model"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'ident' has no attribute {name!r}")
