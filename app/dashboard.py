"""One browser session's page: the session's state and its views, laid out in a template.

:class:`Dashboard` builds a :class:`~app.session.Session` (the state, its URL, its runs, its
background jobs) and one ``pn.viewable.Viewer`` per part of the page, each given the state
(and, if it runs background work, the session's jobs). The views never refer to each other:
they meet only in the state. :meth:`Dashboard.destroy` runs when the session closes.

:class:`Shell` is the page before its views exist: the template, its header, sidebar and tabs
empty, and a "computing…" note in the main area. The server sends it at once and builds the
dashboard into it once the browser has connected (:func:`app.main.create_app`), so a page shows
its layout within a second, and a client that has gone costs no build.

Presentation mode (``state.present``) keeps every view and model: the header's button marks
the page (the template's stylesheet hides the sidebar), the Explorer's stylesheet lays the time
history and the section side by side in the height the window leaves below the header, what
holds them stretches, and the parts a lecture does not need are hidden. ``state.stage`` picks
another view to present instead (:data:`app.ui.present.STAGES`): the diagram, the gear in motion,
the pin, or the Maps tab's map, each shown alone in the same way.
"""
from __future__ import annotations

import weakref
from html import escape
from typing import Any

import panel as pn

from .views.atlas import AtlasView
from .views.bifcurve import CurveView
from .views.continuation import ContinuationView
from .views.controls import Controls
from .views.diagram import DiagramView
from .views.explorer import RegimeView, SectionView
from .views.gearbox import GearboxView
from .views.runup import RunupView
from .views.maps import MapsView
from .views.measurement import MeasurementView
from .views.motion import MotionView
from .views.noise import NoiseView
from .views.pin import PinView
from .views.present import PresentView
from .work.threads import BUILD_LOCK, HV_LOCK, building, give_way
from .session import Session
from .views.sensitivity import SensitivityView
from .views.sound import SoundView
from .views.time_history import TimeHistoryView
from .views.units import UnitsView
from .ui.present import PAGE_CSS, PANE_CSS, PRESENTING, STAGES, mark
from .ui.widgets import message

SIDEBAR_WIDTH = 380
#: The main tabs, in order, as the state's ``tab`` (and the URL) names them.
TABS = ("explorer", "maps", "gearbox")
#: While presenting, the Explorer tab is a grid as high as the main area: the regime's row on
#: top, and below it the time history and the section side by side, sharing what is left.
#: Presenting the gear in motion, the drawing takes the section's place beside the time
#: history; presenting the pin, its caption is a row above the two plots; presenting the
#: diagram, it takes the whole last row.
EXPLORER_CSS = f"""
:host(.{PRESENTING}) {{ display: grid !important; height: 100% !important; column-gap: 10px;
                        grid-template-columns: minmax(0, 1fr) minmax(0, 1fr);
                        grid-template-rows: auto minmax(0, 1fr); }}
:host(.{PRESENTING}.stage-pin) {{ grid-template-rows: auto auto minmax(0, 1fr); }}
:host(.{PRESENTING}) > * {{ grid-column: 1 / -1; }}
:host(.{PRESENTING}) > .th-cell, :host(.{PRESENTING}) > .section-row,
:host(.{PRESENTING}) > .motion-cell {{
    grid-column: auto; width: auto !important; height: auto !important; align-self: stretch !important;
    min-width: 0 !important; min-height: 0 !important; }}
:host(.{PRESENTING}.stage-diagram) > .section-row {{ grid-column: 1 / -1; }}
"""
#: Presenting the diagram, the continuation's controls and multipliers stand in a column at
#: its right, so that the diagram keeps the window's height.
DIAGRAMS_CSS = f"""
:host(.{PRESENTING}) {{ display: grid !important; column-gap: 10px;
                        grid-template-columns: minmax(0, 1fr) 400px;
                        grid-template-rows: minmax(0, 1fr); }}
:host(.{PRESENTING}) > * {{ min-width: 0 !important; min-height: 0 !important;
                            width: auto !important; }}
:host(.{PRESENTING}) > .diagram-cell {{ height: auto !important; align-self: stretch !important; }}
"""
#: Presenting the maps, the map takes the Maps tab's height less what the atlas's card needs.
MAPS_CSS = f"""
:host(.{PRESENTING}) {{ display: grid !important; height: 100% !important;
                        grid-template-columns: minmax(0, 1fr);
                        grid-template-rows: minmax(0, 1fr) auto; }}
:host(.{PRESENTING}) > * {{ min-width: 0 !important; min-height: 0 !important; width: auto !important; }}
:host(.{PRESENTING}) > :first-child {{ height: auto !important; align-self: stretch !important; }}
"""
#: Every live dashboard (weakly held): a closed session's must disappear from here.
LIVE: "weakref.WeakSet[Dashboard]" = weakref.WeakSet()
#: What the main area shows until the dashboard is built into it.
SKELETON = ('<div class="page-skeleton" style="padding: 24px 12px; font-size: 18px; '
            'color: #555;">computing… the first run and the plots are on their way</div>')


class Abandoned(Exception):
    """The page's client went away while its dashboard was being built."""


class Shell:
    """The page's frame, cheap to build and send: the template with its header row, sidebar
    column and main tabs empty, and :data:`SKELETON` where the notes go (the roots stay those
    the template's stylesheet keys on: the header row, the tabs)."""

    def __init__(self) -> None:
        self.skeleton = pn.pane.HTML(SKELETON, css_classes=["page-skeleton-pane"],
                                     sizing_mode="stretch_width", margin=0)
        self.notes = pn.Column(self.skeleton, sizing_mode="stretch_width", margin=0)
        self.tabs = pn.Tabs(dynamic=True, sizing_mode="stretch_width", css_classes=["main-tabs"],
                            stylesheets=[PANE_CSS])
        self.sidebar = pn.Column(sizing_mode="stretch_width", margin=0)
        self.header = pn.Row(margin=0)
        self.layout = pn.template.BootstrapTemplate(
            title="Rattle Explorer: gear rattle, exactly", sidebar=[self.sidebar],
            sidebar_width=SIDEBAR_WIDTH, main=[self.notes, self.tabs], header=[self.header],
            header_background="#2c3e50")
        self.layout.config.raw_css.append(PAGE_CSS)

    def fail(self, text: str) -> None:
        """The dashboard could not be built: say so where "computing…" was."""
        self.skeleton.object = (f'<div class="page-skeleton" data-kind="failed" style="padding: '
                                f'24px 12px; font-size: 18px; color: #a00;">{escape(text)}</div>')


#: Views made of Panel widgets and plain Bokeh only, no HoloViews object: built without
#: :data:`~app.work.threads.BUILD_LOCK`, so another page's build never waits for them (a test
#: checks that they make no HoloViews element, map or stream).
PLAIN_VIEWS = (Controls, UnitsView, PinView, NoiseView, TimeHistoryView, MotionView, SoundView,
               RunupView, PresentView)


def _built(view: type, **kwargs: Any) -> Any:
    """One view, built holding :data:`~app.work.threads.BUILD_LOCK` (its HoloViews streams)
    and letting go after, so that another page's build waits for one view of this page, not
    for all of them; a view of :data:`PLAIN_VIEWS` without it. Another session's redraw
    waits for neither, and the build pauses for it first (:func:`~app.work.threads.give_way`)."""
    give_way()
    if view in PLAIN_VIEWS:
        return view(**kwargs)
    with BUILD_LOCK:
        return view(**kwargs)


class Dashboard:
    """Everything one browser session sees (build it with :func:`app.main.create_app`).

    ``shell``: the page already sent, to build into (a new one by default); ``alive``: asked
    before each heavy step, and the build is abandoned (:class:`Abandoned`, the session
    closed) once it answers no.
    """

    def __init__(self, location: Any = None, doc: Any = None, pool: Any = None,
                 shell: Shell | None = None, alive: Any = None):
        self.shell = shell if shell is not None else Shell()
        self._alive = alive or (lambda: True)
        self._build(location, doc, pool)
        LIVE.add(self)

    def _check_alive(self) -> None:
        if not self._alive():
            if getattr(self, "session", None) is not None:
                self.session.destroy()
            raise Abandoned("the page's client has gone")

    def _build(self, location: Any, doc: Any, pool: Any) -> None:
        with building():
            self._build_views(location, doc, pool)

    def _build_views(self, location: Any, doc: Any, pool: Any) -> None:
        self._check_alive()
        self.session = Session(location=location, doc=doc, pool=pool)
        self._check_alive()  # the first run is done: the views and their plots come next
        s = self.state = self.session.state
        jobs = self.session.jobs
        self.controls = _built(Controls, state=s)
        self.units = _built(UnitsView, state=s)
        self.regime = _built(RegimeView, state=s)
        self.pin = _built(PinView, state=s)
        self.noise = _built(NoiseView, state=s, jobs=jobs)
        self.time_history = _built(TimeHistoryView, state=s)
        self.section = _built(SectionView, state=s)
        self.motion = _built(MotionView, state=s)
        self.diagram = _built(DiagramView, state=s, jobs=jobs)
        self.continuation = _built(ContinuationView, state=s, jobs=jobs)
        self.sound = _built(SoundView, state=s)
        self.sensitivity = _built(SensitivityView, state=s)
        self.curve = _built(CurveView, state=s, jobs=jobs)
        self.maps = _built(MapsView, state=s, jobs=jobs, settings=self.session.map_settings)
        self.atlas = _built(AtlasView, state=s, jobs=jobs, maps=self.maps)
        self.measurement = _built(MeasurementView, state=s, jobs=jobs,
                                  settings=self.session.gearbox_settings)
        self.gearbox = _built(GearboxView, state=s, jobs=jobs, settings=self.session.gearbox_settings,
                              measurement=self.measurement)
        self.runup = _built(RunupView, state=s, jobs=jobs, gearbox=self.gearbox)
        self.present = _built(PresentView, state=s, header=self.shell.header)
        give_way()
        with BUILD_LOCK:  # the views' panels may build HoloViews panes
            maps_tab = self._arrange()
        # each plot's models are built under the build lock, one plot at a time (HoloViewsPane)
        self._lay_out(maps_tab)

    def _arrange(self) -> Any:
        """The views in their rows and columns; returns the Maps tab's column."""
        self.views = [self.controls, self.units, self.regime, self.pin, self.noise,
                      self.time_history, self.section, self.motion,
                      self.diagram, self.continuation, self.curve, self.sound, self.maps,
                      self.atlas, self.gearbox, self.runup, self.sensitivity, self.present]
        cell = lambda v, css="": pn.Column(v, sizing_mode="stretch_width", margin=0,  # noqa: E731
                                           css_classes=[css] if css else [])
        diagram_cell = cell(self.diagram, "diagram-cell")
        self.diagrams = pn.Column(diagram_cell, pn.Column(self.continuation, self.curve, margin=0,
                                                          sizing_mode="stretch_width"),
                                  sizing_mode="stretch_width", stylesheets=[DIAGRAMS_CSS])
        # while presenting, the explorer's stylesheet lays these two cells side by side
        th_cell = cell(self.time_history, "th-cell")
        section_cell = cell(self.section)
        self.section_row = pn.Row(section_cell, self.diagrams, css_classes=["section-row"],
                                  sizing_mode="stretch_width")
        #: The Explorer's parts by the names of :data:`app.ui.present.STAGES` (and the others):
        #: presenting, only those of the stage are shown, and those holding plots stretch.
        self.cells = {"pin": cell(self.pin, "pin-cell"), "noise": cell(self.noise),
                      "table": cell(self.units.table), "time_history": th_cell,
                      "motion": cell(self.motion, "motion-cell"), "section": section_cell,
                      "diagram": self.diagrams, "sensitivity": cell(self.sensitivity),
                      "sound": cell(self.sound)}
        #: What stretches to the window's height while presenting, when shown.
        self.holders = {"time_history": [th_cell], "motion": [self.cells["motion"]],
                        "section": [self.section_row, section_cell],
                        "diagram": [self.section_row, self.diagrams, diagram_cell]}
        c = self.cells
        self.explorer = pn.Column(
            self.regime, c["pin"], c["noise"], th_cell, c["table"], c["motion"], self.section_row,
            c["sensitivity"], c["sound"],
            sizing_mode="stretch_width", css_classes=["explorer"], stylesheets=[EXPLORER_CSS])
        self.maps_tab = pn.Column(self.maps, self.atlas, sizing_mode="stretch_width",
                                  stylesheets=[MAPS_CSS])
        return self.maps_tab

    def _lay_out(self, maps_tab: Any) -> None:
        """The arranged views put in the page already sent (every view's models are built)."""
        s = self.state
        self._check_alive()  # what follows puts every view's models in the page
        shell = self.shell
        self.tabs = shell.tabs
        # no tab is active while the tabs are put in, so that only the link's own tab is built:
        # a tab built and hidden at once left plots that the page never received, and the
        # server went on sending their changes ("reference … isn't known" in the page)
        self.tabs.active = -1
        self.tabs.extend([("Explorer", self.explorer), ("Maps", maps_tab),
                          ("Gearbox", pn.Column(self.gearbox, self.runup,
                                                sizing_mode="stretch_width"))])
        self.tabs.active = TABS.index(s.tab)
        # the active tab is the state's ``tab`` (a URL key): a shared link opens on its tab
        self.tabs.param.watch(self._on_tab, "active")
        s.param.watch(self._on_state_tab, "tab")
        if s.tab == "maps":
            with HV_LOCK:  # it changes the map's view, as a redraw does
                self.maps.open_link()
        self.layout = shell.layout
        shell.sidebar[:] = [self.controls, self.units]
        shell.notes[:] = [message(s, "url"), message(s, "tab"), message(s, "global")]
        s.param.watch(self._present, ["present", "stage"])
        self._present()

    def _present(self, *_: Any) -> None:
        """Presentation mode on or off, and what it shows (``state.stage``): the same views,
        another look (:mod:`app.ui.present`)."""
        s = self.state
        on = s.present
        stage = s.stage if on else None
        shown = set(STAGES[stage]) if on else set(self.cells)
        if on:  # the presented view's tab, whatever tab was open
            tab = TABS.index("maps" if stage == "maps" else "explorer")
            if self.tabs.active != tab:
                self.tabs.active = tab
        mark([self.explorer, self.tabs], on)
        # the diagrams' grid only while they are presented: its display would show them hidden
        mark([self.diagrams], stage == "diagram")
        mark([self.maps_tab], stage == "maps")
        for name in STAGES:
            mark([self.explorer], stage == name, f"stage-{name}")
        # said here, not left to Panel, which would infer it from the stretching plots when
        # the page is built while presenting, and keep it after
        stretched = {id(p) for name in shown if on for p in self.holders.get(name, ())}
        self.tabs.sizing_mode = "stretch_both" if on else "stretch_width"
        self.explorer.sizing_mode = "stretch_both" if on and stage != "maps" else "stretch_width"
        self.maps_tab.sizing_mode = "stretch_both" if stage == "maps" else "stretch_width"
        for part in {id(p): p for ps in self.holders.values() for p in ps}.values():
            part.sizing_mode = "stretch_both" if id(part) in stretched else "stretch_width"
        for name, part in self.cells.items():
            part.visible = not on or name in shown
        self.section_row.visible = not on or bool(shown & {"section", "diagram"})

    def _on_tab(self, event) -> None:
        if 0 <= event.new < len(TABS):
            self.state.tab = TABS[event.new]

    def _on_state_tab(self, event) -> None:
        self.tabs.active = TABS.index(event.new)

    def destroy(self) -> None:
        """The session closed: cancel its work and let go of its results."""
        self.session.destroy()
        self.sound.signal = None
