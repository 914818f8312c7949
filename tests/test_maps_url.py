"""The active tab and the Maps tab's settings in the URL, without a browser.

A whole dashboard session is opened on a link (a ``Location`` standing in for the browser's):
the link's tab is the one shown, its map settings are the ones in the Maps tab, a light map
is computed by itself and a heavy one waits for Compute; refused values get the message every
refused URL value gets, naming the allowed range, and the URL shows the value kept.
"""
from __future__ import annotations

import urllib.parse

import numpy as np
import pytest
from conftest import new_dashboard, wait_for
from panel.io.location import Location

from app.state import MAP_URL_KEYS, MapSettings


@pytest.fixture()
def linked(job_pool):
    """Open dashboards on links; each is closed like a session afterwards."""
    opened = []

    def open_(search: str):
        loc = Location(search=search)
        d = new_dashboard(job_pool, location=loc)
        opened.append(d)
        return d, loc
    yield open_
    for d in opened:
        d.destroy()


def query(loc: Location) -> dict[str, str]:
    return dict(urllib.parse.parse_qsl(loc.search[1:]))


def test_a_link_opens_the_maps_tab_with_its_settings_and_computes_its_light_map(linked):
    """tab=maps with an r × j map: the Maps tab is shown, the settings are the link's, the map runs."""
    d, loc = linked("?tab=maps&map_x_axis=r&map_x_start=0.4&map_x_stop=0.9&map_x_num=4"
                    "&map_y_axis=j&map_y_start=3&map_y_stop=9&map_y_num=3&map_transient=40"
                    "&map_record=20&map_field=intensity")
    m = d.maps.settings
    assert d.tabs.active == 1 and d.state.tab == "maps"
    assert (m.x_axis, m.x_start, m.x_stop, m.x_num) == ("r", 0.4, 0.9, 4)
    assert (m.y_axis, m.y_start, m.y_stop, m.y_num) == ("j", 3.0, 9.0, 3)
    assert (m.transient, m.record, m.field) == (40, 20, "intensity")
    assert d.maps._choices["x_axis"].widget.value == "r" and d.maps._field.widget.value == "intensity"
    wait_for(lambda: d.maps.result is not None, what="the link's map")
    r = d.maps.result
    assert (r.x_name, r.y_name) == ("r", "j")
    np.testing.assert_allclose(r.x_values, np.linspace(0.4, 0.9, 4), rtol=1e-12)
    np.testing.assert_allclose(r.y_values, np.linspace(3.0, 9.0, 3), rtol=1e-12)
    q = query(loc)
    assert q["tab"] == "maps" and q["map_x_axis"] == "r" and q["map_x_num"] == "4"


def test_a_link_naming_an_axis_without_its_range_gets_the_axis_range(linked):
    """map_x_axis=r alone: the x range is r's own, not Λ's default, and the URL shows it."""
    d, loc = linked("?map_x_axis=r")
    m = d.maps.settings
    assert (m.x_start, m.x_stop) == (0.3, 0.95)
    assert float(query(loc)["map_x_start"]) == 0.3
    assert d.tabs.active == 0 and d.maps.result is None  # not on the Maps tab: nothing runs


def test_a_heavy_link_waits_for_compute(linked):
    """200 × 200 points over 260 periods is more than a link runs by itself: it is looked up
    in the disk cache only, and without it the page waits for Compute."""
    d, _ = linked("?tab=maps&map_x_num=200&map_y_num=200")
    wait_for(lambda: "press Compute" in d.maps.status.object, what="the cache lookup")
    assert d.maps.job is None and d.maps.result is None
    assert "40000 points" in d.maps.status.object and "not in the disk cache" in d.maps.status.object


def test_a_heavy_link_whose_map_ran_before_is_read_from_the_disk_cache(linked):
    """A heavy link opened a second time shows its map at once, read from the disk cache."""
    link = ("?tab=maps&map_x_axis=r&map_x_start=0.4&map_x_stop=0.9&map_x_num=61"
            "&map_y_axis=j&map_y_start=3&map_y_stop=9&map_y_num=2&map_transient=7660&map_record=20")
    first, _ = linked(link)  # 122 points × 7680 periods: over a link's own work
    wait_for(lambda: "press Compute" in first.maps.status.object, what="the cache lookup")
    assert first.maps.result is None
    first.maps.compute()
    wait_for(lambda: first.maps.result is not None, what="the computed map")
    second, _ = linked(link)
    wait_for(lambda: second.maps.result is not None, what="the map from the disk cache")
    assert second.maps.result.from_cache
    for k, v in first.maps.result.fields.items():
        np.testing.assert_array_equal(second.maps.result.fields[k], v)


def test_absurd_map_sizes_in_a_link_are_refused_naming_the_range(linked):
    """Points, periods and ranges out of bounds: refused, each message names its allowed range."""
    d, loc = linked("?tab=maps&map_x_num=100000000&map_transient=1e9&map_y_stop=1e400"
                    "&map_kind=%3Cb%3Ewide%3C%2Fb%3E&tab=maps")
    m = d.maps.settings
    said = m.messages
    assert "[2, 400]" in said["x_num"] and "Kept 60" in said["x_num"] and said["x_num"].startswith("URL")
    assert "[0, 100000]" in said["transient"]
    assert "1e400 is outside the allowed range; allowed [-1e+06, 1e+06]" in said["y_stop"]
    assert "allowed: regime, basin" in said["kind"]
    assert (m.x_num, m.transient, m.y_stop, m.kind) == (60, 200, 360.0, "regime")
    q = query(loc)
    assert (q["map_x_num"], q["map_transient"], q["map_kind"]) == ("60", "200", "regime")
    # within each bound but too many points together: refused when the map is asked for
    d, _ = linked("?tab=maps&map_x_num=400&map_y_num=400")
    assert "up to 100,000 points" in d.state.messages["map-run"]
    assert d.maps.job is None


def test_the_tab_and_the_settings_follow_the_page_into_the_url(linked):
    """Changing the tab and a map setting on the page puts them in the URL; a bad tab is refused."""
    d, loc = linked("?tab=gearbox")
    assert d.tabs.active == 2
    d.tabs.active = 1
    assert d.state.tab == "maps" and query(loc)["tab"] == "maps"
    d.maps.settings.param.update(kind="basin")
    q = query(loc)
    assert (q["map_kind"], q["map_x_axis"], q["map_y_axis"], q["map_field"]) == ("basin", "x0", "v0", "attractor")
    d, loc = linked("?tab=%3Cscript%3E")
    assert d.tabs.active == 0 and query(loc)["tab"] == "explorer"
    assert "allowed: explorer, maps, gearbox" in d.state.messages["tab"]


def test_every_map_setting_is_a_url_key():
    """Each MapSettings parameter has its map_ key (and nothing else does)."""
    assert set(MAP_URL_KEYS) == set(MapSettings.param) - {"name", "messages"}
    assert all(k == f"map_{n}" for n, k in MAP_URL_KEYS.items())


def test_a_link_reopens_the_gearbox_tab_with_its_settings(linked):
    """tab=gearbox with speeds, periods and a variant: the Gearbox tab has the link's settings,
    a refused value names its range, and a change on the page goes into the URL."""
    d, loc = linked("?tab=gearbox&gb_rpm_start=1200&gb_rpm_stop=2600&gb_rpm_num=8&gb_record=50"
                    "&gb_variant=backlash&gb_backlash_change_um=-25&gb_harmonics=99")
    g = d.gearbox.settings
    assert d.tabs.active == 2 and g is d.session.gearbox_settings
    assert (g.rpm_start, g.rpm_stop, g.rpm_num, g.record) == (1200.0, 2600.0, 8, 50)
    assert (g.variant, g.backlash_change_um) == ("backlash", -25.0)
    assert g.harmonics == 3 and "[1, 6]" in g.messages["harmonics"]
    g.rpm_num = 5
    q = query(loc)
    assert (q["gb_rpm_num"], q["gb_variant"], q["gb_harmonics"]) == ("5", "backlash", "3")


def test_every_gearbox_setting_is_a_url_key():
    """Each GearboxSettings parameter has its gb_ key, and no key is another's."""
    from app.state import GEARBOX_URL_KEYS, URL_KEYS, GearboxSettings
    assert set(GEARBOX_URL_KEYS) == set(GearboxSettings.param) - {"name", "messages"}
    assert all(k == f"gb_{n}" for n, k in GEARBOX_URL_KEYS.items())
    keys = [*URL_KEYS.values(), *MAP_URL_KEYS.values(), *GEARBOX_URL_KEYS.values()]
    assert len(keys) == len(set(keys))


def test_a_link_carries_the_gearbox_target_and_oil_temperature(linked):
    """gb_target and gb_oil_temp reopen the tab's target and temperature; a target that does not
    read and a temperature outside −40…150 °C are refused with their reasons, and the URL is
    put back to the kept values."""
    d, loc = linked("?tab=gearbox&gb_target=1000%3A10%2C3000%3A20%20sone&gb_oil_temp=-20")
    g = d.gearbox.settings
    assert (g.target, g.oil_temp) == ("1000:10,3000:20 sone", -20.0)
    d, loc = linked("?tab=gearbox&gb_target=1000%3A10%2C3000%20sone&gb_oil_temp=200")
    g = d.gearbox.settings
    assert g.target == "" and g.oil_temp is None
    assert "is not RPM:VALUE" in g.messages["target"] and "[-40, 150]" in g.messages["oil_temp"]
