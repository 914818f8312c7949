"""The range check every layer uses: a bad number raises ``ValueError`` naming the parameter,
the value and the allowed range.

It sits below all of ``rattle_core``'s layers (with ``jitcache``), so the measurement layer,
the lowest, and the model share one check; ``rattle_core.model.params`` re-exports it.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

#: Shaft speeds a measurement may hold [rev/min], open at 0 (the model's engine speeds too).
RPM_RANGE = (0.0, 1.0e5)


def _finite(name: str, value: Any, allowed: str = "", text_ok: bool = False) -> float:
    where = f"; the allowed range is {allowed}" if allowed else ""
    # a bool, or text where a number is due, is a mistake even though float() would take it
    if isinstance(value, (bool, np.bool_)) or (not text_ok and isinstance(value, (str, bytes))):
        raise ValueError(f"{name} must be a real number, got {value!r}{where}")
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} must be a real number, got {value!r:.40}{where}") from None
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {v!r}{where}")
    return v


def check_range(name: str, value: Any, lo: float, hi: float, *, lo_open: bool = False,
                hi_open: bool = False, text_ok: bool = False) -> float:
    """Return ``value`` as a float, or raise ``ValueError`` naming ``name``, the value and its range.

    ``text_ok`` accepts a numeric string (a form field or a URL value); otherwise text and
    bools are refused, since ``float('3.3')`` and ``float(True)`` hide a caller's mistake.
    """
    left = "(" if lo_open else "["
    right = ")" if hi_open else "]"
    allowed = f"{left}{lo:g}, {hi:g}{right}"
    v = _finite(name, value, allowed, text_ok)
    below = v <= lo if lo_open else v < lo
    above = v >= hi if hi_open else v > hi
    if below or above:
        raise ValueError(f"{name} = {v!r} is outside the allowed range {allowed}")
    return v
