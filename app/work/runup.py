"""The run-up replay's work, run in the job pool's worker processes.

:func:`replay` drives the gearbox through the run (and, if asked, the run-down over the same
speeds), driven by the order reconstruction or by the measured angle low-pass filtered at a
cutoff (the measurement's time and speed, as the CLI's ``--wall angle`` reads them), through the
disk cache (:func:`rattle_core.store.runups.cached_runup`), sets it against
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


def check(box: Any, rpm_from: float, rpm_to: float, duration_s: float | None,
          samples: tuple | None = None, cutoff_hz: Any = None, rundown: bool = False) -> Any:
    """Refuse a request the page cannot run, naming the input and its range (``ValueError``).

    With ``samples`` (``(time_s, speed_rpm, source)`` of the measurement), the run is driven by
    the measured angle low-pass filtered at ``cutoff_hz`` over the measurement's own stretch
    between the two speeds (``duration_s`` is not used); returns that angle
    (:func:`measured`), else None."""
    from ..core import check_run, measured_window
    if rpm_from == rpm_to:
        raise ValueError(f"rpm from ({rpm_from:g}) and rpm to ({rpm_to:g}) must differ")
    if samples is None:
        lo, hi = DURATION_RANGE_S
        if not (isinstance(duration_s, (int, float)) and lo <= duration_s <= hi):
            raise ValueError(f"duration = {duration_s!r} s is outside the allowed range "
                             f"[{lo:g}, {hi:g}] s")
        check_run(box, rpm_from, rpm_to, duration_s)
        return None
    angle = measured(box, samples, cutoff_hz)
    measured_window(angle, rpm_from, rpm_to)
    if rundown:
        try:
            measured_window(angle, rpm_to, rpm_from)
        except ValueError as exc:
            raise ValueError(f"the run-down: {exc}") from None
    return angle


def measured(box: Any, samples: tuple, cutoff_hz: Any) -> Any:
    """The measured angle of ``samples`` (``(time_s, speed_rpm, source)``) filtered at
    ``cutoff_hz``, with the gearbox's engine order, as the CLI's ``--wall angle`` builds it
    (:func:`rattle_core.batch.runup.angle_of_samples`); ``ValueError`` naming ``cutoff_hz`` and
    its range (up to the sampling's Nyquist frequency)."""
    from ..core import angle_of_samples
    time_s, speed_rpm, source = samples
    return angle_of_samples(time_s, speed_rpm, cutoff_hz, box.excitation.engine_order,
                            str(source) or "the measurement")


def _same_box(a: Any, b: Any) -> bool:
    """Whether two gearboxes are the same machine (their targets aside)."""
    from ..core import canonical_hash
    ca, cb = a.canonical(), b.canonical()
    ca.pop("target", None)
    cb.pop("target", None)
    return canonical_hash(ca) == canonical_hash(cb)


def replay(box: Any, rpm_from: float, rpm_to: float, duration_s: float | None,
           rundown: bool = False, verdict: Any = None, samples: tuple | None = None,
           cutoff_hz: float | None = None) -> dict | None:
    """The run (and the run-down if asked) as plain data; ``None`` when cancelled.

    The gears are driven by the order reconstruction over ``duration_s``, or, given the
    measurement's ``samples`` (``(time_s, speed_rpm, source)``), by its angle filtered at
    ``cutoff_hz`` over its own stretch between the two speeds (``duration_s`` is not used).

    Returns ``time_s``, ``rpm_t``, ``loudness_t``, ``level_dba_t`` (the series against the
    run's rpm), ``intervals`` and ``impacts_per_gear`` (tables as column dicts), ``onsets``
    (the comparison's table, or None) and ``text`` (where the quasi-steady answer holds, or why
    there is no comparison), ``signal`` (normalised to 0.99), ``rate``, ``calibration_pa``,
    ``rpm_from``, ``rpm_to``, ``duration_s``, ``wall`` (``"orders"`` or ``"angle"``),
    ``cutoff_hz`` and ``from_cache``.
    """
    from ..core import cached_runup, normalize
    from ..core import compare_runup as compare
    angle = check(box, rpm_from, rpm_to, duration_s, samples, cutoff_hz, rundown)
    if angle is not None:
        duration_s = None
    steps = 2 if rundown else 1
    report(0, steps)
    run, hit = cached_runup(box, rpm_from, rpm_to, duration_s, angle=angle)
    report(1, steps)
    back = None
    if rundown:
        if cancelled():
            return None
        back, _ = cached_runup(box, rpm_to, rpm_from, duration_s, angle=angle)
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
            "rpm_to": run.rpm_to, "duration_s": run.duration_s, "wall": run.wall,
            "cutoff_hz": run.cutoff_hz, "from_cache": bool(hit)}
