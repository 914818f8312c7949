"""One browser session without its widgets: the state, its URL, its runs and its background jobs.

:class:`Session` owns the session's :class:`~app.state.ExplorerState` and keeps it
consistent. Every change of the state (from a widget, the URL, a preset, a click) arrives at
one watcher, which

1. carries it across the physical-units link (:func:`app.physical.link`),
2. simulates once and classifies, and publishes the result as ``state.result``, which
   every view draws from;
3. or, when the change cannot run, puts the last good values back, with a message beside
   the control at fault: a rejected value never reaches the views.

The URL is ``pn.state.location.sync`` of the state and of the Maps tab's settings
(:class:`~app.state.MapSettings`, which the session owns so that a link's map settings are in
force before the tab is built). A key whose value param refuses gets a message beside its
control and the URL shows the value kept; unknown keys and empty values get a message too.
The messages are plain text (the views escape them).

A pinned run (``state.pinned``, A) is run by :class:`app.pinning.Pinner`.

Background work goes through :class:`SessionJobs`: the server's job pool
(:mod:`app.work.jobs`), with results moved onto this session's document. :meth:`Session.destroy`
cancels the jobs and lets go of everything, so a closed session is garbage.
"""
from __future__ import annotations

import itertools
import logging
import math
import urllib.parse
import weakref
from typing import Any, Callable

import param

from rattle_core import SolverError

from .work import jobs as jobs_module
from .pinning import Pinner, drop_bad_pin
from .state import (GEARBOX_URL_KEYS, MAP_URL_KEYS, PHYSICAL_KEYS, RUN_KEYS, URL_KEYS,
                    ExplorerState, GearboxSettings, MapSettings,
                    Run, field_of_error, rattle_params)
from .physical import LinkError, link, run_physical
from .query import readable, rejection, serialize, update_query_as_written
from .work.page_run import TIME_LIMIT, PageRun, run_kwargs
from .work.threads import BUILD_LOCK, HV_LOCK, drawing

log = logging.getLogger(__name__)

#: Every live session (weakly held): a closed session must disappear from here.
LIVE: "weakref.WeakSet[Session]" = weakref.WeakSet()
_ids = itertools.count(1)
#: The message while a heavy run is computed in a worker process.
RUNNING = (f"Running this heavy view in the background (up to {TIME_LIMIT:g} s); a new change "
           "replaces it.")
#: Parameters a change of which is carried across the link and may need a new run.
WATCHED = tuple(dict.fromkeys((*RUN_KEYS, *PHYSICAL_KEYS, "units", "solve_for")))
class SessionJobs:
    """A session's handle on the job pool: one job per kind, callbacks run in its document."""

    def __init__(self, key: int, doc: Any = None, pool: Any = None):
        self.key, self.doc, self._pool = key, doc, pool
        self._closed = False

    @property
    def pool(self):
        if self._pool is None:
            self._pool = jobs_module.pool()
        return self._pool

    def submit(self, kind: str, fn: Callable, args: tuple = (), kwargs: dict | None = None, *,
               time_limit: float = 60.0, on_progress: Callable | None = None,
               on_done: Callable | None = None, on_error: Callable | None = None):
        """Run ``fn`` in the background as this session's ``kind`` job (replacing the last)."""
        if self._closed:
            raise RuntimeError("the session is closed")
        wrap = self._in_doc
        return self.pool.submit((self.key, kind), fn, args, kwargs, time_limit=time_limit,
                                on_progress=wrap(on_progress), on_done=wrap(on_done),
                                on_error=wrap(on_error))

    def _in_doc(self, fn: Callable | None) -> Callable | None:
        """``fn`` to be run in this session's document (directly when there is none)."""
        if fn is None:
            return None
        ref = weakref.ref(self)

        def call(arg: Any) -> None:
            me = ref()
            if me is None or me._closed:
                return
            doc = me.doc
            if doc is None or doc.session_context is None:
                # a refresh holds this lock from its change to its message; a job that ends
                # meanwhile must wait, or the refresh would clear the job's own message. With
                # no document to lock, the page's build is waited for too
                with BUILD_LOCK, HV_LOCK:
                    fn(arg)
                return
            from panel.io.state import set_curdoc

            def tick() -> None:
                with set_curdoc(doc), HV_LOCK:
                    try:
                        fn(arg)
                    except Exception as exc:  # a failed update stays in this session's log line
                        log.warning("background update failed: %s: %s", type(exc).__name__, exc)
            try:
                doc.add_next_tick_callback(tick)
            except Exception:
                pass  # the session closed while the job ran
        return call

    def close(self) -> None:
        """Cancel every job of this session; later results are dropped."""
        self._closed = True
        if self._pool is not None:
            self._pool.cancel_session(self.key)
        self.doc = None


class Session:
    """One session's state, kept consistent and in the URL; see the module docstring."""

    def __init__(self, location: Any = None, doc: Any = None, pool: Any = None):
        self.key = next(_ids)
        self.state = ExplorerState()
        #: The Maps tab's request, in the URL beside the state.
        self.map_settings = MapSettings()
        #: The Gearbox tab's settings, in the URL too.
        self.gearbox_settings = GearboxSettings()
        #: What the URL carries: each synced object with its parameter → key names.
        self.synced = ((self.state, URL_KEYS), (self.map_settings, MAP_URL_KEYS),
                       (self.gearbox_settings, GEARBOX_URL_KEYS))
        self.jobs = SessionJobs(self.key, doc, pool)
        self.page = PageRun(self.jobs)
        #: ``(params, run kwargs)`` of ``state.result``: a pin of the same run reuses it.
        self._request: tuple | None = None
        self.pinner = Pinner(self.state, self.jobs, lambda: self._request)
        self.location = location
        self.last_ms = math.nan
        #: How many simulations this session has run (one per accepted change).
        self.runs = 0
        self._busy = False
        self._good = self._snapshot()
        self._watcher = self.state.param.watch(self._on_change, list(WATCHED))
        self._search_watcher = None
        if location is not None:
            self._sync_url(location)
        if self.state.result is None:
            self.refresh(set())
        LIVE.add(self)

    # ----- the update path --------------------------------------------------------------------

    def _snapshot(self) -> dict[str, Any]:
        return {k: getattr(self.state, k) for k in WATCHED}

    def _on_change(self, *events) -> None:
        if self._busy:
            return
        self.refresh({e.name for e in events})

    def refresh(self, names: set[str], physical_wins: bool = False) -> bool:
        """Carry a change of ``names`` across the link, run, publish; False if it was refused."""
        if self._busy:
            return False
        # the views redraw HoloViews plots from here; a page being built meanwhile pauses
        with drawing(), HV_LOCK:
            return self._refresh(names, physical_wins)

    def _refresh(self, names: set[str], physical_wins: bool) -> bool:
        self._busy = True
        s = self.state
        try:
            try:
                values, warning = link(s, names, physical_wins)
                if values:
                    s.param.update(**values)
            except (LinkError, ValueError) as exc:
                where = getattr(exc, "name", None) or next((n for n in PHYSICAL_KEYS if n in names), "units")
                s.say(where, f"{exc}. Kept the last good values.")
                self._revert()
                return False
            if warning:
                s.say("solve_for", warning)
            elif "solve_for" in s.messages and names & {"lam", "j", "h2", "phi2", "solve_for", "units"}:
                s.clear("solve_for")
            if not (values or names & set(RUN_KEYS) or "units" in names or s.result is None):
                self._good = self._snapshot()
                s.clear(*names)
                return True
            for _ in range(len(WATCHED)):
                failed = self._run(names)
                if failed is None:
                    break
                # put back the value at fault only, so one bad value does not cost the others
                moved = [k for k, v in self._good.items() if getattr(s, k) != v]
                if failed in moved and len(moved) > 1:
                    self._put({failed: self._good[failed]})
                    continue
                self._revert()
                return False
            self._good = self._snapshot()
            s.clear(*names, "global")
            if self.page.pending is not None:
                s.say("global", RUNNING)
            return True
        finally:
            self._busy = False

    def _run(self, names: set[str]) -> str | None:
        """Simulate the state within the page's budget (:mod:`app.work.page_run`: here, or in a
        worker when heavy) and publish the run; or the parameter at fault (``global``)."""
        s = self.state
        before = dict(self._good)
        try:
            params, kwargs = rattle_params(s), run_kwargs(s)
            out = self.page.run(params, kwargs, lambda o: self._ran(params, *o, request=kwargs),
                                lambda message: self._failed(before, message))
        except (ValueError, SolverError) as exc:
            field = field_of_error(str(exc)) if isinstance(exc, ValueError) else None
            where = field or next((n for n in RUN_KEYS if n in names), "global")
            s.say(where, f"{exc}. Showing the last good view.")
            return where
        if out is not None:
            self._ran(params, *out, request=kwargs)
        return None

    def _ran(self, params: Any, tr: Any, cls: Any, ms: float, request: dict | None = None) -> None:
        """Publish a run: every view draws from ``state.result``."""
        s = self.state
        self.runs += 1
        self.last_ms = ms
        self._request = (params, request)
        s.result = Run(params=params, tr=tr, cls=cls, phys=run_physical(s, params), phases=s.phases,
                       ms=ms)
        if s.messages.get("global") == RUNNING:
            s.clear("global")

    def _failed(self, before: dict[str, Any], message: str) -> None:
        """A run in a worker failed (its time limit, the solver's limits): the last good values."""
        self._good = before
        self._revert()
        self.state.say("global", f"{message}. Showing the last good view.")

    def _revert(self) -> None:
        """Put the last good values back (without a new run)."""
        self._put({k: v for k, v in self._good.items() if getattr(self.state, k) != v})

    def _put(self, values: dict[str, Any]) -> None:
        if values:
            busy, self._busy = self._busy, True
            try:
                self.state.param.update(**values)
            finally:
                self._busy = busy

    # ----- the URL ----------------------------------------------------------------------------

    def _sync_url(self, location: Any) -> None:
        def on_error(obj: Any, keys: dict[str, str]) -> Callable:
            def apply(values: dict[str, Any]) -> None:
                # the location applies a batch at once: apply the values param accepts, as one
                # batch again (so the physical inputs of a link still win), and say which it
                # refused
                good = {}
                for name, value in values.items():
                    try:
                        obj.param[name]._validate(value)
                        good[name] = value
                    except ValueError:
                        obj.say(name, "URL: " + rejection(obj, name, value))
                obj.param.update(**good)
                rejected = [n for n in values if n not in good]
                if rejected:
                    location.update_query(**{keys[n]: serialize(obj, n) for n in rejected})
            return apply

        # Panel's update_query reads the whole link back as Python values and writes them out
        # again, so one slider move turned every present=true into present=True: keep the text
        # of the keys it does not change
        location.update_query = lambda **values: update_query_as_written(location, values)
        clean, unreadable = readable(location.search)
        pinless = drop_bad_pin(clean, self.state)
        if unreadable or pinless != clean:  # before Panel reads the link: such a value would fail the whole page
            location.search = pinless
        link = location.search
        self._check_query(link)
        for key, why in unreadable.items():
            obj, name = self._owner(key)
            from .ui.labels import short
            obj.say(name, f"URL: the value of {short(key)} cannot be read ({why}); ignored.")
        for obj, keys in self.synced:
            location.sync(obj, keys, on_error=on_error(obj, keys))
        # the URL shows the state in force: rejected and reverted values corrected, unknown
        # keys dropped
        location.search = "?" + urllib.parse.urlencode(
            {key: serialize(obj, name) for obj, keys in self.synced for name, key in keys.items()})
        self._physical_wins(link)
        self._search_watcher = location.param.watch(self._on_search, "search")

    def _owner(self, key: str) -> tuple[Any, str]:
        """The synced object and parameter a URL key belongs to (the state's ``url`` if none)."""
        for obj, keys in self.synced:
            for name, k in keys.items():
                if k == key:
                    return obj, name
        return self.state, "url"

    def _on_search(self, event) -> None:
        # the browser reports the link again once connected, and Panel applies its dimensionless
        # keys first: the physical inputs it holds must win again
        if not self._busy:
            self._physical_wins(event.new)
            self._show_state_in_url(event.new)

    def _show_state_in_url(self, search: str) -> None:
        """Correct URL keys whose value is not the one in force (refused, or put back)."""
        from .query import parse_query
        query, fix = parse_query(search or ""), {}
        for obj, keys in self.synced:
            for name, key in keys.items():
                if key in query:
                    try:
                        same = obj.param[name].deserialize(query[key]) == getattr(obj, name)
                    except Exception:
                        same = False
                    if not same and not (query[key] == "" and getattr(obj, name) is None):
                        fix[key] = serialize(obj, name)
        known = {k for _, keys in self.synced for k in keys.values()}
        unknown = [k for k in query if k not in known]
        if unknown:  # dropped: the URL says what is in force, nothing else
            kept = {k: v for k, v in urllib.parse.parse_qsl((search or "")[1:]) if k not in unknown}
            merged = {**kept, **fix}
            self.location.search = "?" + urllib.parse.urlencode(merged) if merged else ""
        elif fix:
            self.location.update_query(**fix)

    def _physical_wins(self, search: str) -> None:
        """A link holding physical inputs: they decide Λ, j, h₂, φ₂ while the mode is on."""
        from .query import parse_query
        s, query = self.state, parse_query(search or "")
        if not any(URL_KEYS[n] in query for n in PHYSICAL_KEYS):
            return
        diff = {}
        for n in ("units", *PHYSICAL_KEYS):
            if URL_KEYS[n] in query:
                value = s.param[n].deserialize(query[URL_KEYS[n]])
                try:
                    s.param[n]._validate(value)
                except ValueError:
                    continue  # refused when the link was first applied, with its message
                if value != getattr(s, n):
                    diff[n] = value
        if diff:
            busy, self._busy = self._busy, True
            try:
                s.param.update(**diff)
            finally:
                self._busy = busy
        if s.units:
            self.refresh(set(diff), physical_wins=True)

    def _check_query(self, search: str) -> None:
        """Messages for the link's unknown keys and empty values (which are not applied)."""
        s = self.state
        pairs = urllib.parse.parse_qsl((search or "")[1:], keep_blank_values=True)
        unknown = [k for k, _ in pairs if self._owner(k)[1] == "url"]
        if unknown:
            from .ui.labels import short
            s.say("url", f"URL: unknown key{'s' if len(unknown) > 1 else ''} "
                            f"{', '.join(short(k) for k in unknown[:5])} ignored.")
        for key, value in pairs:
            obj, name = self._owner(key)
            if (name != "url" and value == "" and name not in ("x0", "cont_from", "curve_at")
                    and getattr(obj, name) != ""):
                obj.say(name, f"URL: {obj.param[name].label} is empty. Kept {serialize(obj, name)}.")

    # ----- teardown -----------------------------------------------------------------------------

    def destroy(self) -> None:
        """The session closed: cancel its jobs and drop every reference to its results."""
        self.jobs.close()
        self.pinner.close()
        try:
            self.state.param.unwatch(self._watcher)
        except Exception:
            pass
        if self.location is not None:
            if self._search_watcher is not None:
                self.location.param.unwatch(self._search_watcher)
            for obj, _ in self.synced:
                try:
                    self.location.unsync(obj)
                except Exception:
                    pass
            self.location = None
        with param.parameterized.discard_events(self.state):  # no view redraws a closed page
            self.state.result = None
            self.state.pinned_result = None
