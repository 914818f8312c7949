"""Pin a run (A) and compare it with the live one (B): the two buttons and the caption naming both.

A ``pn.viewable.Viewer`` over the state. "Pin this run" writes the settings of the run the
page asks for into ``state.pinned`` (so the URL carries it, as ``pin=``); the session computes
that run once, as ``state.pinned_result``, and the time history, the Poincaré map and the
bifurcation diagram draw it beside the live run. "Unpin" clears it. The caption names both
runs as plain text (a pin may come from a link: nothing in it is ever HTML).
"""
from __future__ import annotations

import html
from typing import Any

import panel as pn
import param

from ..pinning import pin_text
from ..state import ExplorerState
from ..ui.labels import GEAR_COLOR, PIN_COLOR
from ..ui.plots import run_label
from ..ui.present import PANE_CSS, mark, presents
from ..ui.widgets import message
from .present import present_button


class PinView(pn.viewable.Viewer):
    """The pin and unpin buttons and the A-versus-B caption (see the module docstring)."""

    state = param.ClassSelector(class_=ExplorerState)

    def __init__(self, **params: Any):
        super().__init__(**params)
        s = self.state
        self.pin_button = pn.widgets.Button(label="Pin this run", color="primary", width=130,
                                            css_classes=["pin-run"],
                                            description="Keep this run as A; later changes are B")
        self.unpin_button = pn.widgets.Button(label="Unpin", width=90, css_classes=["unpin-run"])
        self.pin_button.on_click(lambda e: self.pin())
        self.unpin_button.on_click(lambda e: self.unpin())
        self.caption = pn.pane.HTML("", css_classes=["pin-caption"], sizing_mode="stretch_width",
                                    margin=(0, 10), stylesheets=[PANE_CSS])
        self.present_button = present_button(s, "pin")
        s.param.watch(self._draw, ["pinned", "pinned_result", "result", "phases"])
        s.param.watch(self._present, ["present", "stage"])
        self._draw()
        self._present()

    def __panel__(self):
        return pn.Column(pn.Row(self.pin_button, self.unpin_button, self.caption,
                                self.present_button, sizing_mode="stretch_width"),
                         message(self.state, "pinned"), sizing_mode="stretch_width")

    def _present(self, *_: Any) -> None:
        """Presented, the caption naming A and B is as large as the badge's sentence; the
        buttons stay, so a lecture can pin another run."""
        mark([self.caption], presents(self.state, "pin"))

    def pin(self) -> None:
        """Keep the run the page asks for as A."""
        self.state.clear("pinned")
        self.state.pinned = pin_text(self.state)

    def unpin(self) -> None:
        """Forget A."""
        self.state.clear("pinned")
        self.state.pinned = ""

    def lines(self) -> list[str]:
        """The caption's lines (plain text): A's and B's names, or what to do."""
        s = self.state
        if not s.pinned:
            return ["Pin this run to compare it with later changes (A: pinned, B: live)."]
        a = s.pinned_result
        b = s.result
        return [run_label("A", a, s.phases) if a is not None else "A: computing the pinned run…",
                run_label("B", b, s.phases) if b is not None else "B: –"]

    def _draw(self, *_: Any) -> None:
        self.unpin_button.disabled = not self.state.pinned
        lines = self.lines()
        if not self.state.pinned:
            self.caption.object = _line(lines[0], "#555555", "pin-none")
            return
        self.caption.object = (_line(lines[0], PIN_COLOR, "pin-a", dashed=True)
                               + _line(lines[1], GEAR_COLOR, "pin-b"))


def _line(text: str, color: str, css: str, dashed: bool = False) -> str:
    """One caption line: a swatch in the run's colour (dashed for A), then the text, escaped."""
    border = "dashed" if dashed else "solid"
    swatch = (f'<span style="display:inline-block;width:22px;height:0;margin-right:6px;'
              f'vertical-align:middle;border-top:2px {border} {color}"></span>')
    return (f'<div class="{css} pin-line" style="font-size:12.5px;color:#333">{swatch}'
            f'{html.escape(text)}</div>')
