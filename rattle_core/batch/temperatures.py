"""A gearbox's verdict over oil temperatures: the rpm × temperature map of regime, loudness and
pass/fail that answers the cold-idle and hot-idle question in one table.

The oil's viscosity sets the drag of every gear whose drag depends on temperature
(:mod:`rattle_core.model.drag`), and with it Λ and the contact boundary; each temperature is
one :func:`~rattle_core.batch.gearbox.verdict` of the box at that temperature
(:meth:`~rattle_core.model.gearbox.Gearbox.replace` with ``oil_temp_C``).  The table holds the
verdict's columns (:data:`~rattle_core.batch.gearbox.COLUMNS`) after ``oil_temp_C`` [°C].
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..model.drag import TEMP_RANGE
from ..model.gearbox import Gearbox
from ..model.params import check_range
from .gearbox import COLUMNS, verdict

#: Most temperatures of one map.
MAX_TEMPS = 50


def check_temps(temps_C: Any) -> list[float]:
    """Oil temperatures of a map: 1 to :data:`MAX_TEMPS` values in −40 … 150 °C."""
    try:
        values = list(np.atleast_1d(np.asarray(temps_C, dtype=object)))
    except (TypeError, ValueError):
        raise ValueError(f"temps_C must be numbers, got {temps_C!r:.100}") from None
    if not 1 <= len(values) <= MAX_TEMPS:
        raise ValueError(f"temps_C has {len(values)} values; the allowed range is 1 to "
                         f"{MAX_TEMPS}")
    return [check_range("oil temperature", v, *TEMP_RANGE) for v in values]


def verdict_over_temperatures(gearbox: Gearbox, rpm: Any, temps_C: Any, **kw: Any):
    """The verdict at each oil temperature in ``temps_C`` [°C], one table (module docstring).

    ``kw`` goes to :func:`~rattle_core.batch.gearbox.verdict` (``transient``, ``record``,
    ``target``, ...).  Temperatures outside −40 … 150 °C raise ``ValueError`` with the range.
    """
    import pandas as pd
    if not isinstance(gearbox, Gearbox):
        raise ValueError(f"gearbox must be a Gearbox, got {type(gearbox).__name__}")
    frames = []
    for temp in check_temps(temps_C):
        table = verdict(gearbox.replace(oil_temp_C=temp), rpm, **kw).table
        frames.append(table.assign(oil_temp_C=temp)[["oil_temp_C"] + COLUMNS])
    return pd.concat(frames, ignore_index=True)


__all__ = ["verdict_over_temperatures", "check_temps", "MAX_TEMPS"]
