"""The link's query, read so that no value can break the page.

Panel reads a query with ``panel.util.parse_query``, which calls ``int()`` on any run of digits
(Python refuses more than 4300 of them) and ``json.loads``/``ast.literal_eval`` on anything
that starts with a bracket (deep nesting raises, long text costs time).  One such value in a
link used to turn the page into a server error.  Here:

* :func:`parse_query` is Panel's parser with every value checked on its own: a value longer
  than :data:`MAX_VALUE` characters, or one the parser cannot read, is left out instead of
  failing the whole query;
* :func:`readable` splits a query string into the part that can be read and the keys that
  cannot, so the session can say which values it dropped;
* :func:`install` makes Panel's location use :func:`parse_query` (once per process).
"""
from __future__ import annotations

import logging
import urllib.parse
from typing import Any

#: Longest query value read, in characters (the longest real one, 32 harmonics, is ~450).
MAX_VALUE = 2000


def _parse_one(key: str, value: str) -> tuple[bool, Any]:
    """``(True, parsed)`` if Panel's parser reads ``value``, else ``(False, why)``."""
    from panel.util import parse_query as panel_parse
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
