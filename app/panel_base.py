"""The contract between the dashboard and its feature panels (units, sound, 2-D maps).

A feature panel owns its widgets and its work; the dashboard only places what the panel
offers and tells it when the trajectory changed:

* ``sidebar``: objects appended to the sidebar, below the export controls;
* ``explorer``: objects placed in the Explorer tab, below the plots;
* ``tab``: a ``(title, object)`` pair shown as a tab of its own, or None;
* :meth:`on_redraw`: called after every good redraw, with ``dashboard.tr``,
  ``dashboard.params``, ``dashboard.state`` and ``dashboard.classification`` current. It runs
  on the slider path, so it must be cheap, or defer its work until the user asks for it;
* :meth:`on_destroyed`: the session closed; cancel background work.
"""
from __future__ import annotations

import functools
import logging
from typing import TYPE_CHECKING, Any, Callable

if TYPE_CHECKING:
    from .dashboard import Dashboard


log = logging.getLogger("app")


def guard(field: str | None) -> Callable[[Callable], Callable]:
    """Decorator for callbacks of an object with ``show_error(field, message)``: any exception
    becomes that message and one log line, never a traceback in the server log."""
    def decorate(method: Callable) -> Callable:
        @functools.wraps(method)
        def wrapper(self: Any, *args: Any, **kwargs: Any) -> Any:
            try:
                return method(self, *args, **kwargs)
            except Exception as exc:
                log.warning("%s.%s failed: %s: %s", type(self).__name__, method.__name__,
                            type(exc).__name__, exc)
                self.show_error(field, f"{type(exc).__name__}: {exc}")
                return None
        return wrapper
    return decorate


class FeaturePanel:
    """Base class: a panel that offers nothing until a subclass fills these in."""

    def __init__(self, dashboard: "Dashboard"):
        self.dashboard = dashboard
        self.sidebar: list[Any] = []
        self.explorer: list[Any] = []
        self.tab: tuple[str, Any] | None = None

    def on_redraw(self) -> None:
        """The dashboard drew a new trajectory."""

    def on_destroyed(self) -> None:
        """The session closed."""
