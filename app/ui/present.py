"""How presentation mode looks: stylesheets, a figure's fonts, the marking class.

Presentation mode (``state.present``) is for a lecture on a projector: the page keeps its
views and their Bokeh models, and only their look changes. Everything that differs is here:

* :data:`PAGE_CSS`, the template's stylesheet: while an element of class ``rattle-presenting``
  is on the page (the header's toggle carries it), the sidebar is hidden, the main area does
  not scroll and its tabs take all of its height (the window's, less the header's): the
  Explorer's grid (:data:`app.dashboard.EXPLORER_CSS`) shares it out, and the figures, which
  stretch while presenting, fill their cells and follow the window when it is resized.
* :data:`PANE_CSS`, given to the HTML panes and layouts that change: rules that apply only
  while the pane carries the ``presenting`` class (:func:`mark`): the badge, the metrics and
  the legend at least 1.4 times their normal fonts (the sentence under the badge 1.3 times,
  so that it keeps to one line on a 1280-pixel projector), the tabs' header hidden.
* :data:`STAGES` names what presentation mode shows, and :func:`presents` tells a view
  whether it is one of them (the others keep their normal look, hidden or on another tab).
* :func:`figure_fonts` sets a Bokeh figure's title, axis, tick and legend fonts, normal or
  large; the views call it on their figures (the section's from its HoloViews hook, so a
  redraw keeps it).
"""
from __future__ import annotations

from typing import Any, Iterable

#: What presentation mode can show (``state.stage``, the URL key ``stage``), and the views each
#: puts on the screen: the time history and the section (the header's "Present"), the
#: bifurcation diagram with continuation, the gear in motion above the time history, the
#: pinned comparison, and the Maps tab's map with its atlas. Each of the four others has its
#: own "Present this" button (:func:`app.views.present.present_button`).
STAGES = {"plots": ("time_history", "section"),
          "diagram": ("diagram",),
          "motion": ("motion", "time_history"),
          "pin": ("pin", "time_history", "section"),
          "maps": ("maps",)}

#: The class the page's stylesheets key on while presenting.
PRESENTING = "presenting"
#: The class of the element whose presence puts the whole page in presentation mode.
PAGE_MARK = "rattle-presenting"

PAGE_CSS = f"""
body:has(.{PAGE_MARK}) #sidebar {{ display: none !important; }}
body:has(.{PAGE_MARK}) #sidebar-toggle {{ display: none !important; }}
body:has(.{PAGE_MARK}) #main {{ overflow: hidden !important; padding-top: 4px;
                                display: flex !important; flex-direction: column; }}
body:has(.{PAGE_MARK}) #main > * > .main-tabs {{ flex: 1 1 0 !important; min-height: 0 !important; }}
body:has(.{PAGE_MARK}) #header {{ padding-top: 0 !important; padding-bottom: 0 !important; }}
"""

PANE_CSS = f"""
:host(.{PRESENTING}) .rattle-badge {{ font-size: 21px !important; }}
:host(.{PRESENTING}) .rattle-badge .badge-letter {{ font-size: 40px !important; padding: 0 12px !important; }}
:host(.{PRESENTING}) .rattle-badge .badge-detail {{ display: none; }}
:host(.{PRESENTING}) .regime-legend {{ font-size: 17px !important; line-height: 1.5 !important; }}
:host(.{PRESENTING}) .regime-seen {{ font-size: 17px !important; }}
:host(.{PRESENTING}) .pin-line {{ font-size: 18px !important; }}
:host(.{PRESENTING}) table {{ font-size: 19px !important; }}
:host(.{PRESENTING}) .bk-header {{ display: none !important; }}
"""

#: Font sizes of a figure: normal, and while presenting (≥ 1.4 × each).
FONTS = {False: {"axis": "13px", "ticks": "11px", "title": "10pt", "legend": "13px"},
         True: {"axis": "20px", "ticks": "17px", "title": "13pt", "legend": "19px"}}


def figure_fonts(fig: Any, present: bool, title: str = "10pt") -> None:
    """Set the fonts of a Bokeh figure's title (``title`` when not presenting), axes, ticks
    and legends; a font already right is left alone, so a redraw sends nothing new."""
    f = {**FONTS[bool(present)], **({} if present else {"title": title})}
    for axis in fig.axis:
        if axis.axis_label_text_font_size != f["axis"]:
            axis.axis_label_text_font_size = f["axis"]
        if axis.major_label_text_font_size != f["ticks"]:
            axis.major_label_text_font_size = f["ticks"]
    if fig.title is not None and fig.title.text_font_size != f["title"]:
        fig.title.text_font_size = f["title"]
    for legend in fig.legend:
        if legend.label_text_font_size != f["legend"]:
            legend.label_text_font_size = f["legend"]


def stretch(fig: Any, present: bool) -> None:
    """A Bokeh figure stretches both ways while presented, across the page otherwise (set only
    when it changes, so a redraw sends nothing new)."""
    mode = "stretch_both" if present else "stretch_width"
    if fig.sizing_mode != mode:
        fig.sizing_mode = mode


def presents(state: Any, view: str) -> bool:
    """Whether ``view`` (a name in :data:`STAGES`) is on the screen in presentation mode."""
    return bool(state.present) and view in STAGES.get(state.stage, ())


def mark(objects: Iterable[Any], present: bool, cls: str = PRESENTING) -> None:
    """Add ``cls`` to (or take it from) the CSS classes of Panel ``objects``."""
    for obj in objects:
        classes = [c for c in obj.css_classes if c != cls] + ([cls] if present else [])
        if classes != list(obj.css_classes):
            obj.css_classes = classes
