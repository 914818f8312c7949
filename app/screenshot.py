"""Save a screenshot of the served dashboard (the README's picture, ``assets/dashboard.png``).

    .venv/bin/python -m app.screenshot [--out assets/dashboard.png] [--query "?lam=3.3"]
    .venv/bin/python -m app.screenshot --maps --out assets/maps.png   # the Maps tab, computed
    .venv/bin/python -m app.screenshot --continuation --query "?lam=1.2&h2=0" \
        --out assets/continuation.png                                  # "Continue this orbit"
    .venv/bin/python -m app.screenshot --gearbox --out assets/gearbox.png   # the Gearbox tab
    .venv/bin/python -m app.screenshot --present --out assets/present.png   # a 1280×720 projector

Serves the app on a free local port, opens it in headless Chromium (Debian's ``chromium``;
Playwright's own browsers cannot be downloaded here), waits until the time history and the
bifurcation diagram are drawn, and writes the PNG. With ``--maps`` it opens the Maps tab,
computes the default regime map (Λ × φ₂) and waits for its image first. With
``--continuation`` it presses "Continue this orbit", waits for the branch on the diagram and
keeps the part of the page with the diagram and the multipliers. With ``--gearbox`` it opens
the Gearbox tab, takes the sample run-up, runs the verdict with a drag +20 % variant and waits
for it. With ``--present`` it opens presentation mode on a 1280×720 viewport, the size of
a common projector.
"""
from __future__ import annotations

import argparse
import os
import shutil
import socket
import sys
from pathlib import Path

CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]

READY = """() => {
  const d = window.Bokeh && Bokeh.documents && Bokeh.documents[0];
  if (!d) return false;
  const th = d.get_model_by_name('th_motion');
  const names = [...d._all_models.values()].map(m => m.name);
  return th != null && th.get_length() > 0 && names.includes('bifurcation') && names.includes('section');
}"""

BRANCH_READY = """() => {
  const m = Bokeh.documents[0].get_model_by_name('cont-stable');
  return m != null && Array.from(m.data_source.data.xs || []).some(x => x.length > 1);
}"""

MAP_READY = """() => {
  const f = [...Bokeh.documents[0]._all_models.values()].find(m => m.name === 'map_figure');
  return f != null && f.renderers.some(r => r.data_source && r.data_source.data.image &&
                                            r.data_source.data.image.length && r.data_source.data.image[0].length > 4);
}"""


def main() -> int:
    ap = argparse.ArgumentParser(description="Screenshot the dashboard.")
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent.parent / "assets" / "dashboard.png"))
    ap.add_argument("--query", default="", help="URL query, e.g. '?lam=3.3&phi2=180'")
    ap.add_argument("--maps", action="store_true", help="screenshot the Maps tab with a computed map")
    ap.add_argument("--continuation", action="store_true",
                    help="press 'Continue this orbit' and screenshot the diagram with the branch")
    ap.add_argument("--gearbox", action="store_true",
                    help="screenshot the Gearbox tab with the sample's verdict and a variant")
    ap.add_argument("--present", action="store_true",
                    help="presentation mode (present=true) on a 1280×720 viewport")
    ap.add_argument("--chromium", default=shutil.which("chromium") or "/usr/bin/chromium")
    args = ap.parse_args()

    from playwright.sync_api import sync_playwright

    from .main import serve

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    server = serve(port=port, threaded=True, quiet=True)
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=args.chromium, args=CHROMIUM_ARGS)
            size = {"width": 1280, "height": 720} if args.present else {"width": 1500, "height": 1020}
            page = browser.new_page(viewport=size)
            query = args.query
            if args.present:
                query += ("&" if query else "?") + "present=true"
            page.goto(f"http://localhost:{port}/{query}")
            page.wait_for_function(READY, timeout=120_000)
            # the diagram is hidden while presenting: its sweep is not on the picture
            if not args.present:
                page.locator(".bif-status").filter(has_text="swept").first.wait_for(timeout=300_000)
            if args.maps:
                page.locator(".bk-tab", has_text="Maps").first.click()
                page.locator(".map-compute button").first.click()
                page.wait_for_function(MAP_READY, timeout=300_000)
            if args.continuation:
                page.locator(".cont-button button").first.click()
                page.wait_for_function(BRANCH_READY, timeout=300_000)
            if args.gearbox:  # the tab's four plots stand one below the other
                page.set_viewport_size({"width": 1500, "height": 1500})
                page.locator(".bk-tab", has_text="Gearbox").first.click()
                page.locator(".gb-sample button").first.click()
                page.locator(".gb-measure-status").filter(has_text="rpm bins").first.wait_for(timeout=120_000)
                page.locator(".gb-variant select").first.select_option(label="drag torque +/- %")
                page.wait_for_timeout(500)
                page.locator(".gb-run button").first.click()
                page.locator(".gb-status").filter(has_text="Verdict (").first.wait_for(timeout=600_000)
            page.wait_for_timeout(1500)  # let the last renders and the badge settle
            os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
            if args.continuation:
                top = page.locator(".diagram").first.bounding_box()
                low = page.locator(".continuation").first.bounding_box()
                clip = {"x": top["x"] - 10, "y": top["y"] - 60, "width": top["width"] + 20,
                        "height": low["y"] + low["height"] - top["y"] + 70}
                page.screenshot(path=args.out, full_page=True, clip=clip)
            else:
                page.screenshot(path=args.out, full_page=True)
            browser.close()
    finally:
        server.stop()
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
