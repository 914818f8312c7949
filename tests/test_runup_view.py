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
