"""HoloViews' process-wide registries, made safe for two threads at once.

A page build (holding :data:`app.work.threads.BUILD_LOCK`) and another session's redraw
(holding :data:`~app.work.threads.HV_LOCK`) run side by side. Both may build HoloViews
plots, and a plot's construction walks the registry of every stream (``Stream.registry``)
and of every link (``Link.registry``) in Python while the other thread may add to them: a
walk that meets an addition stops with "dictionary changed size during iteration". Here
each registry is replaced, once, by one whose walks and changes hold a lock of its own: a
walk reads a copy taken under the lock, and a change waits for it.

:func:`install` does it, before any stream exists (:func:`app.main.configure`); what the old
registry already held is carried over.
"""
from __future__ import annotations

import threading
import weakref
from typing import Any

_installed = False
_guard = threading.Lock()


#: The methods that read or change a registry; those in :data:`_WALKS` return a list.
_METHODS = ("register", "unregister", "items", "values", "keys", "get", "__getitem__",
            "__setitem__", "__delitem__", "__contains__", "__len__", "pop", "setdefault")
_WALKS = frozenset({"items", "values", "keys"})


def _under_lock(method: Any, walk: bool) -> Any:
    def call(self, *args: Any, **kwargs: Any) -> Any:
        with self._lock:
            result = method(self, *args, **kwargs)
            # a walk is read whole under the lock: a generator would walk outside it
            return list(result) if walk else result
    call.__name__ = method.__name__
    return call


def _locked(base: type) -> type:
    """``base`` (a weak-keyed registry class) with its walks and changes under one lock."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self._lock = threading.RLock()
        base.__init__(self, *args, **kwargs)

    body = {name: _under_lock(getattr(base, name), name in _WALKS)
            for name in _METHODS if hasattr(base, name)}
    body.update(__init__=__init__, __iter__=lambda self: iter(self.keys()))
    return type(f"Locked{base.__name__}", (base,), body)


def install() -> None:
    """Swap HoloViews' stream and link registries for locked ones (once per process)."""
    global _installed
    with _guard:
        if _installed:
            return
        from holoviews.plotting.links import Link
        from holoviews.streams import Stream

        old = Stream.registry
        new = _locked(type(old))()
        # the stored weak references, as they are: the streams stay owned by their sources
        for source, refs in weakref.WeakKeyDictionary.items(old):
            weakref.WeakKeyDictionary.__setitem__(new, source, refs)
        Stream.registry = new

        old_links = Link.registry
        links = _locked(type(old_links))()
        for source, value in list(old_links.items()):
            links[source] = value
        Link.registry = links
        _installed = True


def installed() -> bool:
    return _installed
