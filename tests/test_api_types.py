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
