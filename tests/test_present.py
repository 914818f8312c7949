"""Presentation mode and the Explorer's explanations, without a browser.

* ``present`` is a URL key like any other: ``present=true`` opens the page in presentation mode,
  a value that is not a switch is refused with a message naming it.
* In presentation mode the dashboard keeps its views and changes their look: larger figures and
  fonts (at least 1.4 times), the parts a lecture does not need hidden; leaving it restores all.
* The regime legend lists every letter of the vocabulary; the "what you see" sentence follows
  the regime; the vocabulary's regime table and every hover help text are word for word in
  ``docs/model.md``, so the page and the specification cannot drift apart.
"""
from __future__ import annotations

import re
from pathlib import Path

import param
import pytest
from panel.io.location import Location

from app.main import configure
from app.session import Session
from app.state import URL_KEYS
from app.ui import help as page_help
from app.ui.labels import regime_legend_html, what_you_see
from app.ui.present import FONTS
from app.views.explorer import WORDS
from rattle_core.analysis.vocabulary import CLASS_LETTERS, REGIMES

configure()
MODEL_MD = Path(__file__).resolve().parent.parent / "docs" / "model.md"


def model_text() -> str:
    """docs/model.md as running text: without its code and bold marks, spaces collapsed."""
    text = re.sub(r"\*\*|`", "", MODEL_MD.read_text())
    return re.sub(r"\s+", " ", text)


def px(size: str) -> float:
    """A CSS font size in pixels (``px`` or ``pt``)."""
    value = float(re.match(r"[\d.]+", size).group())
    return value * 4 / 3 if size.endswith("pt") else value


# ----- the URL key -------------------------------------------------------------------------------

def test_present_is_a_url_key_and_true_turns_the_mode_on():
    """``?present=true`` opens the session in presentation mode; the key is written back."""
    assert URL_KEYS["present"] == "present"
    session = Session(location=Location(search="?present=true"))
    assert session.state.present is True
    assert "present=true" in session.location.search
    session.destroy()


def test_present_stays_lowercase_in_the_url_after_a_slider_move():
    """Presenting, a move of the header's Λ slider rewrites the link: it still says
    ``present=true`` (and every other switch in lowercase), never Python's ``True``."""
    location = Location(search="?present=true")
    session = Session(location=location)
    s = session.state
    assert s.present is True
    from app.views.present import PresentView
    slider = PresentView(state=s).slider["lam"]
    with param.edit_constant(slider):  # as the page sets it when the handle is released
        slider.value_throttled = 2.25
    assert s.lam == pytest.approx(2.25) and "lam=2.25" in location.search
    assert "present=true" in location.search, location.search
    assert "True" not in location.search and "False" not in location.search, location.search
    session.destroy()


def test_a_bad_present_value_is_refused_with_a_message():
    """``?present=banana`` leaves the mode off and says that only true or false is allowed."""
    session = Session(location=Location(search="?present=banana"))
    s = session.state
    assert s.present is False and s.result is not None
    assert "presentation mode" in s.messages["present"]
    assert "true or false" in s.messages["present"]
    session.destroy()


# ----- the dashboard in presentation mode ----------------------------------------------------------

def test_presentation_mode_enlarges_the_plots_and_hides_the_rest_and_exit_restores(dash):
    """Present: figures that fill their cells (as high as the window allows), fonts ≥ 1.4×, the
    lecture's parts only; exit: all as before."""
    th, s = dash.time_history.fig, dash.state
    before = (th.height, th.sizing_mode, th.xaxis[0].major_label_text_font_size,
              th.xaxis[0].axis_label_text_font_size)
    section = (dash.section.pane.sizing_mode, dash.section.pane.min_height)
    others = [part for name, part in dash.cells.items() if name not in ("time_history", "section")]
    assert all(part.visible for part in dash.cells.values())
    assert dash.present.button.label == "Present"

    dash.present.button.clicks += 1
    assert s.present is True
    assert th.sizing_mode == dash.section.pane.sizing_mode == "stretch_both"
    assert px(th.xaxis[0].major_label_text_font_size) >= 1.4 * px(before[2])
    assert px(th.xaxis[0].axis_label_text_font_size) >= 1.4 * px(before[3])
    assert not any(part.visible for part in others)
    assert dash.cells["time_history"].visible and dash.cells["section"].visible
    assert "presenting" in dash.explorer.css_classes and "presenting" in dash.regime.badge.css_classes
    assert "rattle-presenting" in dash.present.header.css_classes
    assert dash.present.sliders.visible and dash.present.button.label == "Exit presentation"

    dash.present.button.clicks += 1
    assert s.present is False
    assert (th.height, th.sizing_mode, th.xaxis[0].major_label_text_font_size,
            th.xaxis[0].axis_label_text_font_size) == before
    assert (dash.section.pane.sizing_mode, dash.section.pane.min_height) == section
    assert all(part.visible for part in dash.cells.values())
    assert "presenting" not in dash.explorer.css_classes
    assert "rattle-presenting" not in dash.present.header.css_classes
    assert not dash.present.sliders.visible and dash.present.button.label == "Present"


@pytest.mark.parametrize("stage, view, figure", [
    ("diagram", "diagram", lambda d: d.diagram.pane.get_root().select_one({"name": "bifurcation"})),
    ("motion", "motion", lambda d: d.motion.parts["figure"]),
    ("pin", "section", lambda d: d.section.pane.get_root().select_one({"name": "section"})),
    ("maps", "maps", lambda d: d.maps.pane.get_root().select_one({"name": "map_figure"})),
])
def test_present_this_shows_that_view_alone_and_large_and_exit_restores(dash, stage, view, figure):
    """A view's "Present this" button presents it (``present`` and ``stage``, URL keys): the other parts of the Explorer hidden, its figure stretching with fonts ≥ 1.4 × the normal
    ones, the buttons hidden; "Exit presentation" restores the page and the stage."""
    from app.ui.present import STAGES
    s = dash.state
    fig = figure(dash)
    normal = px(fig.xaxis[0].major_label_text_font_size)
    button = {"diagram": dash.diagram, "motion": dash.motion, "pin": dash.pin,
              "maps": dash.maps}[stage].present_button
    assert button.visible and button.label == "Present this"
    button.clicks += 1
    assert (s.present, s.stage) == (True, stage)
    assert URL_KEYS["stage"] == "stage"
    shown = set(STAGES[stage])
    for name, part in dash.cells.items():
        assert part.visible == (name in shown), name
    assert f"stage-{stage}" in dash.explorer.css_classes
    assert dash.tabs.active == (1 if stage == "maps" else 0)
    if stage == "maps":  # the map alone: its controls are hidden
        assert not dash.maps.controls.visible and "presenting" in dash.maps_tab.css_classes
    fig = figure(dash)  # a HoloViews figure is the same model, its fonts set by its hook
    assert fig.sizing_mode == "stretch_both"
    assert px(fig.xaxis[0].major_label_text_font_size) >= 1.4 * normal
    assert not button.visible
    dash.present.button.clicks += 1
    assert (s.present, s.stage) == (False, "plots")
    assert all(part.visible for part in dash.cells.values())
    assert f"stage-{stage}" not in dash.explorer.css_classes and button.visible
    assert figure(dash).sizing_mode == "stretch_width"
    assert px(figure(dash).xaxis[0].major_label_text_font_size) == normal


def test_a_stage_that_is_no_view_is_refused_with_a_message():
    """``?present=true&stage=banana`` presents the plots and names the allowed views."""
    session = Session(location=Location(search="?present=true&stage=banana"))
    s = session.state
    assert s.present is True and s.stage == "plots"
    assert "presented view" in s.messages["stage"] and "diagram" in s.messages["stage"]
    session.destroy()


def test_every_presenting_font_is_at_least_1_4_times_the_normal_one():
    """Axis labels, tick labels and legends of the figures are ≥ 1.4× while presenting; titles,
    which hold every parameter, 1.3×."""
    for part in ("axis", "ticks", "legend"):
        assert px(FONTS[True][part]) >= 1.4 * px(FONTS[False][part]), part
    assert px(FONTS[True]["title"]) >= 1.3 * px(FONTS[False]["title"]) - 1e-9


def test_the_presenting_sliders_move_the_state(dash):
    """The header's Λ slider, shown while presenting, sets Λ; a new Λ moves it back."""
    dash.state.present = True
    slider = dash.present.slider["lam"]
    with param.edit_constant(slider):  # as the page sets it when the handle is released
        slider.value_throttled = 2.5
    assert dash.state.lam == pytest.approx(2.5)
    dash.state.lam = 3.123456789012345  # followed exactly: the slider does not round it back
    assert slider.value == dash.state.lam == 3.123456789012345


# ----- explanations ------------------------------------------------------------------------------

def test_the_legend_lists_every_regime_letter_of_the_vocabulary():
    """Each letter a classification can give is in the legend, with its meaning, once."""
    legend = regime_legend_html()
    letters = re.findall(r'data-regime="([^"]+)"', legend)
    assert letters == list(CLASS_LETTERS)
    for g in REGIMES[:-1]:
        assert g.meaning in legend


def test_the_legend_is_beside_the_badge(dash):
    """The Explorer's regime view shows the legend, with the vocabulary's letters."""
    assert dash.regime.legend.object == regime_legend_html()
    assert dash.regime.legend.visible


def test_what_you_see_follows_the_regime(dash):
    """Fig 7 (chaotic, D) and Fig 8 (one impact per flank, E) give different sentences, each
    the vocabulary's rule of its regime."""
    seen = {}
    for preset in ("Fig 7", "Fig 8"):
        dash.controls.apply_preset(preset)
        cls = dash.state.result.cls
        seen[preset] = (cls.regime, dash.regime.seen.object)
        assert what_you_see(cls) in dash.regime.seen.object.replace("&#x27;", "'")
        assert next(g.rule for g in REGIMES if g.letter == cls.regime) in what_you_see(cls)
    assert seen["Fig 7"][0] == "D" and seen["Fig 8"][0] == "E"
    assert seen["Fig 7"][1] != seen["Fig 8"][1]
    assert "never repeats" in seen["Fig 7"][1] and "every 1 period" in seen["Fig 8"][1]


def test_the_regime_table_of_docs_model_md_is_the_vocabulary():
    """Each row of docs/model.md's regime table is the vocabulary's letter, meaning and rule."""
    rows = re.findall(r"^\| ([A-Z]) \| (.+?) \| (.+?) \|$", MODEL_MD.read_text(), re.M)
    assert {r[0]: (r[1], r[2]) for r in rows} == {g.letter: (g.meaning, g.rule)
                                                  for g in REGIMES[:-1]}


@pytest.mark.parametrize("key", sorted(page_help.HELP))
def test_each_help_text_is_word_for_word_in_docs_model_md(key):
    """Every sentence of a hover help is in docs/model.md, so a change there shows here."""
    text = model_text()
    title, sentences = page_help.HELP[key]
    assert title and sentences
    for sentence in sentences:
        assert " ".join(sentence.split()) in text, (key, sentence)
    assert page_help.help_text(key).startswith(title)


def test_the_page_has_a_help_icon_for_each_word(dash):
    """Λ, r and j have their help beside their sliders; the diagrams' words beside the legend."""
    def icons(obj) -> set[str]:
        import panel as pn
        found = set()
        for w in pn.panel(obj).select(pn.widgets.TooltipIcon):
            found.update(c[5:] for c in w.css_classes if c.startswith("help-"))
            assert w.value == page_help.help_text(next(c[5:] for c in w.css_classes
                                                       if c.startswith("help-")))
        return found
    assert icons(dash.controls) >= {"lam", "r", "j"}
    assert icons(dash.regime) >= set(WORDS)
    assert set(page_help.HELP) == {"lam", "r", "j", *WORDS}
