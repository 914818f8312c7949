"""A view's background job as the page shows it: a progress bar, a Cancel button, a status line.

:class:`JobPanel` runs one kind of session job at a time for a view. Each request carries a
key; callbacks of a job whose key is no longer the panel's (a newer request, a cancel) are
dropped, so a late result never overwrites a newer one.
"""
from __future__ import annotations

import html
from typing import Any, Callable

import panel as pn


def status_html(text: str) -> str:
    """A status line, escaped."""
    return f'<div style="font-size:12px;color:#444">{html.escape(text)}</div>' if text else ""


class JobPanel:
    """One view's job of one kind (``jobs`` is the session's): its widgets and its key."""

    def __init__(self, jobs: Any, kind: str, css: str):
        self.jobs, self.kind = jobs, kind
        self.key: Any = None
        self.job: Any = None
        self.cancel_button = pn.widgets.Button(label="Cancel", disabled=True, width=80,
                                               css_classes=[f"{css}-cancel"])
        self.progress = pn.indicators.Progress(value=0, max=100, visible=False, bar_color="info",
                                               height=14, sizing_mode="stretch_width",
                                               css_classes=[f"{css}-progress"])
        self.status = pn.pane.HTML("", css_classes=[f"{css}-status"], sizing_mode="stretch_width")

    def say(self, text: str | None) -> None:
        self.status.object = status_html(text or "")

    def submit(self, key: Any, fn: Callable, args: tuple, text: str, time_limit: float,
               on_done: Callable[[Any], None], on_error: Callable[[str], None]) -> None:
        """Run ``fn(*args)`` as the session's job of this kind, for request ``key``."""
        self.key = key
        self.say(text)
        self.progress.param.update(value=0, visible=True)
        try:
            self.job = self.jobs.submit(
                self.kind, fn, args, time_limit=time_limit,
                on_progress=lambda f: self._progress(key, f),
                on_done=lambda out: self._finish(key, on_done, out),
                on_error=lambda msg: self._fail(key, on_error, msg))
        except RuntimeError as exc:
            self._fail(key, on_error, str(exc))
            return
        self.cancel_button.disabled = False

    def _progress(self, key: Any, fraction: float) -> None:
        if key == self.key:
            self.progress.value = int(100 * fraction)

    def _finish(self, key: Any, fn: Callable, out: Any) -> None:
        if key == self.key:
            self.finished()
            fn(out)

    def _fail(self, key: Any, fn: Callable, msg: str) -> None:
        if key == self.key:
            self.finished()
            self.key = None
            self.say("")
            fn(msg)

    def finished(self) -> None:
        self.job = None
        self.progress.visible = False
        self.cancel_button.disabled = True

    def stop(self, text: str | None = None) -> None:
        """Cancel the running job and forget its request."""
        if self.job is not None:
            self.job.cancel()
        self.finished()
        self.key = None
        self.say(text)
