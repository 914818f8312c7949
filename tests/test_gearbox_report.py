"""The Gearbox tab's HTML report can be handed on: it names the measurement file and carries
its SHA-256, the date, the version and the settings, the regime legend in words, units on every
column, the target with its failing ranges, and it escapes what users typed."""
from __future__ import annotations

import hashlib
import re

import pytest

from app.work import gearbox as work
from rattle_core.analysis.vocabulary import REGIMES
from rattle_core.model.gearbox import Gearbox
from rattle_core.model.target import Target
from rattle_core.store.verdicts import cached_verdict

pytestmark = pytest.mark.timeout(600)

TOML = """
[excitation]
measurement = "sample"
engine_order = 2
harmonics = 3

[sound]
duration_s = 0.2

[[gear]]
name = "<script>alert(1)</script>"
inertia_kgm2 = 4e-4
base_radius_m = 0.035
drag_torque_Nm = 0.05
backlash_um = 80
"""


@pytest.fixture(scope="module")
def verdicts(tmp_path_factory):
    box = Gearbox.from_text(TOML)
    cache = tmp_path_factory.mktemp("cache")
    run = dict(transient=60, record=30, ensemble_runs=0, directory=cache,
               target=Target.parse("1000:0.1,3000:0.1 sone"))
    a = cached_verdict(box, [1000.0, 2000.0, 3000.0], **run)
    stiffer = box.replace(gears=tuple(g.replace(drag_torque_Nm=0.2) for g in box.gears))
    b = cached_verdict(stiffer, [1000.0, 2000.0, 3000.0], **run)
    return a, b


def test_report_carries_hash_legend_units_and_escapes(verdicts):
    """The measurement's name and SHA-256, an ISO 8601 UTC date, the version, every regime's
    letter with its meaning, units in the table's headers, the target's failing ranges; the gear
    name and the file name appear only escaped."""
    a, b = verdicts
    data = b"time_s,speed_rpm\n0,1000\n"
    ident = work.file_identity(data)
    assert ident["sha256"] == hashlib.sha256(data).hexdigest()
    page = work.report_html(a, b, "drag 0.2 N·m",
                            {"file": "<b>run&up.csv</b>", "sha256": ident["sha256"]})
    assert ident["sha256"] in page
    assert "&lt;b&gt;run&amp;up.csv&lt;/b&gt;" in page and "<b>run&up.csv</b>" not in page
    assert "<script>alert(1)</script>" not in page and "&lt;script&gt;alert(1)&lt;/script&gt;" in page
    assert re.search(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\+00:00", page)
    assert "rattle-explorer version" in page
    legend = page.split("class='legend'>")[1].split("</table>")[0]
    for r in REGIMES:
        assert f"<td><b>{r.letter}</b></td><td>{r.meaning}</td>" in legend
    headers = re.findall(r"<th>([^<]*)</th>", page.split("<h2>Table</h2>")[1])
    assert headers and all(re.search(r"\[[^\]]+\]$", h) for h in headers), headers
    assert "loudness_sone [sone]" in headers and "margin_sone [sone]" in headers
    assert "<h2>Target</h2>" in page and "1000:0.1,3000:0.1 sone" in page
    assert "B - A" in page and page.count("data:image/png;base64,") >= 4


def test_sample_identity_is_the_shipped_file():
    """Without an upload the hash is that of the shipped sample run-up's bytes."""
    from rattle_core.measure.orders import SAMPLE_RUNUP
    with open(SAMPLE_RUNUP, "rb") as f:
        assert work.file_identity(None)["sha256"] == hashlib.sha256(f.read()).hexdigest()
