"""A pinned run (A) beside the live one (B): the pin's text, its checks, and its one run.

The pin (``state.pinned``, URL key ``pin``) is the text of the settings that decide a run,
``'lam:3.3;r:0.65;…'`` over :data:`PIN_KEYS` (:func:`pin_text`). In physical units it also
holds the physical inputs (:data:`PIN_PHYSICAL_KEYS`) that give A its physical scale (time
in ms, engine speed), so a link reopens A as the page pinned it. :func:`parse_pin` reads it
back, checking each item as the state checks that parameter, and names the item at fault and
its allowed range; physical inputs must describe the pin's own Λ and j. A link whose pin does
not parse loses it before the page reads the link (:func:`drop_bad_pin`), with a message
beside the pin, as other unusable URL values do.

:class:`Pinner` (one per session) computes A once, when the pin changes, through the same
budgeted path as the live run (a :class:`~app.work.page_run.PageRun` of its own job kind, so
neither run cancels the other) and publishes it as ``state.pinned_result``; pinning the run
on the page reuses ``state.result`` itself. A pin with physical inputs has a physical side
(``Run.phys``, computed by :func:`app.physical.run_physical` as for the live run); a pin
without them (made on a dimensionless page, or an older link) has none, whatever the page's
mode: its physical scale is unknown, so in physical units its time history and its place on
the engine-speed diagram are not drawn (its section and Λ or φ₂ markers are). A pin that does
not parse or cannot run is refused: a message beside it, and the last pin and its run come
back.
"""
from __future__ import annotations

import urllib.parse
from typing import Any, Callable

import param

from rattle_core import SolverError

from .physical import physical_of, run_physical
from .query import Huge, number, rejection
from .state import PHYSICAL_KEYS, RUN_KEYS, ExplorerState, Run, rattle_params
from .ui.labels import short
from .work.page_run import PageRun, run_kwargs
from .work.threads import HV_LOCK

#: What a pin holds: everything that decides a run (its model and its run settings).
PIN_KEYS = RUN_KEYS
#: What a pin made in physical units holds besides: the inputs of A's physical scale.
PIN_PHYSICAL_KEYS = PHYSICAL_KEYS
#: Longest pin read, in characters (a pin of 32 harmonics is about 700).
MAX_PIN = 1500


def pin_text(state: ExplorerState) -> str:
    """The run ``state`` asks for as a pin: ``'lam:3.3;r:0.65;…'`` (every key of
    :data:`PIN_KEYS`, floats as their shortest exact text, an empty start as nothing), and
    the keys of :data:`PIN_PHYSICAL_KEYS` while the run has a physical side."""
    names = PIN_KEYS
    if state.units and run_physical(state, rattle_params(state)) is not None:
        names = (*PIN_KEYS, *PIN_PHYSICAL_KEYS)
    items = []
    for name in names:
        value = getattr(state, name)
        text = "" if value is None else (repr(value) if isinstance(value, float) else str(value))
        items.append(f"{name}:{text}")
    return ";".join(items)


def _value(name: str, text: str) -> Any:
    """One pin item's text as the state's value of ``name`` (not yet checked for range)."""
    p = ExplorerState.param[name]
    if name == "x0" and text == "":
        return None
    if isinstance(p, param.Number):
        value = number(text)  # a number of any length, a Huge beyond a float's range
        if value is None:
            try:
                value = float(text)  # also 'nan', 'inf': refused with the state's message
            except ValueError:
                return text
        if isinstance(value, Huge):
            return value
        if isinstance(p, param.Integer):
            return int(value) if value.is_integer() else value
        return float(value)
    return text


def _refusal(name: str, value: Any, exc: Exception) -> str:
    """Why a pin's value of ``name`` is refused: the state's own words, without 'Kept …'."""
    p = ExplorerState.param[name]
    if isinstance(p, (param.Number, param.Selector)):
        return rejection(ExplorerState, name, value).rsplit(" Kept ", 1)[0].rstrip(".")
    return f"{p.label or name}: {exc}"


def parse_pin(text: Any) -> dict[str, Any]:
    """The state values a pin holds (:func:`pin_text`'s inverse), each checked as the state
    checks it; keys left out take the state's defaults.

    Raises ``ValueError`` naming the item at fault and, for a number, its allowed range.
    """
    if not isinstance(text, str):
        raise ValueError(f"a pin must be text like 'lam:3.3;r:0.65', got {type(text).__name__}")
    if len(text) > MAX_PIN:
        raise ValueError(f"a pin of {len(text)} characters is longer than {MAX_PIN}")
    values: dict[str, Any] = {}
    for item in filter(None, (s.strip() for s in text.split(";"))):
        name, sep, raw = item.partition(":")
        if not sep:
            raise ValueError(f"pin item {short(item, 30)} must be 'key:value', e.g. 'lam:3.3'")
        if name not in PIN_KEYS and name not in PIN_PHYSICAL_KEYS:
            raise ValueError(f"pin key {short(name, 20)} is unknown; allowed: "
                             f"{', '.join((*PIN_KEYS, *PIN_PHYSICAL_KEYS))}")
        if name in values:
            raise ValueError(f"pin key {name!r} is given twice")
        value = _value(name, raw.strip())
        try:
            ExplorerState.param[name]._validate(value)
        except ValueError as exc:
            raise ValueError("pin: " + _refusal(name, value, exc)) from None
        values[name] = value
    if not values:
        raise ValueError("a pin must hold at least one 'key:value' item, e.g. 'lam:3.3'")
    if physical(values):
        _check_physical(ExplorerState(**values, units=True))
    return values


def physical(values: dict[str, Any]) -> bool:
    """Whether pin values hold physical inputs (then A has a physical side)."""
    return any(name in values for name in PIN_PHYSICAL_KEYS)


def _check_physical(ps: ExplorerState) -> None:
    """Refuse physical inputs that describe no model, or not the pin's own Λ and j (the live
    run's test, :func:`app.physical.run_physical`); inputs left out take their defaults."""
    params = rattle_params(ps)
    if run_physical(ps, params) is not None:
        return
    try:  # why not: no model at all, or another Λ and j
        q = physical_of(ps, params).to_dimensionless()
    except ValueError as exc:
        raise ValueError(f"pin: its physical inputs describe no model: {exc}") from None
    raise ValueError(f"pin: its physical inputs give Λ = {q.lam:.6g}, j = {q.j:.6g}, not "
                     f"its Λ = {params.lam:.6g}, j = {params.j:.6g}")


def pinned_state(text: str) -> ExplorerState:
    """A state holding the pin's run settings (the rest default), to build its run from; in
    physical units when the pin holds physical inputs."""
    values = parse_pin(text)
    return ExplorerState(**values, units=physical(values))


def drop_bad_pin(search: str, state: ExplorerState) -> str:
    """The link ``search`` without its pin if that does not parse (said beside the pin)."""
    pairs = urllib.parse.parse_qsl((search or "")[1:], keep_blank_values=True)
    for key, value in pairs:
        if key == "pin" and value:
            try:
                parse_pin(value)
            except ValueError as exc:
                state.say("pinned", f"URL: {exc}. No run is pinned.")
                kept = [(k, v) for k, v in pairs if k != "pin"]
                return "?" + urllib.parse.urlencode(kept) if kept else ""
    return search


class Pinner:
    """One session's pinned run: computed when the pin changes, never when B does."""

    def __init__(self, state: ExplorerState, jobs: Any, published: Callable[[], tuple | None]):
        self.state = state
        #: ``(params, run kwargs)`` of ``state.result``: a pin of that run reuses it.
        self.published = published
        self.page = PageRun(jobs, kind="pin")
        #: The last pin that ran, and its run: what a refused pin returns to.
        self.good: tuple[str, Any] = ("", None)
        self._busy = False
        self._watcher = state.param.watch(self._on_pin, "pinned")

    def _on_pin(self, event) -> None:
        if not self._busy:
            with HV_LOCK:  # the views redraw HoloViews plots from here
                self.pin(event.new)

    def pin(self, text: str) -> None:
        """Compute and publish the run of pin ``text`` as ``state.pinned_result`` (None for no
        pin); a pin that does not parse or cannot run is refused (see the module docstring)."""
        s = self.state
        self.page.cancel()
        if not text:
            self._publish("", None)
            return
        try:
            ps = pinned_state(text)
        except ValueError as exc:
            self._refuse(str(exc))
            return
        params, kwargs = rattle_params(ps), run_kwargs(ps)
        phys = run_physical(ps, params)
        # the live run is A only if its physical side is A's too (none, for a pin without one)
        if s.result is not None and self.published() == (params, kwargs) and s.result.phys == phys:
            self._publish(text, s.result)
            return
        s.pinned_result = None  # until A's run is in, nothing is drawn as A

        def done(out: tuple) -> None:
            tr, cls, ms = out
            self._publish(text, Run(params=params, tr=tr, cls=cls, phys=phys, phases=ps.phases,
                                    ms=ms))
        try:
            out = self.page.run(params, kwargs, done, self._refuse)
        except (ValueError, SolverError) as exc:
            self._refuse(str(exc))
            return
        if out is not None:
            done(out)

    def _publish(self, text: str, run: Any) -> None:
        self.good = (text, run)
        self.state.pinned_result = run
        self.state.clear("pinned")

    def _refuse(self, message: str) -> None:
        """A cannot be pinned: the last pin and its run come back, with a message."""
        text, run = self.good
        self._busy = True
        try:
            self.state.param.update(pinned=text, pinned_result=run)
        finally:
            self._busy = False
        self.state.say("pinned", f"Run A cannot be pinned: {message}. Kept the last pin.")

    def close(self) -> None:
        """The session closed: no more runs, no reference to the last one."""
        self.page.cancel()
        try:
            self.state.param.unwatch(self._watcher)
        except Exception:
            pass
        self.good = ("", None)
