"""Bifurcation sweeps: parallel kernel against single runs, continuation, progress, cancel, input."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rattle_core import RattleParams, SweepResult, classify, simulate, sweep
from rattle_core.batch.sweep import MAX_VALUES

HARM = RattleParams(lam=1.0)
TWO_H = RattleParams(lam=2.0, amplitudes=(1.0, 0.25), phases_deg=(0.0, -135.0))


def _rows(res: SweepResult, k: int):
    """Impact rows of the k-th swept value (the table is in value order, counts in summary)."""
    counts = (res.summary["n_active"] + res.summary["n_reverse"]).to_numpy()
    lo = int(counts[:k].sum())
    return res.table.iloc[lo:lo + int(counts[k])]


def _check_against_simulate(res: SweepResult, base: RattleParams, name: str, transient: int,
                            record: int, starts=None):
    assert np.all(res.summary["status"] == 0)
    for k, val in enumerate(res.values):
        x0, v0 = (None, 0.0) if starts is None else starts[k]
        p = base.with_value(name, float(val))
        tr = simulate(p, periods=record, transient=transient, x0=x0, v0=v0, lyapunov=True)
        rows = _rows(res, k)
        assert np.all(rows["value"].to_numpy() == val)
        assert len(rows) == len(tr.impact_impulse), (name, val)
        np.testing.assert_allclose(rows["impulse"].to_numpy(), tr.impact_impulse, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(rows["flank"].to_numpy(), tr.impact_flank)
        np.testing.assert_allclose(rows["phase"].to_numpy(), tr.impact_phase, rtol=0, atol=1e-12)
        s = res.summary.iloc[k]
        c = classify(tr)
        assert s["regime"] == c.regime and s["period"] == c.period
        assert math.isclose(s["stick_fraction"], c.stick_fraction, abs_tol=1e-12)
        if math.isfinite(c.lyapunov):
            assert math.isclose(s["lyapunov"], c.lyapunov, rel_tol=1e-9, abs_tol=1e-12)
        else:
            assert s["lyapunov"] == c.lyapunov


def test_parallel_sweep_equals_single_runs():
    """The parallel kernel gives, value by value, the impacts of ``simulate`` (to 1e-12)."""
    vals = np.array([0.8, 1.05, 1.13, 1.16, 1.3, 1.45, 2.0, 3.3, 3.9, 1.2, 2.6, 0.95])
    res = sweep(HARM, "lam", vals, transient=150, record=40, chunk_size=5)
    np.testing.assert_array_equal(res.values, vals)
    assert set(res.summary["regime"]) >= {"A", "B", "C", "D", "E"}
    _check_against_simulate(res, HARM, "lam", 150, 40)


@pytest.mark.parametrize("name, base, vals", [
    ("h2", TWO_H, [0.0, 0.1, 0.4]),
    ("phi2", TWO_H, [-135.0, 0.0, 200.0]),
    ("r", HARM.replace(lam=2.0), [0.3, 0.65, 0.9]),
    ("j", HARM.replace(lam=2.0), [2.0, 8.0, 20.0]),
    ("phi3", TWO_H, [0.0, 90.0]),      # adds a third harmonic of amplitude 0: y is unchanged
])
def test_sweep_any_parameter(name, base, vals):
    """Sweeping ``h2``, ``phi2``, ``r``, ``j`` (and a new ``phi3``) matches single runs."""
    res = sweep(base, name, vals, transient=100, record=30)
    assert res.name == name
    _check_against_simulate(res, base, name, 100, 30)
    assert len(set(np.round(res.table["impulse"], 9))) > 1


def test_h3_sweep_changes_the_response():
    """A new harmonic's amplitude ``h3`` really enters the excitation."""
    res = sweep(TWO_H, "h3", [0.0, 0.3], transient=100, record=20)
    a, b = _rows(res, 0), _rows(res, 1)
    assert len(a) != len(b) or not np.allclose(a["impulse"], b["impulse"])
    _check_against_simulate(res, TWO_H, "h3", 100, 20)


HYST = np.round(np.arange(1.10, 1.2501, 0.01), 4)


@pytest.fixture(scope="module")
def hysteresis():
    up = sweep(HARM, "lam", HYST, transient=300, record=100, mode="continuation")
    down = sweep(HARM, "lam", HYST[::-1], transient=300, record=100, mode="continuation")
    fresh = sweep(HARM, "lam", HYST, transient=300, record=100)
    return up, down, fresh


def test_continuation_reveals_coexisting_attractors(hysteresis):
    """Harmonic Λ ∈ [1.10, 1.25]: going up keeps the stick-and-impact orbit, going down keeps
    the one-sided orbit C and two-flank chaos: the two branches differ at the same Λ."""
    up, down, fresh = hysteresis
    ru = dict(zip(up.summary["value"], up.summary["regime"]))
    rd = dict(zip(down.summary["value"], down.summary["regime"]))
    differ = [v for v in HYST if ru[v] != rd[v]]
    assert len(differ) >= 5, (ru, rd)
    # up: the sticking orbit born below Λ = 1.12 survives the whole range
    assert sum(ru[v] == "B" for v in HYST) >= 10
    # down: the branch reached from above has no sticking at all in [1.10, 1.14] ...
    assert all(rd[v] in "CD" for v in HYST if v <= 1.14)
    # ... and shows both C and chaos (two-flank) in the range
    assert {"C", "D"} <= set(rd.values())
    dd = down.summary[down.summary["regime"] == "D"]
    assert (dd["n_reverse"] > 0).all()
    # same Λ, different attractor: the impulses differ
    v = differ[0]
    iu = up.table.loc[up.table["value"] == v, "impulse"].to_numpy()
    idn = down.table.loc[down.table["value"] == v, "impulse"].to_numpy()
    assert len(iu) != len(idn) or not np.allclose(np.sort(iu), np.sort(idn))
    # fresh starts agree with neither branch everywhere: it lands on both
    rf = dict(zip(fresh.summary["value"], fresh.summary["regime"]))
    assert any(rf[v] != ru[v] for v in HYST) and any(rf[v] != rd[v] for v in HYST)


def test_continuation_carries_the_final_state(hysteresis):
    """Each continuation value starts from the previous value's final state (at t = 2πN ≡ 0)."""
    down = hysteresis[1]
    vals = down.values[:4]
    starts = [(None, 0.0)]
    for v in vals[:-1]:
        tr = simulate(HARM.replace(lam=float(v)), periods=100, transient=300,
                      x0=starts[-1][0], v0=starts[-1][1])
        starts.append((tr.final_state[1], tr.final_state[2]))
    part = SweepResult(name="lam", values=vals, params=HARM, settings={},
                       table=down.table.iloc[:int((down.summary["n_active"] + down.summary["n_reverse"])[:4].sum())],
                       summary=down.summary.iloc[:4])
    _check_against_simulate(part, HARM, "lam", 300, 100, starts=starts)


@pytest.mark.parametrize("mode", ["fresh", "continuation"])
def test_progress_counts_increase_to_total(mode):
    """``progress`` is called with increasing counts that end at the total."""
    calls = []
    vals = np.linspace(1.5, 3.5, 23)
    res = sweep(HARM, "lam", vals, transient=20, record=10, mode=mode, chunk_size=5,
                progress=lambda done, total: calls.append((done, total)))
    assert not res.cancelled and len(res.values) == 23
    assert len(calls) >= 4
    done = [c[0] for c in calls]
    assert all(c[1] == 23 for c in calls)
    assert all(b > a for a, b in zip(done, done[1:]))
    assert done[-1] == 23


@pytest.mark.parametrize("mode", ["fresh", "continuation"])
def test_cancel_stops_early(mode):
    """``cancel`` returning True stops the sweep: ``cancelled`` is set, only a prefix is done."""
    vals = np.linspace(1.5, 3.5, 40)
    seen = []
    res = sweep(HARM, "lam", vals, transient=20, record=10, mode=mode, chunk_size=8,
                progress=lambda d, n: seen.append(d), cancel=lambda: bool(seen) and seen[-1] >= 8)
    assert res.cancelled
    assert 0 < len(res.values) < 40
    np.testing.assert_array_equal(res.values, vals[:len(res.values)])
    assert len(res.summary) == len(res.values)
    assert set(res.table["value"]) <= set(res.values)


def test_cancel_before_start_gives_an_empty_result():
    """Cancelling at once returns an empty, cancelled result with the usual columns."""
    res = sweep(HARM, "lam", [2.0, 3.0], transient=10, record=5, cancel=lambda: True)
    assert res.cancelled and len(res.values) == 0 and len(res.table) == 0
    assert {"value", "regime", "lyapunov"} <= set(res.summary.columns)


def test_dask_executor_matches_local():
    """A Dask client runs the same chunks and returns the same diagram as the local kernel."""
    distributed = pytest.importorskip("dask.distributed")
    vals = np.linspace(1.5, 3.5, 10)
    local = sweep(HARM, "lam", vals, transient=50, record=20)
    with distributed.Client(processes=False, n_workers=1, threads_per_worker=2,
                            dashboard_address=":0") as client:
        calls = []
        remote = sweep(HARM, "lam", vals, transient=50, record=20, executor=client, chunk_size=4,
                       progress=lambda d, n: calls.append(d))
    assert calls[-1] == 10
    np.testing.assert_array_equal(remote.values, local.values)
    np.testing.assert_array_equal(remote.table["impulse"], local.table["impulse"])
    assert list(remote.summary["regime"]) == list(local.summary["regime"])


_CONCURRENT = """
import threading, numpy as np
from rattle_core import RattleParams, sweep
vals = np.linspace(1.5, 3.5, 16)
ref = sweep(RattleParams(lam=1.0), "lam", vals, transient=30, record=10)
out = [None] * 4
def run(k):
    out[k] = sweep(RattleParams(lam=1.0), "lam", vals, transient=30, record=10, chunk_size=4)
threads = [threading.Thread(target=run, args=(k,)) for k in range(4)]
[t.start() for t in threads]
[t.join() for t in threads]
for res in out:
    np.testing.assert_array_equal(res.table["impulse"], ref.table["impulse"])
print("same")
"""


def test_sweeps_from_many_threads_share_the_kernel_safely():
    """Numba's workqueue layer aborts on concurrent parallel launches; sweeps must not."""
    import subprocess
    import sys
    env = {**__import__("os").environ, "NUMBA_THREADING_LAYER": "workqueue"}
    done = subprocess.run([sys.executable, "-c", _CONCURRENT], env=env, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "same"


@pytest.mark.parametrize("kwargs, word", [
    ({"values": []}, "values"),
    ({"values": [1.0, float("nan")]}, "values"),
    ({"values": [1.0, float("inf")]}, "values"),
    ({"values": "abc"}, "values"),
    ({"name": "foo"}, "foo"),
    ({"name": "h1"}, "h1"),
    ({"name": "phi99"}, "phi99"),
    ({"name": "lam", "values": [-1.0, 2.0]}, "lam"),
    ({"name": "r", "values": [0.5, 1.5]}, "r"),
    ({"name": "j", "values": [0.0]}, "j"),
    ({"name": "h2", "values": [-0.1]}, "h_?2"),
    ({"transient": -1}, "transient"),
    ({"transient": 1.5}, "transient"),
    ({"transient": 10**9}, "transient"),
    ({"record": 0}, "record"),
    ({"record": 10**7}, "record"),
    ({"values": np.linspace(1, 2, 100_000), "transient": 100_000, "record": 100}, "values ×"),
    ({"mode": "sideways"}, "mode"),
    ({"chunk_size": 0}, "chunk_size"),
    ({"x0": float("nan")}, "x0"),
    ({"v0": float("inf")}, "v0"),
])
def test_bad_input_raises_value_error_naming_it(kwargs, word):
    """Bad sweep input raises ``ValueError`` naming the parameter, before any work."""
    args = {"base": HARM, "name": "lam", "values": [1.0, 2.0], "transient": 10, "record": 5}
    args.update(kwargs)
    with pytest.raises(ValueError, match=word):
        sweep(**args)


def test_period_budget_is_the_documented_one():
    """A sweep or a map of more than PERIOD_BUDGET forcing periods is refused before it runs,
    naming the product and the budget; one just under the budget is accepted (and cancelled)."""
    from rattle_core.batch.maps import regime_map
    from rattle_core.batch.sweep import PERIOD_BUDGET
    n = 1000
    over = int(PERIOD_BUDGET // n)  # n × (over + 1) periods: just over the budget
    with pytest.raises(ValueError, match=r"values × \(transient \+ record\) = 1e\+08 forcing "
                                         r"periods is over the budget of 1e\+08"):
        sweep(HARM, "lam", np.linspace(1, 2, n), transient=over, record=1)
    with pytest.raises(ValueError, match="points × .* is over the budget"):
        regime_map(HARM, "lam", np.linspace(1, 2, 10), "r", np.linspace(0.1, 0.9, 100),
                   transient=over, record=1)
    res = sweep(HARM, "lam", np.linspace(1, 2, n), transient=over - 1, record=1,
                cancel=lambda: True)
    assert res.cancelled


def test_too_many_values():
    """More than ``MAX_VALUES`` values is refused with a message naming ``values``."""
    with pytest.raises(ValueError, match="values"):
        sweep(HARM, "lam", np.full(MAX_VALUES + 1, 2.0), transient=0, record=1)


def test_base_must_be_params():
    """A base that is not a ``RattleParams`` is refused by name."""
    with pytest.raises(ValueError, match="base"):
        sweep({"lam": 1.0}, "lam", [1.0])


def test_summary_equals_classify_arrays_value_for_value():
    """The compiled per-chunk summary equals ``classify_arrays`` run on each value's own
    impacts and section, field by field, over responses of every regime."""
    from rattle_core.analysis.classify import classify_arrays
    from rattle_core.batch.chunks import run_chunk
    from rattle_core.batch.sweep import _summarise
    runs = [(HARM, [0.5, 1.03, 1.147, 1.235, 1.264, 1.41, 1.68, 3.3]),
            (TWO_H, [0.8, 1.09, 1.59, 2.41, 2.47])]
    seen = set()
    for base, vals in runs:
        # strict mode keeps a chaotic window that sticks ("D", True) among the responses
        chunk = run_chunk(base.replace(noise=0.0), "lam", np.array(vals), 150, 40, None, 0.0)
        summary = _summarise(chunk, 40)
        off = 0
        for k, val in enumerate(vals):
            n = chunk["counts"][k]
            imp, fl = chunk["impulse"][off:off + n], chunk["flank"][off:off + n]
            off += n
            c = classify_arrays(imp, fl, chunk["str_x"][k], chunk["str_v"][k], 40,
                                chunk["stick"][k], chunk["lyap"][k], chunk["j"][k],
                                chunk["rounding"][k], chunk["loop_amp"][k], chunk["kicks"][k])
            s = summary.iloc[k]
            seen.add((c.regime, c.stick_fraction > 0))
            assert s["value"] == val and s["status"] == 0
            assert s["regime"] == c.regime and s["period"] == c.period and s["chaotic"] == c.chaotic
            assert s["sticking"] == c.sticking and s["loop_amplification"] == c.loop_amplification
            assert s["n_active"] == np.sum(fl == 1) and s["n_reverse"] == np.sum(fl == -1)
            for field in ("active_per_period", "reverse_per_period", "stick_fraction",
                          "intensity", "lyapunov"):
                want = getattr(c, field)
                assert s[field] == want or (math.isnan(want) and math.isnan(s[field])), (val, field)
    assert {r for r, _ in seen} == set("ABCDEPQ") and ("D", True) in seen
