"""The twin trajectory: chaos pulls a twin started 1e-6 away apart, a periodic orbit pulls it in.

Driven on a dashboard built without a server (the ``dash`` fixture); the claims are the
paper's: Fig 7 is a strange attractor (positive Lyapunov exponent), Fig 8 a stable periodic
orbit with one impact per flank.
"""
from __future__ import annotations

import numpy as np
import pytest

from app.presets import PRESETS, preset_values
from app.views.explorer import start_from_section
from app.views.sensitivity import PERIODS, twin_runs
from rattle_core import simulate


def test_chaos_pulls_the_twin_apart_at_the_runs_lyapunov_rate(dash):
    """Fig 7: the twin, nudged by 1e-6, ends at least 1e3 times farther; its early growth rate
    is within a factor of three of the run's Lyapunov exponent."""
    s = dash.state
    s.param.update(**preset_values(s, "Fig 7"))
    s.twin = True
    d = dash.sensitivity.data
    assert d is not None and d["distance"][0] == pytest.approx(1e-6, rel=1e-9)
    assert np.median(d["distance"][-100:]) > 1e3 * d["distance"][0]
    lam = s.result.cls.lyapunov
    assert lam > 0
    # the growth over the periods before the gap saturates (at most 1e-2)
    grow = d["distance"] < 1e-2
    last = int(np.argmin(grow)) if not grow.all() else len(grow) - 1
    rate = np.log(d["distance"][last] / d["distance"][0]) / (d["t"][last] * 2 * np.pi)
    assert lam / 3 < rate < 3 * lam, (rate, lam)
    assert "Chaos" in dash.sensitivity.text.object


def test_a_periodic_orbit_pulls_the_twin_in(dash):
    """Fig 8 (regime E): the twin, nudged by 1e-6, ends closer than it started."""
    s = dash.state
    s.param.update(**preset_values(s, "Fig 8"))
    s.twin = True
    d = dash.sensitivity.data
    assert s.result.cls.regime == "E"
    assert d["distance"][-1] < 1e-2 * d["distance"][0]
    assert "periodic orbit" in dash.sensitivity.text.object


def test_the_twin_is_two_exact_runs_and_a_second_click_places_it(dash):
    """The drawn gears are the core's runs from the two starts; with the twin on, a second click
    on the map sets the twin's start, and a start outside the backlash is refused by name."""
    s = dash.state
    s.param.update(**PRESETS["Fig 3E"][1])
    assert start_from_section(s, 4.0, 0.5)  # the first gear
    s.twin = True
    assert start_from_section(s, 4.1, 0.5) and (s.twin_x0, s.twin_v0) == (4.1, 0.5)
    d = twin_runs(s)
    t = s.t0 + d["t"] * 2 * np.pi
    for key, x0 in (("a", 4.0), ("b", 4.1)):
        tr = simulate(s.result.params, periods=PERIODS, x0=x0, v0=0.5, t0=s.t0, transient=0)
        np.testing.assert_allclose(d[key][0], tr.sample(t)[0], rtol=0, atol=1e-12)
    s.twin_x0 = 50.0
    assert "twin" in s.messages and "x0" in s.messages["twin"]


def test_turning_the_twin_on_after_the_page_is_drawn_frames_both_plots_on_their_data(dash):
    """The page drawn with the twin off (both plots empty, on [0, 1]); ticking it then gives
    each plot ranges that cover its curves (times 0…40 periods, x over the backlash, the
    separation on its log scale), and the slope's legend is plain text without braces."""
    from bokeh.document import Document
    from bokeh.models import Legend, Plot

    from conftest import wait_for

    s = dash.state
    s.param.update(**preset_values(s, "Fig 7"))
    wait_for(lambda: s.result is not None and s.result.cls.lyapunov > 0, 120, "Fig 7's run")
    assert not s.twin
    root = dash.sensitivity.__panel__().get_root(Document())
    s.twin = True
    d = dash.sensitivity.data
    figs = {f.title.text: f for f in root.select({"type": Plot})}
    paths, gap = figs["Both gears, x(t)"], figs["Separation in (x, ẋ), log scale"]
    for fig in (paths, gap):
        assert fig.x_range.start <= 0 and fig.x_range.end >= PERIODS, fig.x_range
    x = np.concatenate([d["a"][0], d["b"][0]])
    assert paths.y_range.start <= x.min() and paths.y_range.end >= x.max()
    assert paths.y_range.end - paths.y_range.start < 3 * (x.max() - x.min())
    assert gap.y_range.start <= d["distance"].min() and gap.y_range.end >= d["distance"].max()
    labels = [item.label["value"] for legend in gap.select({"type": Legend})
              for item in legend.items]
    assert any("λt" in text for text in labels) and not any("{" in t for t in labels), labels
