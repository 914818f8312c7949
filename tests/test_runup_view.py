"""Replay the run-up under the Gearbox tab, without a browser: a short run of a 2-gear box in
the background, its plots and intervals table against gearbox_runup's own, the sound scaled
for playback, the onsets set against the verdict, the disk cache, Cancel, and bad input
refused with the range."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from conftest import wait_for

pytestmark = pytest.mark.timeout(900)


@pytest.fixture()
def views(dash, tmp_path, monkeypatch):
    monkeypatch.setenv("RATTLE_CACHE_DIR", str(tmp_path))
    gb, ru = dash.gearbox, dash.runup
    gb.settings.param.update(rpm_num=5, transient=80, record=30)
    gb.table.value = gb.table.value.iloc[:2].reset_index(drop=True)
    gb.measure(None)
    wait_for(lambda: gb.order_map is not None, 120, "the sample's orders")
    return gb, ru


def test_a_short_replay_shows_the_runs_data_and_the_verdict(views):
    """The replay's loudness plot holds the run's N(t) and L_AF(t) against its rpm, the
    intervals table is gearbox_runup's, the sound is the run's length at a peak of 0.99, the
    onsets are the run's beside the verdict's, and the same request again comes from the disk
    cache."""
    from rattle_core.batch.runup import gearbox_runup
    gb, ru = views
    assert gb.run()
    wait_for(lambda: gb.revision == 1, 300, "the verdict")
    ru.rpm_from.value, ru.rpm_to.value, ru.duration.value = 1500.0, 2500.0, 2.0
    assert ru.run()
    wait_for(lambda: ru.revision == 1 or "gearbox-runup" in ru.state.messages, 600, "the replay")
    assert "gearbox-runup" not in ru.state.messages, ru.state.messages["gearbox-runup"]
    ref = gearbox_runup(gb.with_settings(gb.gearbox()), 1500.0, 2500.0, 2.0)
    pd.testing.assert_frame_equal(ru.intervals.reset_index(drop=True), ref.intervals,
                                  check_dtype=False, rtol=1e-12)
    assert set(ru.intervals["gear"]) <= {"5th idler", "reverse idler"} and len(ru.intervals) >= 1
    d = ru.run_src.data
    np.testing.assert_allclose(d["rpm"], ref.rpm_t, rtol=1e-12)
    np.testing.assert_allclose(d["sone"], ref.loudness_t, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(d["dba"], ref.level_dba_t, rtol=1e-9)
    assert list(ru.intervals_src.data["gear"]) == list(ref.intervals["gear"])
    np.testing.assert_allclose(ru.intervals_src.data["start_rpm"], ref.intervals["start_rpm"])
    sig = np.asarray(ru.audio.object)
    assert sig.size == 2 * 48_000 and abs(np.max(np.abs(sig)) - 0.99) < 1e-6
    assert ru.meta_src.data == {"rpm_from": [1500.0], "rpm_to": [2500.0], "duration": [2.0]}
    assert ru.onsets is not None and list(ru.onsets["gear"]) == ["5th idler", "reverse idler"]
    for name, onset in ref.onsets.items():
        row = ru.onsets[ru.onsets["gear"] == name].iloc[0]
        assert row["onset_run_rpm"] == pytest.approx(onset, rel=1e-12, nan_ok=True)
        assert row["onset_verdict_rpm"] == pytest.approx(gb.base.onsets[name], nan_ok=True)
    assert "verdict" in ru.text.object and "5th idler" in ru.text.object
    v = gb.base.gear("gearbox")
    np.testing.assert_allclose(ru.verdict_src.data["sone"], v["loudness_sone"].to_numpy(float))
    assert ru.run()
    wait_for(lambda: ru.revision == 2, 120, "the replay again")
    assert "from the disk cache" in ru.panel.status.object


def test_bad_input_is_refused_with_the_range_and_cancel_drops_the_run(views):
    """A speed outside the measurement names the measured range, a duration outside its range
    names it, equal speeds are refused, and nothing starts; Cancel drops a running replay."""
    gb, ru = views
    lo, hi = gb.order_map.rpm_range
    ru.rpm_from.value = 100.0
    assert not ru.run() and ru.job is None
    msg = ru.state.messages["gearbox-runup"]
    assert "rpm_from = 100" in msg and f"[{lo:g}, {hi:g}]" in msg
    ru.rpm_from.value, ru.duration.value = 1500.0, 0.0
    assert not ru.run()
    assert "duration" in ru.state.messages["gearbox-runup"] and "[0.1, 120]" in \
        ru.state.messages["gearbox-runup"]
    ru.rpm_to.value, ru.duration.value = 1500.0, 2.0
    assert not ru.run() and "must differ" in ru.state.messages["gearbox-runup"]
    ru.rpm_to.value, ru.duration.value = 2500.0, 60.0
    assert ru.run() and "gearbox-runup" not in ru.state.messages
    job = ru.job
    ru.cancel("Replay cancelled.")
    assert job.cancelled and ru.job is None and not ru.panel.progress.visible
    assert "Replay cancelled." in ru.panel.status.object and ru.revision == 0


def test_the_measured_angle_drives_a_replay_of_the_measurements_own_stretch(views):
    """With the measured angle chosen, the cutoff is shown and the duration disabled; the
    replay of the sample measurement runs in the background from the samples the session
    kept, and gives the same impacts and intervals as gearbox_runup driven by measured_angle()
    read from the file itself (as the CLI's --wall angle does), over the stretch of the
    measurement between the two speeds."""
    from rattle_core.batch.runup import gearbox_runup, measured_angle
    from rattle_core.measure.orders import SAMPLE_RUNUP
    from rattle_core.solver.runup import measured_window
    gb, ru = views
    assert not ru.cutoff.visible and not ru.duration.disabled
    ru.wall.value = "angle"
    assert ru.cutoff.visible and ru.duration.disabled
    assert "measurement's own" in ru.duration.label
    ru.rpm_from.value, ru.rpm_to.value, ru.cutoff.value = 1900.0, 2150.0, 400.0
    ru.duration.value = 0.0  # not used by the measured angle's run
    assert ru.run(), ru.state.messages.get("gearbox-runup")
    wait_for(lambda: ru.revision == 1 or "gearbox-runup" in ru.state.messages, 600, "the replay")
    assert "gearbox-runup" not in ru.state.messages, ru.state.messages["gearbox-runup"]
    box = gb.with_settings(gb.gearbox())
    angle = measured_angle(SAMPLE_RUNUP, 400.0, box.excitation.engine_order)
    a, b = measured_window(angle, 1900.0, 2150.0)
    ref = gearbox_runup(box, 1900.0, 2150.0, None, angle=angle, sound=False)
    assert ru.result["wall"] == "angle" and ru.result["cutoff_hz"] == 400.0
    assert ru.result["duration_s"] == pytest.approx(b - a, rel=1e-12)
    assert sum(ru.result["impacts_per_gear"].values()) == len(ref.impacts) > 0
    pd.testing.assert_frame_equal(ru.intervals.reset_index(drop=True), ref.intervals,
                                  check_dtype=False, rtol=1e-12)
    np.testing.assert_allclose(ru.run_src.data["rpm"], angle.mean_rpm(a + ru.result["time_s"]),
                               rtol=1e-12)
    assert np.asarray(ru.audio.object).size == round((b - a) * 48_000)
    assert "measured angle filtered at 400 Hz" in ru.panel.status.object


def test_a_bad_cutoff_or_speed_for_the_measured_angle_is_refused_beside_the_card(views):
    """Bad input with the measured angle: a cutoff above the sampling's Nyquist frequency, at
    0 or NaN names cutoff_hz and its range (0, f_s/2); a speed the measured stretch never
    reaches names the measured range; a run-down asked of the measured run-up is refused; and
    none of them starts a job."""
    from rattle_core.measure.sampling import regularise
    gb, ru = views
    t, w, _ = gb.measurement.samples
    t, _, _, _ = regularise(t, w, str, None)
    nyquist = 0.5 / float(np.median(np.diff(t)))
    ru.wall.value = "angle"
    ru.rpm_from.value, ru.rpm_to.value = 1900.0, 2150.0
    for cutoff, said in ((5000.0, "cutoff_hz = 5000.0 is outside"), (0.0, "cutoff_hz = 0.0"),
                         (float("nan"), "cutoff_hz must be finite")):
        ru.cutoff.value = cutoff
        assert not ru.run() and ru.job is None
        msg = ru.state.messages["gearbox-runup"]
        assert said in msg and f"(0, {nyquist:g})" in msg, msg
    ru.cutoff.value, ru.rpm_to.value = 400.0, 3500.0
    assert not ru.run() and ru.job is None
    assert "rpm_to = 3500.0 is outside the measurement's speed range" in \
        ru.state.messages["gearbox-runup"]
    ru.rpm_to.value, ru.rundown.value = 2150.0, True
    assert not ru.run() and ru.job is None
    assert "the run-down: rpm_to = 1900.0 is not reached" in ru.state.messages["gearbox-runup"]
    ru.rundown.value = False
    assert ru.run() and "gearbox-runup" not in ru.state.messages
    ru.cancel("Replay cancelled.")
