"""One browser session's page: the session's state and its views, laid out in a template.

:class:`Dashboard` builds a :class:`~app.session.Session` (the state, its URL, its runs, its
background jobs) and one ``pn.viewable.Viewer`` per part of the page, each given the state
(and, if it runs background work, the session's jobs). The views never refer to each other:
they meet only in the state. :meth:`Dashboard.destroy` runs when the session closes.
"""
from __future__ import annotations

import weakref
from typing import Any

import panel as pn

from .views.atlas import AtlasView
from .views.bifcurve import CurveView
from .views.continuation import ContinuationView
from .views.controls import Controls
from .views.diagram import DiagramView
from .views.explorer import RegimeView, SectionView
from .views.gearbox import GearboxView
from .views.maps import MapsView
from .views.motion import MotionView
from .views.noise import NoiseView
from .views.pin import PinView
from .work.threads import HV_LOCK
from .session import Session
from .views.sensitivity import SensitivityView
from .views.sound import SoundView
from .views.time_history import TimeHistoryView
from .views.units import UnitsView
from .ui.widgets import message

SIDEBAR_WIDTH = 380
#: The main tabs, in order, as the state's ``tab`` (and the URL) names them.
TABS = ("explorer", "maps", "gearbox")
#: Every live dashboard (weakly held): a closed session's must disappear from here.
LIVE: "weakref.WeakSet[Dashboard]" = weakref.WeakSet()


class Dashboard:
    """Everything one browser session sees (build it with :func:`app.main.create_app`)."""

    def __init__(self, location: Any = None, doc: Any = None, pool: Any = None):
        with HV_LOCK:  # the views build HoloViews streams
            self._build(location, doc, pool)
        LIVE.add(self)

    def _build(self, location: Any, doc: Any, pool: Any) -> None:
        self.session = Session(location=location, doc=doc, pool=pool)
        s = self.state = self.session.state
        jobs = self.session.jobs
        self.controls = Controls(state=s)
        self.units = UnitsView(state=s)
        self.regime = RegimeView(state=s)
        self.pin = PinView(state=s)
        self.noise = NoiseView(state=s, jobs=jobs)
        self.time_history = TimeHistoryView(state=s)
        self.section = SectionView(state=s)
        self.motion = MotionView(state=s)
        self.diagram = DiagramView(state=s, jobs=jobs)
        self.continuation = ContinuationView(state=s, jobs=jobs)
        self.sound = SoundView(state=s)
        self.sensitivity = SensitivityView(state=s)
        self.curve = CurveView(state=s, jobs=jobs)
        self.maps = MapsView(state=s, jobs=jobs, settings=self.session.map_settings)
        self.atlas = AtlasView(state=s, jobs=jobs, maps=self.maps)
        self.gearbox = GearboxView(state=s, jobs=jobs)
        self.views = [self.controls, self.units, self.regime, self.pin, self.noise,
                      self.time_history,
                      self.section, self.motion,
                      self.diagram, self.continuation, self.curve, self.sound, self.maps,
                      self.atlas, self.gearbox, self.sensitivity]
        explorer = pn.Column(
            self.regime, self.pin, self.noise,
            self.time_history, self.units.table,
            self.motion,
            pn.Row(self.section, pn.Column(self.diagram, self.continuation, self.curve,
                                           sizing_mode="stretch_width"),
                   sizing_mode="stretch_width"),
            self.sensitivity, self.sound, sizing_mode="stretch_width")
        maps_tab = pn.Column(self.maps, self.atlas, sizing_mode="stretch_width")
        self.tabs = pn.Tabs(("Explorer", explorer), ("Maps", maps_tab), ("Gearbox", self.gearbox),
                            dynamic=True, active=TABS.index(s.tab),
                            sizing_mode="stretch_width", css_classes=["main-tabs"])
        # the active tab is the state's ``tab`` (a URL key): a shared link opens on its tab
        self.tabs.param.watch(self._on_tab, "active")
        s.param.watch(self._on_state_tab, "tab")
        if s.tab == "maps":
            self.maps.open_link()
        self.layout = pn.template.BootstrapTemplate(
            title="Rattle Explorer: gear rattle, exactly",
            sidebar=[self.controls, self.units], sidebar_width=SIDEBAR_WIDTH,
            main=[message(s, "url"), message(s, "tab"), message(s, "global"), self.tabs],
            header_background="#2c3e50")

    def _on_tab(self, event) -> None:
        if 0 <= event.new < len(TABS):
            self.state.tab = TABS[event.new]

    def _on_state_tab(self, event) -> None:
        self.tabs.active = TABS.index(event.new)

    def destroy(self) -> None:
        """The session closed: cancel its work and let go of its results."""
        self.session.destroy()
        self.sound.signal = None
