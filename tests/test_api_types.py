"""The public API refuses wrong types with a ValueError naming the parameter; it never coerces.

Property tests: for every checked argument of the entry points, hypothesis draws values of the
wrong kind (bools for numbers, text, dicts, sets, fractional counts, non-finite numbers) and
the call must raise ``ValueError`` whose message names the argument, before any work is done.
"""
from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rattle_core import RattleParams, continue_orbit, find_orbit, simulate, sweep
from rattle_core.analysis import sound
from rattle_core.batch.maps import basin_map, regime_map
from rattle_core.store.requests import run_map

P = RattleParams(lam=3.3)
SETTINGS = settings(max_examples=40, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])

reals = st.floats(allow_nan=True, allow_infinity=True)
containers = st.one_of(st.dictionaries(st.integers(0, 5), reals, min_size=1),
                       st.sets(st.floats(-5, 5), min_size=1), st.lists(reals, max_size=3))
#: anything that is not a whole number: a bool, text, a fraction, NaN, a container, None
not_int = st.one_of(st.booleans(), st.text(max_size=5), st.none(), containers,
                    reals.filter(lambda v: not math.isfinite(v) or v != int(v)))
#: anything that is not a bool
not_bool = st.one_of(st.integers(), reals, st.text(max_size=5), st.none(), containers)
#: a "sequence of numbers" that is not one: an unordered container, text, or a list holding
#: text, bools or None
number_seq = st.lists(st.floats(0.5, 2.0), min_size=1, max_size=3)
not_numbers = st.one_of(
    st.dictionaries(st.integers(0, 5), st.floats(0, 2), min_size=1),
    st.sets(st.floats(0, 2), min_size=1), st.text(min_size=1, max_size=5),
    st.tuples(number_seq, st.one_of(st.text(max_size=3), st.booleans(), st.none()),
              st.integers(0, 3)).map(lambda t: t[0][:t[2]] + [t[1]] + t[0][t[2]:]))
not_params = st.one_of(st.none(), st.integers(), st.text(max_size=5), containers)


@functools.lru_cache(maxsize=1)
def orbit():
    return find_orbit(P, transient=200)


@functools.lru_cache(maxsize=1)
def trajectory():
    return simulate(P, periods=2)


#: (argument named in the message, call with the argument set to a value, kind of bad value)
CASES = [
    ("periods", lambda v: simulate(P, periods=v), not_int),
    ("transient", lambda v: simulate(P, periods=1, transient=v), not_int),
    ("max_impacts_per_period", lambda v: simulate(P, periods=1, max_impacts_per_period=v), not_int),
    ("lyapunov", lambda v: simulate(P, periods=1, lyapunov=v), not_bool),
    ("seed", lambda v: simulate(P, periods=1, seed=v), not_int.filter(lambda v: v is not None)),
    ("record_segments", lambda v: simulate(P, periods=1, record_segments=v), not_bool),
    ("params", lambda v: simulate(v, periods=1), not_params),
    ("amplitudes", lambda v: RattleParams(lam=1.0, amplitudes=v, phases_deg=(0.0,)), not_numbers),
    ("phases_deg", lambda v: RattleParams(lam=1.0, amplitudes=(1.0,), phases_deg=v), not_numbers),
    ("values", lambda v: sweep(P, "lam", v, transient=1, record=1), not_numbers),
    ("transient", lambda v: sweep(P, "lam", [1.0], transient=v, record=1), not_int),
    ("record", lambda v: sweep(P, "lam", [1.0], transient=1, record=v), not_int),
    ("chunk_size", lambda v: sweep(P, "lam", [1.0], transient=1, record=1, chunk_size=v),
     not_int.filter(lambda v: v is not None)),
    ("base", lambda v: sweep(v, "lam", [1.0], transient=1, record=1), not_params),
    ("base", lambda v: regime_map(v, "lam", [1.0], "r", [0.5], transient=1, record=1), not_params),
    ("x_values", lambda v: regime_map(P, "lam", v, "r", [0.5], transient=1, record=1), not_numbers),
    ("transient", lambda v: regime_map(P, "lam", [1.0], "r", [0.5], transient=v, record=1), not_int),
    ("decimals", lambda v: basin_map(P, [4.0], [0.0], transient=1, decimals=v), not_int),
    ("params", lambda v: basin_map(v, [4.0], [0.0], transient=1), not_params),
    ("use_cache", lambda v: run_map(P, None, "lam", [1.0], "r", [0.5], use_cache=v, transient=1,
                                    record=1), not_bool),
    ("max_points", lambda v: continue_orbit(orbit(), "lam", max_points=v), not_int),
    ("direction", lambda v: continue_orbit(orbit(), "lam", direction=v, max_points=1),
     st.one_of(st.booleans(), st.integers().filter(lambda i: i not in (1, -1)),
               st.text(max_size=3), st.none())),
    ("transient", lambda v: find_orbit(P, transient=v), not_int),
    ("max_period", lambda v: find_orbit(P, max_period=v), not_int),
    ("normalized", lambda v: sound.synthesize(trajectory(), normalized=v), not_bool),
    ("sample_rate", lambda v: sound.synthesize(trajectory(), sample_rate=v), not_int),
]


@pytest.mark.parametrize("name, call, bad", CASES, ids=[f"{c[0]}-{i}" for i, c in enumerate(CASES)])
def test_wrong_types_are_refused_naming_the_argument(name, call, bad):
    """Every checked argument refuses a value of the wrong kind with a ValueError naming it."""
    @SETTINGS
    @given(bad)
    def check(value):
        with pytest.raises(ValueError) as err:
            call(value)
        assert name in str(err.value), f"{name!r} not named in {err.value}"
    check()


@SETTINGS
@given(x0=st.floats(-5.0, 15.0), h2=st.floats(0.0, 4.0))
def test_sweep_and_simulate_agree_on_the_start(x0, h2):
    """A sweep refuses a start position exactly when simulate refuses it for that value."""
    try:
        simulate(P.with_value("h2", h2), periods=1, x0=x0)
        single = None
    except ValueError as exc:
        single = exc
    try:
        sweep(P, "h2", [h2], transient=0, record=1, x0=x0)
        many = None
    except ValueError as exc:
        many = exc
    assert (single is None) == (many is None), (single, many)
    if many is not None:
        assert "x0" in str(many)
    try:
        regime_map(P, "h2", [h2], "lam", [3.3], transient=0, record=1, x0=x0)
        grid = None
    except ValueError as exc:
        grid = exc
    assert (single is None) == (grid is None), (single, grid)


@pytest.mark.parametrize("d, name", [({}, "lam"), ({"lam": 1.0, "gamma": 2}, "gamma"),
                                     ([("lam", 1.0)], "dict"),
                                     ({"lam": 1.0, "amplitudes": {1: 1.0}}, "amplitudes")])
def test_from_dict_names_what_is_wrong(d, name):
    """RattleParams.from_dict raises ValueError naming a missing, unknown or malformed field."""
    with pytest.raises(ValueError, match=name):
        RattleParams.from_dict(d)


def test_whole_floats_are_still_counts():
    """A whole float (2.0) is a count; only fractions are refused, so nothing is truncated."""
    tr = simulate(P, periods=2.0, transient=np.float64(3.0))
    assert tr.settings["periods"] == 2 and tr.settings["transient"] == 3
    with pytest.raises(ValueError, match="transient = 2.5"):
        find_orbit(P, transient=2.5)


def test_the_sound_has_a_sample_bound():
    """A long, finely sampled sound is refused at once with its sample count, not rendered.

    One period at 1/589 Hz plus a 10 s tail at 384 kHz stays within the duration and rate
    limits but is 2.3e8 samples (9 GB of work arrays before the bound).
    """
    tr = simulate(P, periods=1)
    with pytest.raises(ValueError, match="samples") as err:
        sound.synthesize(tr, sample_rate=384000, excitation_hz=1 / 589, tail=10)
    assert str(sound.MAX_SAMPLES) in str(err.value)


def test_blockwise_rendering_matches_one_block(monkeypatch):
    """The sound rendered in blocks equals the sound rendered in one piece (to rounding)."""
    rng = np.random.default_rng(1)
    t = np.sort(rng.uniform(0, 0.5, 200))
    a = rng.normal(size=200)
    whole = sound.render(t, a, 0.5, 44100)
    monkeypatch.setattr(sound, "_BLOCK", 1000)
    blocks = sound.render(t[::-1], a[::-1], 0.5, 44100)
    np.testing.assert_allclose(blocks, whole, rtol=0, atol=1e-12 * np.max(np.abs(whole)))


# ----- arguments refused before any work: callbacks, sequences, continuation's choices -----

def _box():
    from rattle_core.model.gearbox import Gearbox
    return Gearbox.from_text(
        "[excitation]\norders = [{order = 2, accel_rad_s2 = 400}]\nengine_order = 2\n"
        "harmonics = 1\n[[gear]]\nname = 'g'\ninertia_kgm2 = 4e-4\nbase_radius_m = 0.035\n"
        "drag_torque_Nm = 0.05\nbacklash_um = 80\n")


def _entry_points():
    """Every public function that takes progress and cancel: name → call(**callbacks)."""
    from rattle_core import contact_bifurcation, continue_bifurcation, noise_sensitivity, statistics
    from rattle_core.analysis.continuation import atlas
    from rattle_core.batch.gearbox import verdict
    from rattle_core.store.verdicts import cached_verdict
    return {
        "sweep": lambda **cb: sweep(P, "lam", np.linspace(1, 4, 400), transient=500, record=200,
                                    chunk_size=20, **cb),
        "regime_map": lambda **cb: regime_map(P, "lam", [1.0, 2.0], "r", [0.5, 0.6], transient=1,
                                              record=1, **cb),
        "basin_map": lambda **cb: basin_map(P, [4.0], [0.0], transient=1, **cb),
        "run_map": lambda **cb: run_map(P, None, "lam", [1.0], "r", [0.5], use_cache=False,
                                        transient=1, record=1, **cb),
        "statistics": lambda **cb: statistics(P, runs=2, periods=10, transient=0, **cb),
        "noise_sensitivity": lambda **cb: noise_sensitivity(P, runs=2, periods=10, transient=0,
                                                            **cb),
        "continue_orbit": lambda **cb: continue_orbit(orbit(), "lam", max_points=3, **cb),
        "continue_bifurcation": lambda **cb: continue_bifurcation(
            contact_bifurcation(P, "lam"), "r", max_points=3, **cb),
        "atlas": lambda **cb: atlas(P, "lam", (1.0, 2.0), "r", (0.5, 0.7), max_curves=1,
                                    max_points=10, **cb),
        "verdict": lambda **cb: verdict(_box(), [1000.0, 2000.0], transient=10, record=10, **cb),
        "cached_verdict": lambda **cb: cached_verdict(_box(), [1000.0, 2000.0], transient=10,
                                                      record=10, use_cache=False, **cb),
    }


ENTRY_POINTS = ["sweep", "regime_map", "basin_map", "run_map", "statistics", "noise_sensitivity",
                "continue_orbit", "continue_bifurcation", "atlas", "verdict", "cached_verdict"]
BAD_CALLBACKS = [("progress", 5), ("progress", "x"), ("cancel", "x"), ("cancel", 5),
                 ("cancel", object())]


@pytest.mark.parametrize("bad", BAD_CALLBACKS, ids=[f"{n}={v!r:.10}" for n, v in BAD_CALLBACKS])
@pytest.mark.parametrize("entry", ENTRY_POINTS)
def test_bad_progress_or_cancel_is_refused_before_any_work(entry, bad):
    """A progress that is not callable, or a cancel that is neither an Event nor a callable,
    raises a TypeError naming the argument before any work: the other callback, a valid
    recorder, is never called (a chunk or a point would have polled or reported)."""
    name, value = bad
    calls = []
    other = ({"cancel": lambda: calls.append("cancel") or False} if name == "progress"
             else {"progress": lambda *a: calls.append("progress")})
    with pytest.raises(TypeError) as err:
        _entry_points()[entry](**{name: value}, **other)
    assert name in str(err.value) and isinstance(err.value, ValueError)
    assert calls == []


def test_an_event_cancels_a_sweep_as_it_does_a_branch():
    """A threading.Event is a cancel everywhere: set before a sweep, it stops it before the
    first chunk (the batch layer polls a callable; the Event's is_set is taken)."""
    import threading
    stop = threading.Event()
    stop.set()
    res = sweep(P, "lam", [1.0, 2.0], transient=1, record=1, cancel=stop)
    assert res.cancelled and len(res.values) == 0
    free = sweep(P, "lam", [1.0, 2.0], transient=1, record=1, cancel=threading.Event())
    assert not free.cancelled and len(free.values) == 2


@pytest.mark.parametrize("name, call", [
    ("amplitudes", lambda: RattleParams(lam=1.0, amplitudes=(a for a in (1.0, 0.2)),
                                        phases_deg=(0.0, 0.0))),
    ("phases_deg", lambda: RattleParams(lam=1.0, amplitudes=(1.0, 0.2),
                                        phases_deg=iter((0.0, 0.0)))),
    ("amplitudes", lambda: RattleParams.paper(lam=1.0, amplitudes=(a for a in (1.0, 0.2)),
                                              phases_deg=(0.0, 0.0))),
    ("amplitudes", lambda: __import__("rattle_core").units.PhysicalParams(
        inertia=2e-4, radius=0.04, drag_torque=0.02, backlash=1.6e-4, rpm=1500,
        amplitudes=(a for a in (5e-4,)))),
])
def test_amplitudes_given_as_a_generator_are_refused(name, call):
    """A generator or iterator where a sequence is due is refused with a TypeError naming the
    argument: it would be used up by its first reading."""
    with pytest.raises(TypeError, match=f"{name} must be a sequence or array"):
        call()


@pytest.mark.parametrize("direction", [1.0, -1.0, np.float64(1.0), 1 + 0j, True, "1"])
def test_continue_orbit_takes_only_the_int_directions(direction):
    """direction must be the int 1 or -1: a float, a complex, a bool or text is refused."""
    with pytest.raises(ValueError, match="direction"):
        continue_orbit(orbit(), "lam", direction=direction, max_points=1)
    for ok in (1, -1, np.int64(-1)):
        continue_orbit(orbit(), "lam", direction=ok, max_points=1)


def test_continue_orbit_needs_its_parameter_named():
    """param=None is refused for an orbit or parameters (it would silently be Λ); only a
    bifurcation's restart may leave it out.  A name that is not text is a TypeError."""
    for start in (orbit(), P):
        with pytest.raises(ValueError, match="param = None"):
            continue_orbit(start, None, max_points=1)
        with pytest.raises(ValueError, match="param = None"):
            continue_orbit(start, max_points=1)
    with pytest.raises(TypeError, match="param = 3"):
        continue_orbit(orbit(), 3, max_points=1)
