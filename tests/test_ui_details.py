"""Browser tests of details a teacher preparing a lecture met: each failed on the old dashboard.

Saved pictures are caught as the browser's downloads; legends, labels and ranges are read from
the page's Bokeh document; values are compared with the core's own numbers.

Checks that can share a page run as steps of one test on one page (a page load is the costly
part of a browser test), in an order where no step spoils a later one: the default page's
statuses, saved plots and regime map; a page in physical units (whose diagram runs over engine
speed) for the units table, the diagram's labels and the phase convention. The diagram's zoom
needs a page opened with H₂/H₁ = 1, and a diagram read from the disk cache a second page load.
"""
from __future__ import annotations

import random

import pytest

from app import dashboard as dashboard_module
from app.state import convert_phase
from test_ui import box, open_dashboard, wait_bif, wait_box
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


def text(page, css: str) -> str:
    """The text shown inside the component ``css`` (its panes render in shadow roots)."""
    return " ".join(page.locator(f"{css} div").all_inner_texts())


def saved(page, name: str, tmp_path) -> tuple[str, bytes]:
    """The file name and bytes the browser saves from the named figure's save tool."""
    with page.expect_download(timeout=30_000) as info:
        page.evaluate(SAVE, name)
    path = tmp_path / info.value.suggested_filename
    info.value.save_as(path)
    return info.value.suggested_filename, path.read_bytes()


def _step_continue_says_why_it_is_off(page):
    """On chaos the Continue button says why it is off."""
    page.locator(".cont-why div", has_text="periodic orbit").first.wait_for(timeout=30_000)
    assert "regime D" in text(page, ".cont-why")


def _step_saved_plots_are_png_files_named_by_their_parameters(page, tmp_path):
    """The time history, section and diagram save as ``….png`` files that are PNG images, and
    each can be shown full screen."""
    wait_bif(page)
    page.wait_for_function(f"() => ({BY_NAME})('section') != null", timeout=60_000)
    for name in ("time_history", "section", "bifurcation"):
        filename, data = saved(page, name, tmp_path)
        assert filename.endswith(".png") and "lam3.3_r0.65_j8" in filename, filename
        assert data[:8] == b"\x89PNG\r\n\x1a\n", name
        assert page.evaluate(f"(n) => ({BY_NAME})(n).toolbar.tools.some(t => t.type === 'FullscreenTool')",
                             name), f"{name} cannot be shown full screen"


def _step_a_regime_map_carries_its_colour_key_into_the_png(page, tmp_path):
    """A regime map's figure holds a key of the regimes it shows, in the map's colours."""
    from app.ui.labels import REGIME_COLOR
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


def test_continue_status_saved_plots_and_regime_map_key(page, dashboard_server, tmp_path):
    """On the default page (chaos): the Continue button says why it is off; the time history,
    section and diagram save as PNG files named by their parameters; a regime map's figure
    holds a key of its regimes in the map's colours, and saves it."""
    open_dashboard(page, dashboard_server)
    _step_continue_says_why_it_is_off(page)
    _step_saved_plots_are_png_files_named_by_their_parameters(page, tmp_path)
    _step_a_regime_map_carries_its_colour_key_into_the_png(page, tmp_path)


#: Text of every label glyph in the named figure (diagram marks, branch labels).
TEXTS = """(name) => {
  const f = (""" + BY_NAME + """)(name);
  const out = [];
  for (const r of f.renderers) {
    const g = r.glyph, col = g && g.type === 'Text' && g.text.field ? r.data_source.data[g.text.field] : null;
    if (col) out.push(...Array.from(col));
  }
  return out.filter(t => t && t.trim());
}"""
RANGES = """(name) => { const f = (""" + BY_NAME + """)(name);
  return [f.x_range.start, f.x_range.end, f.y_range.start, f.y_range.end]; }"""


def test_the_diagram_zooms_its_swept_axis_and_labels_its_marks(page, dashboard_server):
    """The wheel zooms Λ only (eight steps keep every impulse in view); the marks' labels name
    their unit, stay in the view when Λ_c < 0.5, and the page warns of no missing field."""
    errors: list[str] = []
    page.on("console", lambda m: errors.append(m.text))
    open_dashboard(page, dashboard_server, "?h2=1")
    wait_bif(page)
    page.wait_for_function(f"() => ({TEXTS})('bifurcation').length > 0", timeout=60_000)
    texts = page.evaluate(TEXTS, "bifurcation")
    onset = [t for t in texts if "rattle starts" in t]
    assert onset and onset[0].strip().startswith("← rattle starts (Λ_c = "), texts
    before = page.evaluate(RANGES, "bifurcation")
    page.locator(".diagram").first.scroll_into_view_if_needed()
    plot = page.locator(".diagram").first.bounding_box()
    page.mouse.move(plot["x"] + 0.5 * plot["width"], plot["y"] + 0.6 * plot["height"])
    for _ in range(8):
        page.mouse.wheel(0, -300)
    page.wait_for_function(f"() => ({RANGES})('bifurcation')[1] - ({RANGES})('bifurcation')[0] "
                           f"< {0.5 * (before[1] - before[0])}", timeout=20_000)
    after = page.evaluate(RANGES, "bifurcation")
    assert after[2:] == pytest.approx(before[2:])
    assert not [e for e in errors if "nonexistent field" in e]


def _step_units_table_reads_one_line_per_row(page):
    """In physical units every row of the SI table is one line high."""
    rows = page.locator(".units-table table.units-params tr")
    rows.first.wait_for(timeout=20_000)
    heights = [rows.nth(i).bounding_box()["height"] for i in range(rows.count())]
    assert len(heights) > 8 and max(heights) < 1.6 * min(heights), heights


def _step_the_engine_speed_diagram_labels_its_marks_in_rpm(page):
    """Over engine speed the marks' labels name rpm, not Λ, and the rpm box shows a short number."""
    page.locator(".bif-status", has_text="engine speeds swept").first.wait_for(timeout=180_000)
    page.wait_for_function(f"() => ({TEXTS})('bifurcation').some(t => t.includes('rattle starts'))",
                           timeout=60_000)
    onset = [t for t in page.evaluate(TEXTS, "bifurcation") if "rattle starts" in t][0]
    assert "rpm" in onset and "Λ" not in onset
    shown = box(page, "rpm").input_value()  # an engine speed derived from Λ, shortened
    assert len(shown.replace(".", "").lstrip("0")) <= 9, shown


def _step_units_mode_speaks_one_phase_convention_and_names_engine_orders(page):
    """In physical units the physical φ₂ and the slider's φ₂ agree in the page's convention (both
    paper, then both core), and the excitation's harmonics are named by engine order."""
    phase = box(page, "phase2")
    phase.wait_for(state="visible", timeout=20_000)
    labels = text(page, ".units-card")
    assert "sin(2ωt + φ₂)" in labels and "cos(" not in labels
    assert "amplitude at engine order 2 " in labels and "amplitude at engine order 4 " in labels
    for typed in ("0", "30"):
        phase.fill(typed)
        phase.press("Enter")
        wait_box(page, "phi2", float(typed), tol=1e-6)
    page.locator(".units-table div", has_text="φ_2 = 30°").first.wait_for(timeout=20_000)
    table = text(page, ".units-table")
    assert "engine order 4" in table and "harmonic 2" not in table
    page.locator(".ctl-phases button", has_text="core").first.click()
    wait_box(page, "phi2", convert_phase(30.0, 2), tol=1e-6)
    wait_box(page, "phase2", convert_phase(30.0, 2), tol=1e-6)
    assert "cos(2ωt − φ₂)" in text(page, ".units-card")


def test_units_mode_table_engine_speed_diagram_and_phase_convention(page, dashboard_server):
    """In physical units, where the diagram runs over engine speed: every row of the SI table is
    one line high; the diagram's marks are labelled in rpm; the physical and the slider's φ₂
    agree in the page's convention, and the harmonics are named by engine order."""
    open_dashboard(page, dashboard_server, "?units=1&bif=rpm")
    _step_units_table_reads_one_line_per_row(page)
    _step_the_engine_speed_diagram_labels_its_marks_in_rpm(page)
    _step_units_mode_speaks_one_phase_convention_and_names_engine_orders(page)


def test_statuses_speak_plainly(page, dashboard_server):
    """A first diagram is "computed", its reload "read from the disk cache"; a branch's status
    has no internal names, its buttons leave the multipliers' plot free, and the diagram keys
    the branch in a legend and labels each bifurcation once."""
    r = f"{0.55 + 0.05 * random.random():.6f}"  # a diagram no earlier run left in the cache
    for source in ("computed", "read from the disk cache"):
        open_dashboard(page, dashboard_server, f"?lam=1.2&h2=0&r={r}&cont=1")
        status = page.locator(".bif-status div", has_text="swept").first
        status.wait_for(timeout=180_000)
        assert status.inner_text().rstrip().endswith(source), status.inner_text()
    page.locator(".cont-clear button").first.wait_for(timeout=30_000)
    hide = page.locator(".cont-clear").first.bounding_box()
    plot = page.locator(".cont-multipliers").first.bounding_box()
    # the button never covers the plot: it sits beside, below or (in a narrow column) above it
    assert (hide["x"] + hide["width"] <= plot["x"] + 1 or hide["y"] >= plot["y"] + plot["height"]
            or hide["y"] + hide["height"] <= plot["y"] + 1)
    done = page.locator(".cont-status div", has_text="Continued branch").first
    done.wait_for(timeout=180_000)
    assert "_" not in done.inner_text() and "stopped" in done.inner_text()
    page.wait_for_function(f"""() => {{ const f = ({BY_NAME})('bifurcation');
        return f.center.some(m => m.type === 'Legend' && m.name === 'cont-legend' && m.visible
            && m.items.some(i => i.visible && String((i.label || {{}}).value || '').includes('period'))); }}""",
                           timeout=60_000)
    dash = max(dashboard_module.LIVE, key=lambda d: d.session.key)
    bifurcations = len(dash.state.branch.marks.drop_duplicates(["kind", "x"]))
    drawn = [t for t in page.evaluate(TEXTS, "bifurcation") if "rattle" not in t and "chaos" not in t]
    # at most once each, never once per impact; crowded ones are thinned (their diamonds stay)
    assert bifurcations >= 1 and 1 <= len(drawn) <= bifurcations, drawn
