"""Presentation mode's switches, and the few sliders a lecture needs while the sidebar is hidden.

:class:`PresentView` is a button in the page's header: "Present" sets ``state.present`` (the URL
key ``present``) to show the time history and the section, "Exit presentation" clears it.
:func:`present_button` is the "Present this" button the other presentable views carry (the
diagram, the gear in motion, the pin, the Maps tab): it presents that view instead
(``state.stage``, :data:`app.ui.present.STAGES`). While presenting, the button carries the class
that the template's stylesheet keys on (:data:`app.ui.present.PAGE_MARK`), which hides the
sidebar, and Λ and φ₂ get sliders beside the button. The other views
follow ``state.present`` themselves; the dashboard hides what a lecture does not need.
"""
from __future__ import annotations

from typing import Any

import panel as pn
import param

from ..state import ExplorerState
from ..ui.present import PAGE_MARK, STAGES, mark
from ..ui.widgets import set_value

#: The sliders kept while presenting.
ESSENTIAL = ("lam", "phi2")
#: Their titles as large as the presenting figures' tick labels.
SLIDER_CSS = ".bk-slider-title { font-size: 17px !important; }"


class PresentView(pn.viewable.Viewer):
    """The header's "Present" / "Exit presentation" button, and the sliders beside it while
    presenting (the header is a root of the page: its class reaches the template's stylesheet)."""

    state = param.ClassSelector(class_=ExplorerState)
    header = param.ClassSelector(class_=pn.Row, default=None, doc=(
        "the row the button and sliders go in: the page's header root, when it was drawn "
        "before this view was built"))

    def __init__(self, **params: Any):
        super().__init__(**params)
        s = self.state
        self._syncing = False
        self.button = pn.widgets.Button(label="Present", color="light", width=170,
                                        css_classes=["present-toggle"], align="center",
                                        description="Large fonts and plots for a projector "
                                                    "(present=true in the URL)")
        self.button.on_click(lambda e: s.param.update(present=not s.present, stage="plots"))
        self.slider = {n: self._slider(n) for n in ESSENTIAL}
        self.sliders = pn.Row(*self.slider.values(),
                              css_classes=["present-sliders"], visible=s.present, margin=(0, 10))
        if self.header is None:
            self.header = pn.Row(margin=0)
        self.header[:] = [self.button, self.sliders]
        s.param.watch(self._follow, "present")
        for n in ESSENTIAL:
            s.param.watch(self._follow_value, n)
        self._follow()

    def __panel__(self):
        return self.header

    def _slider(self, name: str) -> pn.widgets.FloatSlider:
        p, v = self.state.param[name], getattr(self.state, name)
        lo, hi = p.softbounds
        w = pn.widgets.FloatSlider(label=p.label, start=min(lo, v), end=max(hi, v), step=p.step,
                                   value=v, width=230, css_classes=[f"present-{name}"],
                                   stylesheets=[SLIDER_CSS])
        w.param.watch(lambda e: self._on_slider(name, e.new), "value_throttled")
        return w

    def _on_slider(self, name: str, value: Any) -> None:
        if not self._syncing and value is not None:
            set_value(self.state, name, round(float(value), 10))

    def _follow_value(self, event) -> None:
        w, (lo, hi) = self.slider[event.name], self.state.param[event.name].softbounds
        v = event.new
        # Panel copies a value set here into value_throttled: that is no move of the user's
        self._syncing = True
        try:
            w.param.update(start=min(lo, v), end=max(hi, v), value=v)
        finally:
            self._syncing = False

    def _follow(self, *_: Any) -> None:
        on = self.state.present
        self.button.label = "Exit presentation" if on else "Present"
        mark([self.header], on, PAGE_MARK)
        self.sliders.visible = on


def present_button(state: ExplorerState, stage: str, width: int = 120) -> pn.widgets.Button:
    """A "Present this" button that presents ``stage`` (a key of :data:`STAGES`); hidden while
    presenting, when the header's "Exit presentation" is the way back."""
    if stage not in STAGES:
        raise ValueError(f"stage must be one of {sorted(STAGES)}, not {stage!r}")
    button = pn.widgets.Button(label="Present this", width=width, align="center",
                               css_classes=["present-this", f"present-{stage}"],
                               description="Show this view alone, large, for a projector "
                                           f"(present=true&stage={stage} in the URL)")
    button.on_click(lambda e: state.param.update(stage=stage, present=True))

    def follow(*_: Any) -> None:
        button.visible = not state.present
    state.param.watch(follow, "present")
    follow()
    return button
