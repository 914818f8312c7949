"""Every URL value gives a drawn page and a message, never an error page.

A property test opens a session on a link holding one hostile value for any URL key: runs of
more digits than Python converts, NaN and infinities, nesting deeper than a parser follows,
values too long to read.  The session must be built, draw its run (``state.result``), and say
beside the key's control (or the URL's) that the value was not used.  The served page is
checked too: such a link answers 200, not a server error.

A number of any size, from beyond every key's range up to 10⁴⁰⁰⁰ either way, written as an
integer, with a decimal point or with an exponent, is read as the number it is: every key
refuses it beside its control, naming the allowed range (never calling it infinite), and the
page draws its run.
"""
from __future__ import annotations

import math
import urllib.parse
import urllib.request

import param
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from panel.io.location import Location

from app.main import configure
from app.session import Session
from app.pinning import PIN_KEYS, PIN_PHYSICAL_KEYS, parse_pin
from app.query import range_text, rejection
from app.state import (GEARBOX_URL_KEYS, MAP_URL_KEYS, URL_KEYS, ExplorerState, GearboxSettings,
                       MapSettings)

configure()
#: Every URL key: the state's, the Maps tab's settings' and the Gearbox tab's settings'.
KEYS = sorted([*URL_KEYS.values(), *MAP_URL_KEYS.values(), *GEARBOX_URL_KEYS.values()])

hostile = st.one_of(
    st.integers(4301, 6000).map(lambda n: "9" * n),                       # int() refuses these
    st.integers(4301, 6000).map(lambda n: "-" + "1" * n),
    st.sampled_from(["NaN", "nan", "Infinity", "-Infinity", "inf", "1e400", "-1e400"]),
    st.integers(50, 3000).map(lambda n: "[" * n),                         # nesting, unbalanced
    st.integers(50, 3000).map(lambda n: "[" * n + "]" * n),               # nesting, balanced
    st.integers(2001, 5000).map(lambda n: "a" * n),                       # longer than read
)


def opened(search: str) -> Session:
    return Session(location=Location(search=search))


#: The largest bound of any numeric URL key: every key refuses a number beyond it.
LIMIT = max(abs(b) for cls in (ExplorerState, MapSettings, GearboxSettings)
            for p in cls.param.objects().values() if isinstance(p, param.Number)
            for b in p.bounds)
#: Fewest digits of an integer beyond :data:`LIMIT`.
DIGITS = len(str(math.ceil(LIMIT))) + 1


def _of_digits(n: int, most: int = 4001):
    return st.integers(10 ** (n - 1), min(10 ** n - 1, 10 ** (most - 1)))


def beyond_every_range(most: int = 4001):
    """Numbers from beyond every key's range up to ``10**(most-1)``, either sign, as a link
    writes them: ``1000…0``, ``-1000…0.5``, ``2.5e400``."""
    sign = st.sampled_from(["", "-"])
    whole = st.integers(DIGITS, most).flatmap(lambda n: _of_digits(n, most))
    return st.one_of(
        st.builds(lambda s, n: f"{s}{n}", sign, whole),
        st.builds(lambda s, n, d: f"{s}{n}.{d}", sign, whole, st.integers(0, 99)),
        st.builds(lambda s, m, e: f"{s}{m}e{e}", sign,
                  st.sampled_from(["1", "2.5", "9.99", "0.5"]), st.integers(DIGITS, most)),
    )


NEUTRAL = opened("")


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(key=st.sampled_from(KEYS), value=beyond_every_range())
def test_a_number_of_any_size_in_any_key_draws_the_page_and_names_the_range(key, value):
    """A number beyond every range, up to 10⁴⁰⁰⁰, under any key: the run is drawn, the value is
    refused beside the key's control and, for a numeric key, the message gives its range."""
    session = opened("?" + urllib.parse.urlencode({key: value}))
    assert session.state.result is not None
    owner, name = session._owner(key)
    assert name != "url"
    text = owner.messages.get(name, "")
    assert text.startswith("URL: ") and len(text) < 400, (key, value[:20], owner.messages)
    if isinstance(owner.param[name], param.Number):
        assert f"allowed {range_text(owner, name)}" in text, (key, value[:20], text)
        assert "finite" not in text and "inf" not in text, (key, value[:20], text)
    neutral = NEUTRAL._owner(key)[0]
    assert getattr(owner, name) == getattr(neutral, name)


@pytest.mark.parametrize("value, shown", [(10 ** 400, "a whole number of about 401 digits"),
                                           (-(10 ** 5000), "a negative whole number of about "
                                                           "5001 digits")],
                         ids=["401 digits", "-5001 digits"])
def test_an_int_too_large_for_a_float_is_refused_with_its_size_and_range(value, shown):
    """An int no float holds (which Python will not even print past 4300 digits) is refused
    with its size and the allowed range, whoever sets it."""
    s = ExplorerState()
    with pytest.raises(ValueError):
        s.lam = value
    assert rejection(s, "lam", value) == (f"Λ = {shown} is outside the allowed range; "
                                          f"allowed (1e-06, 10000]. Kept 3.3.")


NUMERIC_PIN_KEYS = [k for k in (*PIN_KEYS, *PIN_PHYSICAL_KEYS)
                    if isinstance(ExplorerState.param[k], param.Number)]


@settings(max_examples=60, deadline=None)
@given(key=st.sampled_from(NUMERIC_PIN_KEYS), value=beyond_every_range(most=1400))
def test_a_pin_holding_a_number_of_any_size_names_the_range(key, value):
    """A pin item holding a number beyond every range is refused, naming its range."""
    with pytest.raises(ValueError) as err:
        parse_pin(f"{key}:{value}")
    text = str(err.value)
    assert f"allowed {range_text(ExplorerState, key)}" in text and ".." not in text, text
    assert "finite" not in text and "inf" not in text and len(text) < 300, text


def test_a_310_digit_lam_in_a_pin_link_is_said_beside_the_pin():
    """The link's pin with a 310-digit Λ: the run is drawn and the pin's message gives Λ's range."""
    s = opened("?pin=" + urllib.parse.quote("lam:1" + "0" * 309)).state
    assert s.result is not None
    assert "allowed (1e-06, 10000]" in s.messages["pinned"]


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(key=st.sampled_from(KEYS), value=hostile)
@example(key="gb_target", value="[" * 156 + "]" * 156)  # once quoted whole: 401 characters
def test_any_hostile_value_draws_the_page_and_says_so(key, value):
    """One hostile value under any key: the page draws its run and a message names the key."""
    session = opened("?" + urllib.parse.urlencode({key: value}))
    assert session.state.result is not None
    owner, where = session._owner(key)
    said = {**session.state.messages, **owner.messages}
    assert where in said or "url" in said, (key, value[:20], said)
    text = said.get(where, said.get("url", ""))
    assert "URL" in text and len(text) < 400


@pytest.mark.parametrize("key", ["periods", "shown", "transient"])
@pytest.mark.parametrize("value", ["NaN", "Infinity", "-Infinity"])
def test_non_finite_counts_keep_their_value_with_a_message(key, value):
    """NaN or ±Infinity for a count leaves its last value in force and says it must be finite."""
    s = opened(f"?{key}={value}").state
    assert s.result is not None
    assert "finite" in s.messages[key]
    assert getattr(s, key) == s.param[key].default


def test_garbage_for_continued_from_has_a_message():
    """cont_from garbage is refused with a message beside it, not dropped silently."""
    s = opened("?cont_from=garbage").state
    assert s.result is not None and "cont_from" in s.messages


def test_a_link_with_too_many_digits_is_served(dashboard_server):
    """The served page answers 200 for values of 310 and 5000 digits (the first overflowed a
    float in its message: an empty page; Panel's int() refused the second: 500)."""
    url = (dashboard_server["url"] + "/?lam=1" + "0" * 309 + "&map_x_num=" + "1" * 5000
           + "&periods=Infinity")
    with urllib.request.urlopen(url, timeout=120) as resp:
        assert resp.status == 200
        assert b"Rattle Explorer" in resp.read()
    assert dashboard_server["log"].tracebacks() == []
