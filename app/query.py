"""The link's query, read so that no value can break the page.

Panel reads a query with ``panel.util.parse_query``, which calls ``int()`` on any run of digits
(Python refuses more than 4300 of them) and ``json.loads``/``ast.literal_eval`` on anything
that starts with a bracket (deep nesting raises, long text costs time).  One such value in a
link used to turn the page into a server error.  Here:

* :func:`parse_query` is Panel's parser with every value checked on its own: a value longer
  than :data:`MAX_VALUE` characters, or one the parser cannot read, is left out instead of
  failing the whole query;
* a number written in decimal (``1000…0``, ``-2.5``, ``1e400``) is read by :func:`number`,
  whatever its length: one beyond a float's range becomes a :class:`Huge`, which every
  numeric parameter refuses by its bounds and which prints shortened, so the message beside
  the control names the number as written and the allowed range (an ``int`` of 310 digits
  used to overflow the float conversion of that message, leaving the page empty);
* :func:`readable` splits a query string into the part that can be read and the keys that
  cannot, so the session can say which values it dropped;
* :func:`install` makes Panel's location use :func:`parse_query` (once per process);
* :func:`rejection` words the message beside a control whose value is refused (plain text);
* :func:`update_query_as_written` and :func:`serialize` write values back into the link,
  keeping every other key's text as written (``present=true`` stays lowercase).
"""
from __future__ import annotations

import logging
import math
import re
import urllib.parse
from typing import Any

import param

#: Longest query value read, in characters (the longest real one, 32 harmonics, is ~450);
#: numbers are read whatever their length (:func:`number`).
MAX_VALUE = 2000
#: A number as a link writes it: sign, digits, an optional fraction and exponent.
_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
#: How much of a huge number's text a message shows, either side of the cut.
_SHOWN = 10


class Huge(float):
    """A finite number written in a link that no float holds: ``±inf`` as a float, so every
    bound refuses it, and its text kept: ``str`` gives it whole (a link re-encoded from the
    parsed query keeps it), ``repr`` shortened (for a message)."""

    text: str

    def __new__(cls, text: str) -> "Huge":
        self = super().__new__(cls, math.copysign(math.inf, -1.0 if text.startswith("-") else 1.0))
        self.text = text
        return self

    def __repr__(self) -> str:
        t = self.text
        if len(t) <= 2 * _SHOWN + 3:
            return t
        return f"{t[:_SHOWN]}…{t[-_SHOWN // 2:]} ({len(t)} characters)"

    def __str__(self) -> str:  # what a link re-encoded from the parsed query carries
        return self.text

    def __reduce__(self):
        return Huge, (self.text,)


def number(text: str) -> int | float | None:
    """``text`` as the number it writes (an ``int`` for whole digits, a :class:`Huge` beyond a
    float's range), or None if it is no decimal number. Any length: ``float()`` reads digits in
    linear time and never overflows, and ``int()`` is called only on at most 309 digits."""
    if not _NUMBER.fullmatch(text):
        return None
    value = float(text)
    if math.isinf(value):
        return Huge(text)
    if re.fullmatch(r"-?[0-9]+", text):  # Panel's rule: whole digits are an int
        sign, digits = ("-", text[1:]) if text.startswith("-") else ("", text)
        return int(sign + (digits.lstrip("0") or "0"))
    return value


def _parse_one(key: str, value: str) -> tuple[bool, Any]:
    """``(True, parsed)`` if Panel's parser reads ``value``, else ``(False, why)``."""
    from panel.util import parse_query as panel_parse
    read = number(value)
    if read is not None:
        return True, read
    if len(value) > MAX_VALUE:
        return False, f"{len(value)} characters, more than {MAX_VALUE}"
    logger = logging.getLogger("panel.util")
    level = logger.level
    logger.setLevel(logging.ERROR)  # its "could not parse" warning is reported by the caller
    try:
        parsed = panel_parse("?" + urllib.parse.urlencode({key: value}))
    except Exception as exc:  # int() of too many digits, a nesting too deep
        return False, type(exc).__name__
    finally:
        logger.setLevel(level)
    if key not in parsed and value != "":
        return False, "not a value the page reads"
    return True, parsed.get(key)


def parse_query(query: str) -> dict[str, Any]:
    """Panel's ``parse_query``, leaving out the values it cannot read instead of raising."""
    out: dict[str, Any] = {}
    for key, value in urllib.parse.parse_qsl((query or "")[1:]):
        ok, parsed = _parse_one(key, value)
        if ok:
            out[key] = parsed
    return out


def readable(search: str) -> tuple[str, dict[str, str]]:
    """``search`` without its unreadable values, and ``{key: why}`` for each one left out."""
    keep, bad = [], {}
    for key, value in urllib.parse.parse_qsl((search or "")[1:], keep_blank_values=True):
        ok, why = _parse_one(key, value) if value != "" else (True, None)
        if ok:
            keep.append((key, value))
        else:
            bad[key] = str(why)
    return ("?" + urllib.parse.urlencode(keep) if keep else ""), bad


def install() -> None:
    """Make Panel's location read every query through :func:`parse_query`."""
    import panel.io.location as location
    location.parse_query = parse_query


# ----- what the page says of a refused value, and what it writes back -----------------
def range_text(state: param.Parameterized, name: str) -> str:
    """The allowed range of a numeric parameter, e.g. ``(0, 10000]``."""
    p = state.param[name]
    lo, hi = p.bounds
    inc = getattr(p, "inclusive_bounds", (True, True))
    return f"{'[' if inc[0] else '('}{lo:g}, {hi:g}{']' if inc[1] else ')'}"


def rejection(state: param.Parameterized, name: str, value: Any, reason: str = "") -> str:
    """The message beside control ``name`` when ``value`` is refused (plain text, not HTML)."""
    p = state.param[name]
    label = p.label or name
    kept = getattr(state, name)
    kept_text = "empty" if kept is None else (f"{kept:g}" if isinstance(kept, float) else str(kept))
    if isinstance(p, param.Selector):
        allowed = ", ".join(map(str, p.objects))
        return f"{label} = {_show(value)} is not allowed; allowed: {allowed}. Kept {kept_text}."
    if isinstance(p, param.Boolean):
        return f"{label} = {_show(value)} is not allowed; allowed: true or false. Kept {kept_text}."
    if isinstance(p, param.Number):
        whole = "a whole number" if isinstance(p, param.Integer) else "a number"
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            what = f"{label} must be {whole}, got {_show(value)}"
        elif isinstance(value, Huge) or (isinstance(value, int) and not _fits_float(value)):
            what = f"{label} = {_show_number(value)} is outside the allowed range"
        elif not math.isfinite(value):  # before int(), which refuses NaN and infinities
            what = f"{label} must be finite, got {value!r}"
        elif isinstance(p, param.Integer) and value != int(value):
            what = f"{label} = {value!r} must be {whole}"
        else:
            shown = int(value) if isinstance(p, param.Integer) else float(value)
            what = f"{label} = {_show(shown)} is outside the allowed range"
        return f"{what}; allowed {range_text(state, name)}. Kept {kept_text}."
    if not reason:
        try:
            p._validate(value)
        except ValueError as exc:
            reason = str(exc)
    return f"{label}: {reason or 'not allowed'}. Kept {kept_text or 'empty'}."


def _show(value: Any) -> str:
    from .ui.labels import short
    return short(value)


def _fits_float(value: int) -> bool:
    """Whether an int converts to a float (``math.isfinite`` of a larger one raises)."""
    try:
        float(value)
    except OverflowError:
        return False
    return True


def _show_number(value: int | float) -> str:
    """A number too large for a float, shortened (an int's full text may be refused by
    Python's limit on the digits it converts)."""
    if isinstance(value, Huge):
        return repr(value)
    digits = math.floor(math.log10(abs(value))) + 1  # log10 takes ints of any size
    return f"a{' negative' if value < 0 else ''} whole number of about {digits} digits"


def update_query_as_written(location: Any, values: dict[str, Any]) -> None:
    """Set ``values`` (URL text, or values JSON writes) in ``location``'s query; the other
    keys keep their text as it is."""
    import json
    query = dict(urllib.parse.parse_qsl((location.search or "")[1:], keep_blank_values=True))
    query.update({k: v if isinstance(v, str) else json.dumps(v) for k, v in values.items()})
    location.search = "?" + urllib.parse.urlencode(query) if query else ""


def serialize(obj: param.Parameterized, name: str) -> str:
    """``obj``'s value of ``name`` as the URL carries it."""
    import json
    v = obj.param[name].serialize(getattr(obj, name))
    return v if isinstance(v, str) else json.dumps(v)
