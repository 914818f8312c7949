"""RattleParams and simulate(): bad input is refused with a useful message; keys are canonical."""
from __future__ import annotations

import math
import os
import subprocess
import sys

import numpy as np
import pytest

from rattle_core import RattleParams, simulate

NAN = float("nan")
INF = float("inf")


def assert_message(err: pytest.ExceptionInfo, name: str, value: str, *range_tokens: str) -> None:
    """The error names the parameter, shows the offending value and states the allowed range."""
    msg = str(err.value)
    assert name in msg, f"parameter {name!r} not named in {msg!r}"
    assert value.lower() in msg.lower(), f"value {value!r} not shown in {msg!r}"
    for tok in range_tokens:
        assert tok in msg, f"range part {tok!r} missing from {msg!r}"


# (keyword arguments, parameter name in the message, value as shown, range tokens)
BAD_PARAMS = [
    (dict(lam=0.0), "lam", "0", ("(1e-06", "10000]")),
    (dict(lam=-1.0), "lam", "-1", ("(1e-06", "10000]")),
    (dict(lam=NAN), "lam", "nan", ("(1e-06", "10000]")),
    (dict(lam=INF), "lam", "inf", ("(1e-06", "10000]")),
    (dict(lam=-INF), "lam", "-inf", ("(1e-06", "10000]")),
    (dict(lam=3.3, r=-0.01), "r", "-0.01", ("[0", "1]")),
    (dict(lam=3.3, r=1.01), "r", "1.01", ("[0", "1]")),
    (dict(lam=3.3, r=NAN), "r", "nan", ("[0", "1]")),
    (dict(lam=3.3, j=0.0), "j", "0", ("(0",)),
    (dict(lam=3.3, j=-2.0), "j", "-2", ("(0",)),
    (dict(lam=3.3, j=INF), "j", "inf", ("(0",)),
    (dict(lam=3.3, v_stick=-1e-6), "v_stick", "-1e-06", ("[0",)),
    (dict(lam=3.3, v_stick=NAN), "v_stick", "nan", ("[0",)),
    (dict(lam=3.3, amplitudes=(1.0, NAN), phases_deg=(0.0, 0.0)), "amplitudes[1]", "nan", ("[0", "100]")),
    (dict(lam=3.3, amplitudes=(1.0, INF), phases_deg=(0.0, 0.0)), "amplitudes[1]", "inf", ("[0", "100]")),
    (dict(lam=3.3, amplitudes=(1.0, -0.2), phases_deg=(0.0, 0.0)), "amplitudes[1]", "-0.2", ("[0", "100]")),
    (dict(lam=3.3, phases_deg=(NAN,)), "phases_deg[0]", "nan", ("range",)),
    (dict(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, INF)), "phases_deg[1]", "inf", ("range",)),
    # found by fuzzing: no OverflowError, no silent conversion of text or bools, no stall
    (dict(lam=10**400), "lam", "1000000", ("(1e-06", "10000]")),
    (dict(lam="3.3"), "lam", "'3.3'", ("(1e-06", "10000]")),
    (dict(lam=True), "lam", "True", ("(1e-06", "10000]")),
    (dict(lam=5e-324), "lam", "5e-324", ("(1e-06", "10000]")),
    (dict(lam=3.3, r="0.5"), "r", "'0.5'", ("[0", "1]")),
]


@pytest.mark.parametrize("kwargs, name, value, rng", BAD_PARAMS,
                         ids=[f"{b[1]}={b[2]}" for b in BAD_PARAMS])
def test_bad_scalar_parameters_raise_with_name_value_and_range(kwargs, name, value, rng):
    """Out-of-range, NaN or infinite parameters raise ValueError naming parameter, value, range."""
    with pytest.raises(ValueError) as err:
        RattleParams(**kwargs)
    assert_message(err, name, value, *rng)


def test_empty_harmonic_list_is_refused():
    """An empty amplitude list raises ValueError that names amplitudes and the h_1 = 1 rule."""
    with pytest.raises(ValueError) as err:
        RattleParams(lam=3.3, amplitudes=(), phases_deg=())
    assert_message(err, "amplitudes", "empty", "h_1 = 1")


@pytest.mark.parametrize("amps, phases", [((1.0, 0.25), (0.0,)), ((1.0,), (0.0, 45.0)),
                                          ((1.0, 0.25, 0.1), (0.0, 45.0))])
def test_mismatched_harmonic_lists_are_refused(amps, phases):
    """Amplitude and phase lists of different lengths raise ValueError naming both lengths."""
    with pytest.raises(ValueError) as err:
        RattleParams(lam=3.3, amplitudes=amps, phases_deg=phases)
    msg = str(err.value)
    assert "phases_deg" in msg and "amplitudes" in msg
    assert str(len(amps)) in msg and str(len(phases)) in msg


@pytest.mark.parametrize("h1", [0.0, 0.5, 2.0, 1.0 + 1e-12])
def test_first_amplitude_must_be_one(h1):
    """A first amplitude other than exactly 1 raises ValueError showing h_1 and the value 1."""
    with pytest.raises(ValueError) as err:
        RattleParams(lam=3.3, amplitudes=(h1, 0.25), phases_deg=(0.0, 45.0))
    assert_message(err, "h_1", repr(float(h1)), "1")


@pytest.mark.parametrize("bad", ["abc", None, [1.0], object()])
def test_non_numbers_are_refused(bad):
    """A non-numeric Λ raises ValueError (not TypeError) naming lam."""
    with pytest.raises(ValueError, match="lam"):
        RattleParams(lam=bad)


P = RattleParams(lam=3.3)
BAD_RUNS = [
    (dict(periods=0), "periods", "0", ("[1", "2e+06]")),
    (dict(periods=-5), "periods", "-5", ("[1", "2e+06]")),
    (dict(periods=2_000_001), "periods", "2000001", ("[1", "2e+06]")),
    (dict(periods=10**9), "periods", "1000000000", ("[1", "2e+06]")),
    (dict(periods=NAN), "periods", "nan", ("[1", "2e+06]")),
    (dict(periods=INF), "periods", "inf", ("[1", "2e+06]")),
    (dict(periods=10, transient=1_999_995), "transient", "2000005", ("[1", "2000000]")),
    (dict(x0=0.99), "x0", "0.99", ("[1", "9]")),
    (dict(x0=9.01), "x0", "9.01", ("[1", "9]")),
    (dict(x0=NAN), "x0", "nan", ("[1", "9]")),
    (dict(v0=NAN), "v0", "nan", ("range",)),
    (dict(v0=INF), "v0", "inf", ("range",)),
    (dict(t0=NAN), "t0", "nan", ("range",)),
    (dict(strobe_phase=INF), "strobe_phase", "inf", ("range",)),
]


@pytest.mark.parametrize("kwargs, name, value, rng", BAD_RUNS,
                         ids=[f"{b[1]}={b[2]}" for b in BAD_RUNS])
def test_bad_simulate_arguments_raise_with_name_value_and_range(kwargs, name, value, rng):
    """simulate() refuses bad periods, x0 outside the backlash, NaN/inf, naming value and range."""
    with pytest.raises(ValueError) as err:
        simulate(P, **kwargs)
    assert_message(err, name, value, *rng)


def test_x0_range_follows_the_wall_at_t0():
    """The allowed x0 range is [y(t0), y(t0) + j]: at t0 = π it is [−1, 7] for y = cos t."""
    with pytest.raises(ValueError) as err:
        simulate(P, periods=1, x0=7.5, t0=math.pi)
    assert_message(err, "x0", "7.5", "[-1", "7]")
    tr = simulate(P, periods=1, x0=-1.0, v0=0.0, t0=math.pi)
    assert tr.t_start == pytest.approx(math.pi)


def test_fractional_periods_are_refused():
    """A non-integer number of periods raises ValueError naming periods."""
    with pytest.raises(ValueError, match="periods"):
        simulate(P, periods=2.5)


def test_params_object_is_required():
    """simulate() with a plain dict instead of RattleParams raises ValueError naming params."""
    with pytest.raises(ValueError, match="params"):
        simulate({"lam": 3.3}, periods=1)


def test_valid_boundaries_are_accepted():
    """Closed range ends (r = 0 and 1, v_stick = 0, x0 on either wall) are valid input."""
    for r in (0.0, 1.0):
        assert RattleParams(lam=3.3, r=r).r == r
    assert RattleParams(lam=3.3, v_stick=0.0).v_stick == 0.0
    simulate(P, periods=1, x0=1.0)
    simulate(P, periods=1, x0=9.0)


# ----- canonical form and key ---------------------------------------------------------


def test_same_parameters_give_the_same_key():
    """Equal parameters, however they are spelled (ints, lists, numpy floats), share one key."""
    a = RattleParams(lam=3.3, r=0.65, j=8.0, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0))
    b = RattleParams(lam=np.float64(3.3), r=0.65, j=8, amplitudes=[1, 0.25], phases_deg=[0, 45])
    assert a.key() == b.key()
    assert a.canonical() == b.canonical()
    assert a == b


def test_trailing_zero_harmonics_do_not_change_the_key():
    """Adding a zero-amplitude harmonic describes the same excitation, so the key is the same."""
    a = RattleParams(lam=3.3)
    b = RattleParams(lam=3.3, amplitudes=(1.0, 0.0, 0.0), phases_deg=(0.0, 30.0, 60.0))
    assert a.key() == b.key()


@pytest.mark.parametrize("change", [dict(lam=3.3000000000000003), dict(r=0.6500000000000001),
                                    dict(j=8.000001), dict(v_stick=1e-7),
                                    dict(amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0)),
                                    dict(amplitudes=(1.0, 0.25), phases_deg=(0.0, 90.0)),
                                    dict(phases_deg=(1e-9,))])
def test_different_parameters_give_different_keys(change):
    """Any change, down to the last bit of a float, gives a different key."""
    base = RattleParams(lam=3.3)
    assert base.replace(**change).key() != base.key()
    if "amplitudes" not in change and "phases_deg" not in change:
        base2 = RattleParams(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0))
        assert base2.replace(**change).key() != base2.key()


def test_key_depends_on_settings():
    """Settings passed to key() (e.g. periods) are part of the key."""
    p = RattleParams(lam=3.3)
    assert p.key(periods=100) != p.key(periods=200)
    assert p.key(periods=100) == p.key(periods=100)


def test_canonical_form_is_exact_and_round_trips():
    """canonical() stores floats bit-exactly (float.hex); from_dict(to_dict()) keeps the key."""
    p = RattleParams(lam=0.1 + 0.2, r=0.65, amplitudes=(1.0, 1 / 3), phases_deg=(0.0, 45.0))
    c = p.canonical()
    assert float.fromhex(c["lam"]) == 0.1 + 0.2
    assert float.fromhex(c["amplitudes"][1]) == 1 / 3
    assert RattleParams.from_dict(p.to_dict()).key() == p.key()
    assert RattleParams.from_dict(c).key() == p.key()


def test_key_is_stable_across_processes():
    """The key is the same in a fresh interpreter (no dependence on hash seeds or ids)."""
    p = RattleParams(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0))
    code = ("from rattle_core import RattleParams; print(RattleParams(lam=3.3, amplitudes=(1.0, 0.25),"
            " phases_deg=(0.0, 45.0)).key(periods=100))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env={**os.environ, "PYTHONHASHSEED": "12345"})
    assert out.stdout.strip() == p.key(periods=100)
    assert len(p.key()) == 64 and int(p.key(), 16) >= 0


@pytest.mark.parametrize("kwargs", [dict(periods=True), dict(periods="10"), dict(transient=False),
                                    dict(seed=True), dict(seed="1"), dict(lyapunov="yes"), dict(periods=1e400)])
def test_simulate_refuses_bools_and_text_for_numbers_and_numbers_for_switches(kwargs):
    """simulate names the argument when a bool or text stands for a number, or a number for a
    switch, instead of converting it silently."""
    name = next(iter(kwargs))
    with pytest.raises(ValueError, match=name):
        simulate(RattleParams(lam=3.3), **{"periods": 5, **kwargs})


def test_paper_takes_h2_and_phi2_as_the_cli_does():
    """``RattleParams.paper(h2=, phi2=)`` is the paper's second harmonic: the same parameters as
    the amplitudes/phases form; Fig 7's values (Λ = 3.3, 0.25, 45°) are chaotic, while the same
    numbers read as core phases give a periodic orbit (the README's example)."""
    from rattle_core import classify, simulate
    fig7 = RattleParams.paper(lam=3.3, h2=0.25, phi2=45.0)
    assert fig7 == RattleParams.paper(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0))
    assert classify(simulate(fig7, periods=500, transient=200, lyapunov=True)).regime == "D"
    core = RattleParams(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0))
    assert classify(simulate(core, periods=500, transient=200, lyapunov=True)).period > 0
    with pytest.raises(ValueError, match="h2"):
        RattleParams.paper(lam=3.3, amplitudes=(1.0, 0.5), h2=0.25)
