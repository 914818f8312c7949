"""Frames per second of the gear in motion, measured in headless Chromium against the page's idle rate.

The script serves the dashboard (``app.main.serve``, threaded, as the browser tests do), opens
it in Debian's Chromium through Playwright with the flags of ``tests/conftest.py``, and for
each case:

1. presses Play and counts the frames the animation itself drew (its clock's frame counter)
   over a few seconds, while the teeth, the impact flashes and the time history's cursor move;
2. presses Pause and counts ``requestAnimationFrame`` callbacks of an empty loop over the same
   time: the page's idle rate, the most frames the browser paints here (the baseline,
   measured in the same run, once the page has settled);
3. prints both rates and their ratio; the target is at least 30 frames per second.

Cases: the default page (12 periods shown, Fig 7's chaotic parameters), then 200 periods
shown (about 33 000 frames sent to the page), and the physical-units mode at 1× real time.
The frame rate of headless Chromium without a GPU is what is measured: a desktop browser
with a GPU paints at its screen's rate.

    .venv/bin/python benchmarks/bench_motion.py [--seconds 4] [--sizes 1280x720,1920x1080]
"""
from __future__ import annotations

import argparse
import os
import sys
import time
import urllib.request

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests"))

TARGET_FPS = 30.0

READY = """() => { const d = window.Bokeh && Bokeh.documents && Bokeh.documents[0];
  if (!d) return false; const m = d.get_model_by_name('motion_frames');
  return m != null && m.get_length() > 0; }"""

IDLE = """(ms) => new Promise((done) => { let n = 0; const t0 = performance.now();
  const f = (now) => { n += 1; if (now - t0 < ms) requestAnimationFrame(f);
    else done(1000 * n / (now - t0)); }; requestAnimationFrame(f); })"""

DRAWN = """(ms) => new Promise((done) => {
  const src = Bokeh.documents[0].get_model_by_name('motion_frames');
  const n0 = src._rattle_motion.frames, t0 = performance.now();
  setTimeout(() => done(1000 * (src._rattle_motion.frames - n0) / (performance.now() - t0)), ms); })"""

FRAMES = "() => Bokeh.documents[0].get_model_by_name('motion_frames').get_length()"
PLAYING = ("() => { const s = Bokeh.documents[0].get_model_by_name('motion_frames')._rattle_motion;"
           " return s != null && s.playing; }")


def serve() -> tuple[object, str]:
    from conftest import free_port
    from app.main import serve as serve_app

    port = free_port()
    server = serve_app(port=port, address="localhost", show=False, threaded=True)
    url = f"http://localhost:{port}"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        try:
            with urllib.request.urlopen(f"{url}/liveness", timeout=2) as resp:
                if resp.status == 200:
                    return server, url
        except OSError:
            time.sleep(0.2)
    raise RuntimeError(f"the dashboard did not come up at {url}")


def measure(page, url: str, query: str, seconds: float, speed: float | None) -> tuple[int, float, float]:
    page.goto(f"{url}/{query}", timeout=180_000)
    page.wait_for_function(READY, timeout=120_000)
    page.locator(".motion-play button").first.wait_for(timeout=60_000)
    # the page has settled once its diagram and its first sound are in
    page.locator(".bif-status").filter(has_text="swept").first.wait_for(timeout=180_000)
    page.wait_for_function("(el) => el.src.length > 100",
                           arg=page.locator(".sound-audio audio").first.element_handle(),
                           timeout=120_000)
    page.wait_for_timeout(1500)
    if speed is not None:
        page.evaluate("""(v) => { const s = Bokeh.documents[0].get_model_by_name('motion_speed');
                         s.value = Math.log10(v); }""", speed)
    page.locator(".motion-play button").first.click()
    page.wait_for_function(PLAYING, timeout=20_000)
    drawn = page.evaluate(DRAWN, 1000 * seconds)
    page.locator(".motion-pause button").first.click()
    page.wait_for_function(f"() => !({PLAYING})()", timeout=20_000)
    idle = page.evaluate(IDLE, 1000 * seconds)  # after the play: the page has settled by then
    return page.evaluate(FRAMES), idle, drawn


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=4.0, help="seconds counted per measure")
    ap.add_argument("--sizes", default="1400x1000",
                    help="browser window sizes, WIDTHxHEIGHT separated by commas")
    args = ap.parse_args()
    try:
        sizes = [tuple(int(v) for v in size.lower().split("x")) for size in args.sizes.split(",")]
        if any(len(s) != 2 or not (320 <= s[0] <= 7680 and 240 <= s[1] <= 4320) for s in sizes):
            raise ValueError
    except ValueError:
        ap.error(f"--sizes = {args.sizes!r}: give WIDTHxHEIGHT pairs from 320x240 to 7680x4320")
    from playwright.sync_api import sync_playwright
    from conftest import CHROMIUM, CHROMIUM_ARGS

    server, url = serve()
    cases = [("default page, 12 periods, 0.1×", "", None),
             ("200 periods shown, 1×", "?shown=200", 1.0),
             ("physical units, 1× real time", "?units=true", 1.0)]
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS, headless=True)
            print(f"{'window':<10} {'case':<34} {'frames sent':>11} {'idle rAF/s':>11} "
                  f"{'drawn/s':>9} {'ratio':>7}")
            for w, h in sizes:
                page = browser.new_page(viewport={"width": w, "height": h})
                for name, query, speed in cases:
                    n, idle, drawn = measure(page, url, query, args.seconds, speed)
                    print(f"{f'{w}x{h}':<10} {name:<34} {n:>11d} {idle:>11.1f} {drawn:>9.1f} "
                          f"{drawn / idle:>7.2f}", flush=True)
                page.close()
            browser.close()
    finally:
        server.stop()
    print(f"target: at least {TARGET_FPS:.0f} frames drawn per second")


if __name__ == "__main__":
    main()
