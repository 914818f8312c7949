"""Every URL value gives a drawn page and a message, never an error page.

A property test opens a session on a link holding one hostile value for any URL key: runs of
more digits than Python converts, NaN and infinities, nesting deeper than a parser follows,
values too long to read.  The session must be built, draw its run (``state.result``), and say
beside the key's control (or the URL's) that the value was not used.  The served page is
checked too: such a link answers 200, not a server error.
"""
from __future__ import annotations

import urllib.parse
import urllib.request

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from panel.io.location import Location

from app.main import configure
from app.session import Session
from app.state import GEARBOX_URL_KEYS, MAP_URL_KEYS, URL_KEYS

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


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(key=st.sampled_from(KEYS), value=hostile)
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
    """The served page answers 200 for a value of 5000 digits (Panel's int() refused it: 500)."""
    url = dashboard_server["url"] + "/?lam=" + "1" * 5000 + "&periods=Infinity"
    with urllib.request.urlopen(url, timeout=120) as resp:
        assert resp.status == 200
        assert b"Rattle Explorer" in resp.read()
    assert dashboard_server["log"].tracebacks() == []
