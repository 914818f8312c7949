"""The memory tests' account of what holds an object (``tests/holders.py``) finds the holder."""
from __future__ import annotations

import weakref

import holders


class Page:
    pass


def test_a_holder_in_the_app_is_named_and_found_through_the_app():
    from app import session
    page = Page()
    session._held_here = {"page": [page]}  # a module global of the app holds the page
    try:
        chains = holders.roots(page)
        assert any("dict['page']" in c and "module app.session" in c for c in chains), chains
        assert holders.through(chains, "app")
    finally:
        del session._held_here
    assert not holders.through(holders.roots(page), "app")  # only this test holds it now



def test_a_dead_weak_proxy_on_the_heap_is_walked_past():
    """A weak proxy whose object is gone stays on the heap (``isinstance`` on it raises)."""
    page, gone = Page(), Page()
    proxy = weakref.proxy(gone)
    del gone
    keep = {"page": page}
    assert any("dict['page']" in c for c in holders.roots(page))
    assert keep and type(proxy) is weakref.ProxyType
