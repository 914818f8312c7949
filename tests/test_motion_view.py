"""The gear in motion without a browser: the frames sent to the page and the teeth drawn from them.

The frames are checked against the trajectory itself (``Trajectory.sample`` and
``Trajectory.walls`` at the frame times, every impact instant among them), against the model's
constraint ``y ≤ x ≤ y + j`` and, in physical units, against the unit conversion; the teeth's
polygons against the gaps they must show.
"""
from __future__ import annotations

import numpy as np
import pytest

from app.presets import PRESETS
from app.views.motion import IDLE_V, DRIVING_V, motion_frames, teeth_xs, tooth_size


def flank_at(xs, vs, i0, i1, v):
    """Abscissa at height ``v`` of the straight flank through vertices ``i0`` and ``i1``."""
    s = (v - vs[i0]) / (vs[i1] - vs[i0])
    return xs[i0] + s * (xs[i1] - xs[i0])


@pytest.mark.parametrize("preset", ["Fig 7", "Fig 3B", "Fig 3E"])
def test_frames_are_exact_samples_holding_every_impact_and_stay_between_the_teeth(dash, preset):
    """Chaos, sticking and regime E: frame x equals Trajectory.sample, each impact is a frame
    with x on its flank, and y ≤ x ≤ y + j at every frame."""
    s = dash.state
    s.param.update(**PRESETS[preset][1])
    tr = s.result.tr
    data = motion_frames(tr, s.shown)
    f, imp = data["frames"], data["impacts"]
    t_end = tr.t_start + 2 * np.pi * min(s.shown, int(tr.periods))
    assert f["t"][0] == tr.t_start and f["t"][-1] == pytest.approx(t_end)
    assert np.all(np.diff(f["t"]) > 0)
    x, _ = tr.sample(f["t"])
    y, yj = tr.walls(f["t"])
    np.testing.assert_array_equal(f["x"], x)
    np.testing.assert_array_equal(f["y"], y)
    j = tr.params.j
    assert data["meta"]["j"][0] == pytest.approx(j, rel=1e-12)
    assert np.min(f["x"] - f["y"]) >= -1e-9 and np.min(f["y"] + j - f["x"]) >= -1e-9
    want = tr.impact_t[(tr.impact_t >= tr.t_start) & (tr.impact_t <= t_end)]
    np.testing.assert_array_equal(imp["t"], want)
    at = np.searchsorted(f["t"], want)
    np.testing.assert_array_equal(f["t"][at], want)
    gap = np.where(imp["flank"] > 0, f["x"][at] - f["y"][at], f["y"][at] + j - f["x"][at])
    assert np.max(np.abs(gap)) <= 1e-9
    assert data["meta"]["rate"][0] == pytest.approx(2 * np.pi)  # one period per second at 1×


def test_physical_frames_are_in_ms_and_micrometres_played_at_real_time(dash):
    """Units mode: frame times are 10³·(t − t_start)/ω ms, positions 10⁶·H₁·x µm, 1× = 1000 ms/s."""
    s = dash.state
    s.units = True
    run = s.result
    tr, ph = run.tr, run.phys
    data = motion_frames(tr, s.shown, ph)
    f = data["frames"]
    t = tr.t_start + np.asarray(f["t"]) * 1e-3 * ph.omega
    np.testing.assert_allclose(f["x"], 1e6 * ph.position(tr.sample(t)[0]), rtol=1e-9, atol=1e-9)
    assert data["meta"]["rate"][0] == 1000.0 and data["meta"]["real"][0] == 1
    assert data["meta"]["period"][0] == pytest.approx(1e3 / ph.frequency_hz, rel=1e-12)
    assert data["meta"]["j"][0] == pytest.approx(1e6 * ph.position(tr.params.j), rel=1e-9)
    assert data["labels"][0] == "t [ms]"


def test_teeth_show_the_models_gaps_at_every_height():
    """Facing flanks are parallel: the drawn gaps are x − y and y + j − x at every height of
    the overlap, and the teeth are as thick as tooth_size says on the pitch line."""
    x, y, j = 1.7, -0.4, 8.0
    d, _ = tooth_size(j)
    drv, idle, opp = teeth_xs(x, y, j)
    for v in np.linspace(0.2, 0.8, 7):
        right_drv = flank_at(drv, DRIVING_V, 1, 2, v)
        left_idle = flank_at(idle, IDLE_V, 0, 3, v)
        right_idle = flank_at(idle, IDLE_V, 1, 2, v)
        left_opp = flank_at(opp, DRIVING_V, 0, 3, v)
        assert left_idle - right_drv == pytest.approx(x - y, abs=1e-12)
        assert left_opp - right_idle == pytest.approx(y + j - x, abs=1e-12)
    assert flank_at(drv, DRIVING_V, 1, 2, 0.5) == pytest.approx(y)
    assert flank_at(idle, IDLE_V, 1, 2, 0.5) - flank_at(idle, IDLE_V, 0, 3, 0.5) == pytest.approx(d)
    assert flank_at(opp, DRIVING_V, 0, 3, 0.5) == pytest.approx(y + j + d)


def test_the_page_gets_the_current_runs_frames_and_its_first_frames_teeth(dash):
    """The view's sources hold the run's frames, impacts and the teeth at the window's start."""
    s = dash.state
    s.param.update(**PRESETS["Fig 3E"][1])
    src = dash.motion.parts
    tr = s.result.tr
    want = motion_frames(tr, s.shown)
    np.testing.assert_array_equal(src["frames"].data["t"], want["frames"]["t"])
    np.testing.assert_array_equal(src["impacts"].data["t"], want["impacts"]["t"])
    x0, y0 = tr.sample([tr.t_start])[0][0], tr.walls([tr.t_start])[0][0]
    np.testing.assert_allclose(src["teeth"].data["xs"], teeth_xs(x0, y0, tr.params.j))
    fig = src["figure"]
    drawn = np.asarray(src["teeth"].data["xs"])
    assert fig.x_range.start < drawn.min() and drawn.max() < fig.x_range.end
