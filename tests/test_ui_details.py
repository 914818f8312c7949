"""Browser tests of details a teacher preparing a lecture met: each failed on the old dashboard.

Saved pictures are caught as the browser's downloads; legends, labels and ranges are read from
the page's Bokeh document; values are compared with the core's own numbers.
"""
from __future__ import annotations

import pytest

from test_ui import open_dashboard, wait_bif
from test_ui_fixes import BY_NAME, compute_map

pytestmark = [pytest.mark.ui, pytest.mark.timeout(600)]

#: Press the save tool of the named figure (as a click on its toolbar button does).
SAVE = """(name) => {
  const f = (""" + BY_NAME + """)(name);
  const tool = f.toolbar.tools.find(t => t.type === 'SaveTool');
  Bokeh.index.find_one(f).tool_views.get(tool).doit('save');
}"""
#: The entries of the legend named ``key`` in the named figure: [label, colour].
KEY = """(name) => {
  const f = (""" + BY_NAME + """)(name);
  const l = f == null ? null : f.right.find(m => m.type === 'Legend' && m.name === 'key');
  return l == null || !l.visible ? [] : l.items.map(i => [i.label.value, i.renderers[0].glyph.fill_color.value]);
}"""


def saved(page, name: str, tmp_path) -> tuple[str, bytes]:
    """The file name and bytes the browser saves from the named figure's save tool."""
    with page.expect_download(timeout=30_000) as info:
        page.evaluate(SAVE, name)
    path = tmp_path / info.value.suggested_filename
    info.value.save_as(path)
    return info.value.suggested_filename, path.read_bytes()


def test_saved_plots_are_png_files_named_by_their_parameters(page, dashboard_server, tmp_path):
    """The time history, section and diagram save as ``….png`` files that are PNG images."""
    open_dashboard(page, dashboard_server)
    wait_bif(page)
    page.wait_for_function(f"() => ({BY_NAME})('section') != null", timeout=60_000)
    for name in ("time_history", "section", "bifurcation"):
        filename, data = saved(page, name, tmp_path)
        assert filename.endswith(".png") and "lam3.3_r0.65_j8" in filename, filename
        assert data[:8] == b"\x89PNG\r\n\x1a\n", name


def test_a_regime_map_carries_its_colour_key_into_the_png(page, dashboard_server, tmp_path):
    """A regime map's figure holds a key of the regimes it shows, in the map's colours."""
    from app.ui.labels import REGIME_COLOR
    open_dashboard(page, dashboard_server)
    compute_map(page, 8, 6)
    page.wait_for_function(f"() => ({KEY})('map_figure').length > 0", timeout=30_000)
    key = page.evaluate(KEY, "map_figure")
    letters = [label.split()[0] for label, _ in key]
    assert len(letters) >= 2 and len(set(letters)) == len(letters)
    shown = page.locator(".map-regime").all_inner_texts()  # "C one active-flank … (12)"
    present = [t.split()[0] for t in shown if not t.rstrip().endswith("(0)")]
    assert letters == present
    for label, colour in key:
        assert colour.lower() == REGIME_COLOR[label.split()[0]].lower(), label
    filename, data = saved(page, "map_figure", tmp_path)
    assert filename.endswith(".png") and data[:4] == b"\x89PNG"
