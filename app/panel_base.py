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

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .dashboard import Dashboard


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
