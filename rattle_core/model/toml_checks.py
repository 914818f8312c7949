"""Checks of an untrusted TOML file before and after parsing, and errors placed in it.

A file's brackets and braces may nest at most :data:`MAX_TOML_DEPTH` deep before it is parsed
(the parser recurses once per level); once parsed, tables nest at most that deep, an array
holds at most :data:`MAX_TOML_ARRAY` items and a string or key at most :data:`MAX_TOML_STRING`
characters.  A name may not hold control characters, line breaks or bidirectional formatting
characters.  :class:`_FileError` and :class:`_at` place an error at a key path or a table, so
every message is one line naming the place (:mod:`rattle_core.model.gearbox` uses them).
"""
from __future__ import annotations

import re
import unicodedata
from typing import Any

#: Deepest nesting of brackets and braces, and of tables, in a gearbox file (the format needs 2).
MAX_TOML_DEPTH = 8
#: Most items of one array in a gearbox file.
MAX_TOML_ARRAY = 256
#: Longest string or key in a gearbox file [characters].
MAX_TOML_STRING = 1024
#: Bidirectional formatting characters: embeddings, overrides, isolates and marks.
BIDI_CHARACTERS = frozenset("\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069"
                            "\u200e\u200f\u061c")


def check_name(what: str, name: str) -> str:
    """``name`` if it holds no control character (NUL included), line or paragraph separator,
    or bidirectional formatting character; else ``ValueError`` naming ``what`` and the
    character (the name is shown escaped, so the message stays one readable line)."""
    for i, ch in enumerate(name):
        if ch in BIDI_CHARACTERS or unicodedata.category(ch) in ("Cc", "Zl", "Zp"):
            kind = ("a bidirectional formatting character" if ch in BIDI_CHARACTERS
                    else "a control character")
            raise ValueError(f"{what} {name!r:.100} holds {kind}, U+{ord(ch):04X}, at position "
                             f"{i + 1}; names may hold only printable text")
    return name


class _FileError(ValueError):
    """An error at a place in a gearbox file: ``place`` (a key path, a gear) and ``message``."""

    def __init__(self, place: str, message: str) -> None:
        super().__init__(f"{place}: {message}")
        self.place = place
        self.message = message


class _at:
    """A context that turns a ``ValueError`` raised in it into a :class:`_FileError` at ``place``."""

    def __init__(self, place: str) -> None:
        self.place = place

    def __enter__(self) -> None:
        return None

    def __exit__(self, kind, exc, tb) -> bool:
        if isinstance(exc, ValueError) and not isinstance(exc, _FileError):
            raise _FileError(self.place, str(exc)) from None
        return False


def _subtable(build, t: Any, place: str):
    """``build(t, place)``, its error placed at ``place`` (the builders name it first)."""
    try:
        return build(t, place)
    except ValueError as exc:
        text = str(exc)
        raise _FileError(place, text[len(place) + 2:] if text.startswith(place + ": ")
                         else text) from None


def _one_line(text: str) -> str:
    return " ".join(text.split())


# the tokens that matter for nesting: strings and comments are skipped whole, so that
# brackets inside them do not count
_TOKEN = re.compile(r'"""|' + r"'''" + r'''|"|'|#|[\[\]{}]|\n''')
_STRING_END = {'"""': re.compile(r'(?:[^"\\]|\\.|"(?!""))*"""', re.S),
               "'''": re.compile(r"(?:[^']|'(?!''))*" + r"'''", re.S),
               '"': re.compile(r'(?:[^"\\\n]|\\.)*(?:"|$)', re.M),
               "'": re.compile(r"[^'\n]*(?:'|$)", re.M)}


def check_nesting(text: str, limit: int = MAX_TOML_DEPTH) -> None:
    """Refuse TOML text whose arrays and inline tables nest deeper than ``limit``, before it
    is parsed (the parser recurses once per level): ``ValueError`` naming the line."""
    depth = 0
    line = 1
    pos = 0
    while True:
        m = _TOKEN.search(text, pos)
        if m is None:
            return
        tok = m.group()
        pos = m.end()
        if tok == "\n":
            line += 1
        elif tok == "#":
            nl = text.find("\n", pos)
            pos = len(text) if nl < 0 else nl
        elif tok in _STRING_END:
            end = _STRING_END[tok].match(text, pos)
            stop = end.end() if end else len(text)
            line += text.count("\n", pos, stop)
            pos = stop
        elif tok in "[{":
            depth += 1
            if depth > limit:
                raise _FileError(f"line {line}", f"arrays and inline tables nest more than "
                                 f"{limit} deep; the allowed depth is {limit}")
        else:
            depth = max(0, depth - 1)


def check_sizes(data: dict) -> None:
    """Refuse parsed TOML whose tables nest deeper than :data:`MAX_TOML_DEPTH`, whose arrays
    hold more than :data:`MAX_TOML_ARRAY` items, or whose strings or keys are longer than
    :data:`MAX_TOML_STRING` characters: ``ValueError`` naming the key path."""
    todo: list[tuple[str, Any, int]] = [("", data, 0)]
    while todo:
        path, value, depth = todo.pop()
        where = path or "the top level"
        if depth > MAX_TOML_DEPTH:
            raise _FileError(where, f"tables and arrays nest more than {MAX_TOML_DEPTH} deep; "
                             f"the allowed depth is {MAX_TOML_DEPTH}")
        if isinstance(value, dict):
            for key, item in value.items():
                if len(key) > MAX_TOML_STRING:
                    raise _FileError(where, f"a key has {len(key)} characters; the allowed "
                                     f"length is up to {MAX_TOML_STRING}")
                todo.append((f"{path}.{key}" if path else key, item, depth + 1))
        elif isinstance(value, list):
            if len(value) > MAX_TOML_ARRAY:
                raise _FileError(where, f"the array has {len(value)} items; the allowed size is "
                                 f"up to {MAX_TOML_ARRAY}")
            todo.extend((f"{path}[{i}]", item, depth + 1) for i, item in enumerate(value))
        elif isinstance(value, str) and len(value) > MAX_TOML_STRING:
            raise _FileError(where, f"the string has {len(value)} characters; the allowed "
                             f"length is up to {MAX_TOML_STRING}")


def _check_keys(t: dict, allowed: set[str], where: str) -> None:
    extra = set(t) - allowed
    if extra:
        raise ValueError(f"{where + ': ' if where else ''}unknown key {sorted(extra)[0]!r}; "
                         f"allowed: {', '.join(sorted(allowed))}")


def _table(data: dict, name: str, allowed: set[str]) -> dict:
    t = data.get(name, {})
    if not isinstance(t, dict):
        raise _FileError(f"[{name}]", "must be a table")
    with _at(f"[{name}]"):
        _check_keys(t, allowed, "")
    return t


__all__ = ["check_name", "check_nesting", "check_sizes", "MAX_TOML_DEPTH", "MAX_TOML_ARRAY",
           "MAX_TOML_STRING", "BIDI_CHARACTERS"]
