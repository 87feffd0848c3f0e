"""Look at the built site in a real browser: screenshots at 1280 px, and what overflows.

    python -m sphinx -b html docs /tmp/site
    python docs/check_layout.py /tmp/site [--out /tmp/shots]

Opens the index, the guide pages and an API page in headless Chromium (Debian's
``chromium``, driven by Playwright; ``apt install chromium`` and ``pip install
playwright``, no browser download), 1280 x 900, and for each page:

* writes a full-page screenshot (``--out``);
* fails when an element of the article (a code block, a table, a picture) reaches past
  the article's right edge (by more than the 8 px of furo's table border), or hides part
  of its content with ``overflow: hidden`` (clipped); code blocks and tables that scroll
  are counted, not failed (a long line of a real output is better scrolled than
  wrapped);
* fails when a picture did not load.

Exit status 0 when every page is clean. ``tests/test_docs_layout.py`` runs it (marked
slow: it builds the site) where Chromium and Playwright are installed.
"""

from __future__ import annotations

import argparse
import functools
import http.server
import shutil
import sys
import threading
from dataclasses import dataclass, field
from pathlib import Path

WIDTH, HEIGHT = 1280, 900
PAGES = [
    "index.html",
    "first-test.html",
    "your-recordings.html",
    "lidar.html",
    "lidar-relations.html",
    "detectors.html",
    "components.html",
    "findings/README.html",
    "campaigns.html",
    "soundness.html",
    "power.html",
    "api.html",
    "api/pytest_metamorphic.core.engine.html",
]
CHROMIUM_FLAGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]

# Run in the page: what reaches past the article, what is clipped, what scrolls.
_PROBE = """() => {
  const article = document.querySelector('[role="main"]') ||
      document.querySelector('article') || document.body;
  // furo draws a table's wrapper a few pixels wider than the column (its border)
  const edge = article.getBoundingClientRect().right + 8;
  const found = {overflowing: [], clipped: [], scrolling: [], broken_images: []};
  const name = (el) => el.tagName.toLowerCase() + ': ' +
      (el.innerText || el.getAttribute('alt') || '').trim().slice(0, 60).replace(/\\s+/g, ' ');
  for (const el of article.querySelectorAll('pre, table, img, .highlight')) {
    const style = getComputedStyle(el);
    if (el.getBoundingClientRect().right > edge) found.overflowing.push(name(el));
    if (el.scrollWidth > el.clientWidth + 1) {
      if (style.overflowX === 'hidden' || style.overflowX === 'clip') found.clipped.push(name(el));
      else found.scrolling.push(name(el));
    }
    if (el.tagName === 'IMG' && !(el.complete && el.naturalWidth > 0))
      found.broken_images.push(name(el));
  }
  return found;
}"""


@dataclass
class PageLayout:
    """What the probe found on one page."""

    page: str
    overflowing: list[str] = field(default_factory=list)
    clipped: list[str] = field(default_factory=list)
    scrolling: list[str] = field(default_factory=list)
    broken_images: list[str] = field(default_factory=list)

    @property
    def clean(self) -> bool:
        return not (self.overflowing or self.clipped or self.broken_images)


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, format: str, *args: object) -> None:
        pass


def chromium() -> str | None:
    """Debian's Chromium, if installed."""
    return shutil.which("chromium") or shutil.which("chromium-browser")


def check_site(site: Path, out: Path | None = None, pages: list[str] = PAGES) -> list[PageLayout]:
    """Open each page of a built site at 1280 px; screenshots into ``out``."""
    from playwright.sync_api import sync_playwright

    handler = functools.partial(_QuietHandler, directory=str(site))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    results = []
    try:
        with sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=chromium(), args=CHROMIUM_FLAGS)
            view = browser.new_page(viewport={"width": WIDTH, "height": HEIGHT})
            for page in pages:
                view.goto(f"http://127.0.0.1:{server.server_port}/{page}")
                view.wait_for_load_state("networkidle")
                results.append(PageLayout(page, **view.evaluate(_PROBE)))
                if out is not None:
                    out.mkdir(parents=True, exist_ok=True)
                    shot = out / (page.replace("/", "_").removesuffix(".html") + ".png")
                    view.screenshot(path=str(shot), full_page=True)
            browser.close()
    finally:
        server.shutdown()
    return results


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("site", type=Path, help="the folder sphinx -b html wrote")
    parser.add_argument("--out", type=Path, default=None, help="where screenshots go")
    options = parser.parse_args(argv)
    if chromium() is None:
        print("no chromium: apt install chromium", file=sys.stderr)
        return 2
    results = check_site(options.site, options.out)
    for result in results:
        verdict = "ok" if result.clean else "FAIL"
        print(f"{verdict:4} {result.page}: {len(result.scrolling)} block(s) scroll")
        for kind in ("overflowing", "clipped", "broken_images"):
            for what in getattr(result, kind):
                print(f"     {kind}: {what}")
    return 0 if all(result.clean for result in results) else 1


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
