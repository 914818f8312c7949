"""The run-up replay's work, run in the job pool's worker processes.

:func:`replay` drives the gearbox through the run (and, if asked, the run-down over the same
speeds) through the disk cache (:func:`rattle_core.store.runups.cached_runup`), sets it against
the quasi-steady verdict when one is given (:func:`rattle_core.batch.runup.compare`), and
returns plain data: the page needs the series, the tables and the sound scaled for playback,
not the replays.  Progress is reported per run; Cancel is polled between runs (the pool kills
a run that does not stop).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .jobs import cancelled, report

#: The pool's limit on a replay [s]; the period budget refuses longer runs before they start.
RUNUP_JOB_LIMIT = 600.0
#: The inputs' ranges on the page: a run's length [s].
DURATION_RANGE_S = (0.1, 120.0)


def check(box: Any, rpm_from: float, rpm_to: float, duration_s: float) -> None:
    """Refuse a request the page cannot run, naming the input and its range (``ValueError``)."""
    from ..core import check_run
    lo, hi = DURATION_RANGE_S
    if not (isinstance(duration_s, (int, float)) and lo <= duration_s <= hi):
        raise ValueError(f"duration = {duration_s!r} s is outside the allowed range "
                         f"[{lo:g}, {hi:g}] s")
    if rpm_from == rpm_to:
        raise ValueError(f"rpm from ({rpm_from:g}) and rpm to ({rpm_to:g}) must differ")
    check_run(box, rpm_from, rpm_to, duration_s)


def _same_box(a: Any, b: Any) -> bool:
    """Whether two gearboxes are the same machine (their targets aside)."""
    from ..core import canonical_hash
    ca, cb = a.canonical(), b.canonical()
    ca.pop("target", None)
    cb.pop("target", None)
    return canonical_hash(ca) == canonical_hash(cb)


def replay(box: Any, rpm_from: float, rpm_to: float, duration_s: float, rundown: bool = False,
           verdict: Any = None) -> dict | None:
    """The run (and the run-down if asked) as plain data; ``None`` when cancelled.

    Returns ``time_s``, ``rpm_t``, ``loudness_t``, ``level_dba_t`` (the series against the
    run's rpm), ``intervals`` and ``impacts_per_gear`` (tables as column dicts), ``onsets``
    (the comparison's table, or None) and ``text`` (where the quasi-steady answer holds, or why
    there is no comparison), ``signal`` (normalised to 0.99), ``rate``, ``calibration_pa``,
    ``rpm_from``, ``rpm_to``, ``duration_s`` and ``from_cache``.
    """
    from ..core import cached_runup, normalize
    from ..core import compare_runup as compare
    check(box, rpm_from, rpm_to, duration_s)
    steps = 2 if rundown else 1
    report(0, steps)
    run, hit = cached_runup(box, rpm_from, rpm_to, duration_s)
    report(1, steps)
    back = None
    if rundown:
        if cancelled():
            return None
        back, _ = cached_runup(box, rpm_to, rpm_from, duration_s)
        report(2, steps)
    if cancelled():
        return None
    onsets, text = None, ""
    if verdict is None:
        text = "No verdict to compare with: run the verdict to set the run against it."
    elif not _same_box(verdict.gearbox, box):
        text = ("The verdict shown is of another gearbox (the gears or the measurement changed "
                "since): run the verdict again to compare.")
    else:
        cmp_ = compare(run, verdict, back)
        onsets, text = cmp_.onsets.to_dict("list"), cmp_.text
    imp = run.impacts
    return {"time_s": run.time_s, "rpm_t": run.rpm_t, "loudness_t": run.loudness_t,
            "level_dba_t": run.level_dba_t, "intervals": run.intervals.to_dict("list"),
            "impacts_per_gear": {str(k): int(v) for k, v in imp["gear"].value_counts().items()},
            "onsets": onsets, "text": text,
            "signal": normalize(run.pressure_pa).astype(np.float32), "rate": run.sample_rate,
            "calibration_pa": run.calibration_pa, "rpm_from": run.rpm_from,
            "rpm_to": run.rpm_to, "duration_s": run.duration_s, "from_cache": bool(hit)}
