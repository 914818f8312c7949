"""matplotlib pictures of a gearbox's run-up: N(t) and dB(A)(t) against rpm with the quasi-steady
verdict's loudness overlaid and the onsets marked, and a spectrogram of the simulated sound with
the engine orders marked.  Shared by the CLI."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .drawing import agg_figure

#: Highest frequency of the spectrogram [Hz] (the housing modes ring well below it).
SPECTROGRAM_MAX_HZ = 8000.0
_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
            "#7f7f7f", "#bcbd22", "#17becf")


def runup_png(path: Path | str, run, comparison=None, verdict=None, title: str = "") -> None:
    """The run ``run`` (a :class:`~rattle_core.batch.runup.GearboxRunup` with its sound) in one
    figure: the gearbox's and each gear's N(t) against rpm, with the verdict's N5 per grid speed
    dashed and each gear's onsets marked (run: solid, verdict: dotted); L_AF(t) in dB(A)
    against rpm with the verdict's L_AFmax; the spectrogram of the sound over rpm with the
    excitation's engine orders ``engine_order · k`` marked."""
    from scipy.signal import spectrogram
    if run.time_s is None:
        raise ValueError("run must be measured with its sound (gearbox_runup(..., sound=True))")
    fig = agg_figure((10.0, 10.0), dpi=110)
    ax_n, ax_l, ax_s = fig.subplots(3, 1, sharex=True)
    names = list(run.gear_loudness_t)
    lo, hi = sorted((run.rpm_from, run.rpm_to))
    ax_n.plot(run.rpm_t, run.loudness_t, color="k", lw=1.0, label="gearbox, run")
    for i, name in enumerate(names):
        c = _COLOURS[i % len(_COLOURS)]
        ax_n.plot(run.rpm_t, run.gear_loudness_t[name], color=c, lw=0.6, alpha=0.8,
                  label=f"{name}, run")
        onset = run.onsets[name]
        if math.isfinite(onset):
            ax_n.axvline(onset, color=c, lw=1.0)
        if verdict is not None:
            rows = verdict.gear(name)
            ax_n.plot(rows["rpm"], rows["loudness_sone"], "--o", color=c, ms=2, lw=1.0,
                      label=f"{name}, verdict")
            v_on = verdict.onsets[name]
            if math.isfinite(v_on):
                ax_n.axvline(v_on, color=c, lw=1.0, ls=":")
    if verdict is not None:
        rows = verdict.gear("gearbox")
        ax_n.plot(rows["rpm"], rows["loudness_sone"], "--o", color="k", ms=2, lw=1.0,
                  label="gearbox, verdict")
        ax_l.plot(rows["rpm"], rows["spl_dba_max"], "--o", color="k", ms=2, lw=1.0,
                  label="verdict, L_AFmax")
    ax_n.set_ylabel("loudness N [sone]")
    ax_n.legend(fontsize=7, ncol=2, loc="upper left")
    ax_n.set_title(title or f"run {run.rpm_from:g} → {run.rpm_to:g} rpm in {run.duration_s:g} s "
                   "(onsets: run solid, verdict dotted)", fontsize=10)
    level = np.where(np.isfinite(run.level_dba_t), run.level_dba_t, np.nan)
    ax_l.plot(run.rpm_t, level, color="k", lw=0.8, label="run, L_AF (fast, 125 ms)")
    if np.any(np.isfinite(level)):
        # a silent stretch's level falls without end: 60 dB below the loudest is enough to see
        ax_l.set_ylim(bottom=max(0.0, float(np.nanmax(level)) - 60.0))
    ax_l.set_ylabel("level [dB(A)]")
    ax_l.legend(fontsize=7, loc="upper left")

    p = run.pressure_pa
    fs = run.sample_rate
    f, t, sxx = spectrogram(p, fs=fs, nperseg=2048, noverlap=1024, mode="psd")
    keep = f <= SPECTROGRAM_MAX_HZ
    with np.errstate(divide="ignore"):
        db = 10.0 * np.log10(np.maximum(sxx[keep], 1e-30) / (20e-6) ** 2)
    top = float(np.max(db)) if db.size else 0.0
    ax_s.pcolormesh(run.rpm_at(t), f[keep], db, shading="auto", cmap="magma",
                    vmin=top - 60.0, vmax=top, rasterized=True)
    exc = run.gearbox.excitation
    rpm = np.linspace(lo, hi, 50)
    for k in range(1, exc.harmonics + 1):
        order = exc.engine_order * k
        ax_s.plot(rpm, order * rpm / 60.0, color="c", lw=0.8, ls="--")
        ax_s.annotate(f"order {order:g}", (hi, order * hi / 60.0), fontsize=7, color="c",
                      ha="right", va="bottom")
    ax_s.set_yscale("symlog", linthresh=100.0)
    ax_s.set_ylim(0.0, SPECTROGRAM_MAX_HZ)
    ax_s.set_ylabel("frequency [Hz]")
    ax_s.set_xlabel("shaft speed [rpm]")
    ax_s.set_xlim(lo, hi)
    fig.tight_layout()
    fig.savefig(path)


__all__ = ["runup_png", "SPECTROGRAM_MAX_HZ"]
