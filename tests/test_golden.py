"""Nothing computed changes: runs, sweeps and maps equal, bit for bit, arrays saved earlier.

``tests/data/golden_*.npz`` were written by this file (``python tests/test_golden.py --write``)
from the code as it stood before the package was split into layers, and every later
restructuring must reproduce them to the last bit.  A change that is meant to alter the numbers
(a new solver version) regenerates them on purpose, in the same commit.

Why these cases.  The release of a stick phase is where the solver may legitimately change how
it resolves rounding (a chaotic run that sticks forgets its past, and the first bits that differ
decide where it goes next).  Every case here therefore either never sticks, over its whole run
including the transient, or sticks on a robust periodic stick orbit (regime B at Λ = 1.05 and
1.35, harmonic: the gear sticks every period and leaves at the phase where ``R̃ = 1 + Λ ÿ``
changes sign, whatever happened before).  The test checks that precondition too, so a case that
starts to stick is reported as such, not as a mismatch.  Covered: regimes B, C, D (two chaotic
runs that never stick), E and P/Q; a start off the default state; fresh and continuation sweeps
in several chunks; a regime map and a basin map in several chunks.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from rattle_core import RattleParams, simulate, sweep
from rattle_core.batch.maps import basin_map, regime_map

DATA = Path(__file__).resolve().parent / "data"

#: name → (parameters, simulate() keywords).  All but the B cases never stick.
RUNS = {
    "E_harmonic_3.3": (RattleParams(lam=3.3), {}),
    "E_harmonic_2.0_offset_start": (RattleParams(lam=2.0),
                                    {"x0": 3.0, "v0": 0.5, "t0": 0.3, "strobe_phase": 1.0}),
    "C_harmonic_1.2": (RattleParams(lam=1.2), {}),
    "D_harmonic_1.16": (RattleParams(lam=1.16), {}),
    "D_paper_phi45_3.3": (RattleParams.paper(3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0)),
                          {}),
    "B_harmonic_1.05": (RattleParams(lam=1.05), {}),
}
STICKING = {"B_harmonic_1.05"}
RUN_LENGTH = {"periods": 300, "transient": 200}
_TRAJ_FIELDS = ("impact_t", "impact_phase", "impact_impulse", "impact_flank", "impact_w",
                "strobe_t", "strobe_x", "strobe_v", "seg_t", "seg_kind", "seg_x", "seg_v")


def _sweep_values() -> np.ndarray:
    # Λ = 1.40, 1.45 (stick-locked, periods 6 and 3) and 1.50 (one stick in its transient)
    # stick after chaotic stretches, so they are left out; 1.35 is a period-1 stick orbit.
    v = np.linspace(1.3, 2.5, 25)
    return v[(v < 1.38) | (v > 1.52)]


SWEEP_SETTINGS = {"transient": 200, "record": 50, "chunk_size": 8}
CONT_VALUES = np.linspace(2.5, 1.8, 8)
MAP_BASE = RattleParams(lam=2.0, amplitudes=(1.0, 0.0), phases_deg=(0.0, 90.0))
MAP_AXES = ("lam", np.linspace(1.8, 2.5, 8), "h2", np.linspace(0.0, 0.08, 5))
MAP_SETTINGS = {"transient": 200, "record": 50, "chunk_size": 7}
BASIN_PARAMS = RattleParams(lam=2.5)
BASIN_AXES = (np.linspace(2.5, 8.5, 5), np.linspace(-1.0, 1.0, 4))
BASIN_SETTINGS = {"transient": 200, "record": 80, "chunk_size": 6}


def compute_runs() -> dict[str, np.ndarray]:
    out = {}
    for name, (p, kw) in RUNS.items():
        tr = simulate(p, lyapunov=True, **RUN_LENGTH, **kw)
        for f in _TRAJ_FIELDS:
            out[f"{name}/{f}"] = getattr(tr, f)
        out[f"{name}/scalars"] = np.array([tr.t_start, tr.t_end, *tr.final_state,
                                           tr.lyapunov_sum, tr.lyapunov_time, tr.stick_time,
                                           tr.n_stick_phases], dtype=np.float64)
    return out


def _frame(prefix: str, df) -> dict[str, np.ndarray]:
    out = {}
    for c in df.columns:
        a = df[c].to_numpy()
        out[f"{prefix}/{c}"] = a.astype("U8") if a.dtype.kind == "O" else a
    return out


def compute_sweeps() -> dict[str, np.ndarray]:
    st = dict(SWEEP_SETTINGS)
    fresh = sweep(RattleParams(lam=1.0), "lam", _sweep_values(), **st)
    cont = sweep(RattleParams(lam=1.0), "lam", CONT_VALUES, mode="continuation", **st)
    out = {}
    for tag, res in (("fresh", fresh), ("continuation", cont)):
        out.update(_frame(f"{tag}/table", res.table))
        out.update(_frame(f"{tag}/summary", res.summary))
    return out


def compute_maps() -> dict[str, np.ndarray]:
    xn, xv, yn, yv = MAP_AXES
    m = regime_map(MAP_BASE, xn, xv, yn, yv, **MAP_SETTINGS)
    b = basin_map(BASIN_PARAMS, *BASIN_AXES, **BASIN_SETTINGS)
    out = {f"regime/{k}": v for k, v in m.fields.items()}
    out.update({f"basin/{k}": v for k, v in b.fields.items()})
    out["basin/attractors"] = np.array([repr(sorted(a.items())) for a in b.attractors])
    return out


COMPUTE = {"runs": compute_runs, "sweeps": compute_sweeps, "maps": compute_maps}


def _assert_same(kind: str) -> None:
    with np.load(DATA / f"golden_{kind}.npz", allow_pickle=False) as z:
        saved = {k: z[k] for k in z.files}
    now = COMPUTE[kind]()
    # later versions may add columns (issue 8 added ``sticking``); the saved ones must stay
    missing = sorted(set(saved) - set(now))
    assert not missing, f"{kind}: arrays no longer computed: {missing}"
    for k in saved:
        a, b = now[k], saved[k]
        assert a.dtype.kind == b.dtype.kind and a.shape == b.shape, (k, a.dtype, b.dtype, a.shape,
                                                                     b.shape)
        # bit for bit: compare the bytes, so NaN == NaN and −0.0 != +0.0
        same = (np.array_equal(a, b) if a.dtype.kind in "UOb"
                else np.ascontiguousarray(a).tobytes() == np.ascontiguousarray(b).tobytes())
        assert same, f"{kind}: {k} differs from the saved arrays"


def test_cases_never_stick_except_stick_orbits():
    """The precondition of the golden cases: no stick phase over a whole run, bar the B orbits."""
    for name, (p, kw) in RUNS.items():
        tr = simulate(p, periods=RUN_LENGTH["periods"] + RUN_LENGTH["transient"], **kw)
        assert (tr.n_stick_phases > 0) == (name in STICKING), name
    whole = SWEEP_SETTINGS["transient"] + SWEEP_SETTINGS["record"]
    for v in _sweep_values():
        tr = simulate(RattleParams(lam=float(v)), periods=whole)
        assert tr.n_stick_phases == 0 or v == pytest.approx(1.35), v
    for lam in MAP_AXES[1]:
        for h2 in MAP_AXES[3]:
            p = MAP_BASE.replace(lam=float(lam), amplitudes=(1.0, float(h2)))
            assert simulate(p, periods=whole).n_stick_phases == 0, (lam, h2)
    whole = BASIN_SETTINGS["transient"] + BASIN_SETTINGS["record"]
    for x0 in BASIN_AXES[0]:
        for v0 in BASIN_AXES[1]:
            tr = simulate(BASIN_PARAMS, periods=whole, x0=float(x0), v0=float(v0))
            assert tr.n_stick_phases == 0, (x0, v0)


def test_simulate_runs_are_unchanged():
    """Six single runs (regimes B, C, D, E) equal the saved trajectories bit for bit."""
    _assert_same("runs")


def test_sweeps_are_unchanged():
    """A fresh and a continuation Λ sweep equal the saved tables and summaries bit for bit."""
    _assert_same("sweeps")


def test_maps_are_unchanged():
    """A regime map over Λ × h₂ and a basin map equal the saved fields bit for bit."""
    _assert_same("maps")


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        sys.exit("usage: python tests/test_golden.py --write   (overwrites tests/data/golden_*.npz)")
    DATA.mkdir(exist_ok=True)
    for kind, fn in COMPUTE.items():
        np.savez_compressed(DATA / f"golden_{kind}.npz", **fn())
        print("wrote", DATA / f"golden_{kind}.npz")
