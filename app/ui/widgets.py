"""Controls bound to one state parameter each, with the parameter's message beside them.

Every control writes its parameter through param (whose bounds refuse bad values) and
follows it back, so a value put back by the session (a run that failed, a link that could
not follow) shows at once. A refused value leaves :func:`app.query.rejection`'s message
beside the control and the control at the value kept; a slider's range is never stretched
by a refused value. Sliders act on ``value_throttled`` (on release), not on every drag event.

:func:`message` is the pane that shows a parameter's message: escaped text, never HTML.
"""
from __future__ import annotations

import logging
import math
from typing import Any

import panel as pn
import param

from ..query import rejection
from .help import tooltip
from .labels import message_html

log = logging.getLogger(__name__)


def message(state: Any, name: str, **kw: Any) -> pn.pane.HTML:
    """A pane showing ``state.messages[name]`` (escaped), hidden while there is none."""
    text = state.messages.get(name, "")
    pane = pn.pane.HTML(message_html(text) if text else "", visible=bool(text), margin=(0, 10),
                        css_classes=[f"msg-{name}"], sizing_mode="stretch_width", **kw)
    shown = [text]

    def update(event) -> None:
        new = event.new.get(name, "")
        if new != shown[0]:
            shown[0] = new
            pane.param.update(object=message_html(new) if new else "", visible=bool(new))
    state.param.watch(update, "messages")
    return pane


def set_value(state: Any, name: str, value: Any) -> bool:
    """Set ``state.<name>`` or leave the refusal's message beside its control; True if set."""
    if value == getattr(state, name):
        return True
    try:
        setattr(state, name, value)
    except ValueError:
        state.say(name, rejection(state, name, value))
        return False
    except Exception as exc:  # a callback never raises into the page
        log.warning("setting %s failed: %s: %s", name, type(exc).__name__, exc)
        state.say(name, f"{type(exc).__name__}: {exc}")
        return False
    return True


def deferred(obj: Any) -> Any:
    """``obj`` rendered only once the page has loaded (a spinner until then)."""
    return pn.param.ParamFunction(lambda: obj, defer_load=True, sizing_mode="stretch_width",
                                  min_height=380)


def built_when_shown(part: Any) -> Any:
    """A holder that puts ``part`` in the page the first time ``part`` is visible: a plot
    hidden until the user asks for it (a traced curve, the twin) costs a page build nothing."""
    holder = pn.Column(sizing_mode=part.sizing_mode or "stretch_width", margin=0)

    def show(*_: Any) -> None:
        if part.visible and not holder.objects:
            holder.append(part)
    part.param.watch(show, "visible")
    show()
    return holder


def shortened(v: Any) -> Any:
    """A float as a box shows it: nine significant digits, so a derived value (an engine speed
    from Λ) reads like a typed one and every box fits the same digits; others unchanged."""
    if isinstance(v, float) and math.isfinite(v):
        return float(f"{v:.9g}")
    return v


class FloatBox(pn.widgets.FloatInput):
    """Panel's ``FloatInput``, whose empty value reaches the page empty: Panel sends ``None`` as
    NaN, and the page's box then reads "NaN" (an optional value, such as x₀, cleared by a
    preset). Bokeh's box takes ``null`` and shows it empty."""

    def _process_param_change(self, params: dict[str, Any]) -> dict[str, Any]:
        empty = params.get("value", False) is None
        out = super()._process_param_change(params)
        if empty and "value" in out:
            out["value"] = None
        return out


class Field(pn.viewable.Viewer):
    """A numeric parameter: its label, an exact-value box, a slider (if it has softbounds), its message."""

    state = param.Parameter()
    name_ = param.String()

    def __init__(self, state: Any, name: str, label: str | None = None, slider: bool | None = None,
                 integer: bool | None = None, placeholder: str = "", width: int | None = None,
                 css: str | None = None, help: str | None = None):
        super().__init__(state=state, name_=name)
        p = state.param[name]
        self._p = p
        self._syncing = False
        value = getattr(state, name)
        integer = isinstance(p, param.Integer) if integer is None else integer
        box_cls = pn.widgets.IntInput if integer else FloatBox
        box_kw = dict(value=value, placeholder=placeholder, css_classes=["value-box"], margin=(0, 5))
        slider = bool(p.softbounds) if slider is None else slider
        text = label if label is not None else f"{p.label} · {p.doc}" if p.doc else p.label
        self.label = pn.pane.HTML(_label_html(text), margin=(4, 10, 0, 10), sizing_mode="stretch_width")
        # ``help``: a key of app.ui.help.HELP, shown by a "?" icon beside the label
        head = self.label if help is None else pn.Row(self.label, tooltip(help), margin=0,
                                                      sizing_mode="stretch_width")
        if slider:
            lo, hi = p.softbounds
            self.box = box_cls(width=95, **box_kw)
            self.slider = pn.widgets.FloatSlider(value=value, start=lo, end=hi, step=p.step or 0.01,
                                                 show_value=False, sizing_mode="stretch_width",
                                                 margin=(8, 10, 0, 10), css_classes=[f"slider-{name}"])
            self.slider.param.watch(self._on_slider, "value_throttled")
            row = pn.Row(self.slider, self.box, sizing_mode="stretch_width", margin=0)
        else:
            self.slider = None
            self.box = box_cls(sizing_mode="stretch_width" if width is None else "fixed",
                               width=width, **box_kw)
            row = self.box
        self.box.param.watch(self._on_box, "value")
        self.msg = message(state, name)
        self.layout = pn.Column(head, row, self.msg, css_classes=[css or f"ctl-{name}"],
                                sizing_mode="stretch_width", margin=(0, 0, 4, 0))
        state.param.watch(self._from_state, name)
        self._from_state()

    def __panel__(self):
        return self.layout

    def _on_box(self, event) -> None:
        if not self._syncing:
            value = event.new
            if value is None and not self._p.allow_None:
                self._from_state()
                return
            # the slider follows the typed value at once: the state's watchers redraw every
            # view before this field hears of the change, and the slider would move after them
            if isinstance(value, (int, float)) and math.isfinite(value):
                self._show_on_slider(value)
            set_value(self.state, self.name_, value)
            self._from_state()

    def _on_slider(self, event) -> None:
        if not self._syncing and event.new is not None:
            value = round(float(event.new), 10)
            set_value(self.state, self.name_, int(value) if isinstance(self._p, param.Integer) else value)
            self._from_state()

    def _from_state(self, *_: Any) -> None:
        """Show the state's value; the slider's range is its softbounds, stretched to the value."""
        v = getattr(self.state, self.name_)
        self._syncing = True
        try:
            shown = shortened(v)
            if self.box.value != shown:
                self.box.value = shown
            if v is not None:
                self._show_on_slider(v)
        finally:
            self._syncing = False

    def _show_on_slider(self, v: float) -> None:
        if self.slider is None:
            return
        lo, hi = self._p.softbounds
        want = {"start": min(lo, v), "end": max(hi, v), "value": v}
        changes = {k: x for k, x in want.items() if getattr(self.slider, k) != x}
        if changes:
            was, self._syncing = self._syncing, True
            try:
                self.slider.param.update(**changes)
            finally:
                self._syncing = was


class Choice(pn.viewable.Viewer):
    """A selector or switch parameter: radio buttons or (``select``) a drop-down over ``options``
    (label → value), or a checkbox when there are no options."""

    def __init__(self, state: Any, name: str, options: dict[str, Any] | None = None,
                 label: str | None = None, select: bool = False, **kw: Any):
        super().__init__()
        self.state, self.name_ = state, name
        self._syncing = False
        value = getattr(state, name)
        css = [f"ctl-{name}"]
        if options is None:
            self.widget = pn.widgets.Checkbox(label=label or state.param[name].label, value=value,
                                              css_classes=css, **kw)
        elif select:
            self.widget = pn.widgets.Select(label=label or state.param[name].label, options=options,
                                            value=value, css_classes=css, **kw)
        else:
            self.widget = pn.widgets.RadioButtonGroup(options=options, value=value, css_classes=css,
                                                      color="default", **kw)
        self.widget.param.watch(self._on_widget, "value")
        self.msg = message(state, name)
        state.param.watch(self._from_state, name)

    def __panel__(self):
        return pn.Column(self.widget, self.msg, margin=0, sizing_mode="stretch_width")

    def _on_widget(self, event) -> None:
        if not self._syncing:
            set_value(self.state, self.name_, event.new)
            self._from_state()

    def _from_state(self, *_: Any) -> None:
        v = getattr(self.state, self.name_)
        if self.widget.value != v:
            self._syncing = True
            try:
                self.widget.value = v
            finally:
                self._syncing = False


def _label_html(text: str) -> str:
    import html
    return (f'<div style="font-size:13px;line-height:1.25;overflow-wrap:anywhere">'
            f"{html.escape(text)}</div>")
