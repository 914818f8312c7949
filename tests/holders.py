"""What keeps an object alive, in words: for a failing memory test to say what it found
instead of only that something survived.

:func:`roots` walks the heap backwards from the object (one pass of ``gc.get_referents``
over every tracked object builds the reverse graph) and returns, for each root that reaches
it, the shortest chain of holders from that root to the object. A root is what no tracked
object refers to: a running thread's frame or context, a module, a class, or a C-level global.
Each holder is named: a dict by the keys that lead on, a frame by its file, line and
function, a function by its name.
"""
from __future__ import annotations

import collections
import gc
import re
import sys
import types
from typing import Any


def _is(obj: Any, kinds: Any) -> bool:
    """``isinstance`` by the object's own type: a weak proxy whose object is gone raises on
    ``isinstance`` (it asks the proxy for ``__class__``)."""
    return issubclass(type(obj), kinds)


def _name(holder: Any, held: Any) -> str:
    if _is(holder, types.FrameType):
        return f"frame {holder.f_code.co_filename}:{holder.f_lineno} in {holder.f_code.co_name}"
    if _is(holder, dict):
        keys = [repr(k)[:60] for k, v in list(holder.items()) if v is held or k is held][:3]
        return f"dict[{', '.join(keys)}]"
    if _is(holder, types.FunctionType):
        return f"function {holder.__module__}.{holder.__qualname__}"
    if _is(holder, types.MethodType):
        return f"bound method {holder.__func__.__module__}.{holder.__func__.__qualname__}"
    if _is(holder, types.CellType):
        return "closure cell"
    if _is(holder, types.ModuleType):
        return f"module {holder.__name__}"
    if _is(holder, type):
        return f"class {holder.__module__}.{holder.__qualname__}"
    if _is(holder, (list, tuple, set)):
        return f"{type(holder).__name__} of {len(holder)}"
    return f"{type(holder).__module__}.{type(holder).__qualname__}"


def _frames_of_threads() -> dict[int, str]:
    """The frames the threads are running now (a frame's locals are roots while it runs)."""
    out = {}
    for ident, frame in sys._current_frames().items():
        while frame is not None:
            out[id(frame)] = f"thread {ident}"
            frame = frame.f_back
    return out


def roots(obj: Any, limit: int = 8) -> list[str]:
    """Up to ``limit`` chains ``obj <- holder <- … <- root``, shortest first; the frame of
    this function and of its caller are not roots (they hold ``obj`` to look at it)."""
    mine = {id(sys._getframe()), id(sys._getframe(1))}
    everything = gc.get_objects()
    reverse: dict[int, list[Any]] = collections.defaultdict(list)
    for holder in everything:
        if id(holder) in mine:
            continue
        # a module holds its dict; asking the C module _asyncio for its referents walks its
        # free lists, which does not end on CPython 3.12.1
        held_by = ([vars(holder)] if _is(holder, types.ModuleType)
                   else gc.get_referents(holder))
        for held in held_by:
            if gc.is_tracked(held):  # an untracked object (a str, an int) holds nothing tracked
                reverse[id(held)].append(holder)
    del everything
    running = _frames_of_threads()
    # breadth-first from obj to its holders: parent[id(h)] is the object h was reached from
    parent: dict[int, Any] = {id(obj): None}
    found: list[str] = []
    queue = collections.deque([obj])
    while queue and len(found) < limit:
        held = queue.popleft()
        holders = reverse.get(id(held), [])
        is_root = (not holders or _is(held, (types.ModuleType, type))
                   or id(held) in running)
        if is_root and held is not obj:
            chain, node = [], held
            while node is not None:
                nxt = parent[id(node)]
                chain.append(_name(node, nxt) if nxt is not None else
                             f"{type(node).__module__}.{type(node).__qualname__}")
                node = nxt
            where = f" ({running[id(held)]})" if id(held) in running else ""
            found.append(" <- ".join(reversed(chain)) + where)
            continue
        for h in holders:
            if id(h) not in parent and id(h) not in mine:
                parent[id(h)] = held
                queue.append(h)
    reverse.clear()
    return found


def through(chains: list[str], package: str) -> list[str]:
    """The chains that pass through an object, function or module of ``package``."""
    named = re.compile(rf"(^|<- |function |bound method |class |module ){re.escape(package)}\.")
    return [c for c in chains if named.search(c)]
