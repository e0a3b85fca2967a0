"""Render a run's ``report.html`` in headless Chromium at 1280×900 and check that its
first screen answers: the verdict and the whole parameter headline table lie inside
the first viewport, and nothing overflows its width.

    python scripts/check_report_in_browser.py RUN_DIR [--screenshot first_screen.png]

Exit 0 when the first screen holds both, 1 when it does not (what is where is
printed), 2 when no Chromium is installed (Debian: ``apt-get install chromium``).
The report is not changed: a copy with a measuring script is rendered from a
temporary directory.
"""

from __future__ import annotations

import argparse
import html
import json
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

WIDTH, HEIGHT = 1280, 900
BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")

_MEASURE = """<script>
window.addEventListener("load", () => {
  const head = document.getElementById("s0");
  const out = {viewport: [window.innerWidth, window.innerHeight],
               page_width: document.documentElement.scrollWidth};
  if (head) {
    out.heading = head.textContent;
    const verdict = head.nextElementSibling;
    let table = verdict;
    while (table && table.tagName !== "TABLE") table = table.nextElementSibling;
    out.verdict = verdict ? verdict.textContent : null;
    out.verdict_bottom = verdict ? verdict.getBoundingClientRect().bottom : null;
    if (table) {
      const box = table.getBoundingClientRect();
      out.table_bottom = box.bottom;
      out.table_right = box.right;
      out.table_rows = Array.from(table.rows).map(r => r.cells[0].textContent);
    }
    let next = head.nextElementSibling;
    while (next && next.tagName !== "H2") next = next.nextElementSibling;
    out.section_bottom = next ? next.getBoundingClientRect().top : null;
  }
  const pre = document.createElement("pre");
  pre.id = "first-screen-check";
  pre.textContent = JSON.stringify(out);
  document.body.appendChild(pre);
});
</script>"""


def browser() -> str | None:
    return next((p for p in map(shutil.which, BROWSERS) if p), None)


# A headless browser that reaches no network of its own and keeps no state: no QUIC,
# no first-run, background, component-update or sync traffic, and a profile of its own
# (a fresh, temporary --user-data-dir) for every page, so no user's profile is read or
# locked and two checks never share one.
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--hide-scrollbars", "--virtual-time-budget=10000")


def _chromium(exe: str, page: Path, *extra: str, height: int = HEIGHT) -> str:
    with tempfile.TemporaryDirectory(prefix="chromium-profile-") as profile:
        cmd = [exe, *FLAGS, f"--window-size={WIDTH},{height}", f"--user-data-dir={profile}",
               *extra, page.as_uri()]
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=True)
    return done.stdout


def _measured(exe: str, page: Path, height: int) -> dict:
    dom = _chromium(exe, page, "--dump-dom", height=height)
    found = re.search(r'<pre id="first-screen-check">(.*?)</pre>', dom, flags=re.S)
    if not found:
        raise RuntimeError("the browser did not run the measuring script")
    return json.loads(html.unescape(found.group(1)))


def measure(report: Path, screenshot: Path | None = None) -> dict:
    """Where the first section's verdict and headline table lie in a 1280×900 viewport
    (CSS pixels from the top), as the browser laid them out.

    Chromium's headless mode counts its (invisible) bars in ``--window-size`` when it
    lays out a page for ``--dump-dom`` (a 900 px window gives the page 757 or 813 px,
    as the profile goes), not for ``--screenshot``; so the measuring window is made
    taller by what the bars took, and the page is measured in the same 1280×900
    viewport the screenshot shows (``viewport`` in the result says what it had)."""
    exe = browser()
    if exe is None:
        raise FileNotFoundError("no Chromium found (" + ", ".join(BROWSERS) + ")")
    text = report.read_text(encoding="utf-8")
    with tempfile.TemporaryDirectory() as tmp:
        page = Path(tmp) / "report.html"
        page.write_text(text.replace("</body>", _MEASURE + "</body>"), encoding="utf-8")
        m = _measured(exe, page, HEIGHT)
        bars = HEIGHT - m["viewport"][1]
        if bars > 0:
            m = _measured(exe, page, HEIGHT + bars)
        if screenshot is not None:
            plain = Path(tmp) / "plain.html"
            plain.write_text(text, encoding="utf-8")
            _chromium(exe, plain, f"--screenshot={Path(screenshot).resolve()}")
    return m


def verdict(m: dict) -> list[str]:
    """What is wrong with the first screen (empty when it answers)."""
    height = m["viewport"][1]
    problems = []
    if m.get("heading") != "At a glance":
        problems.append(f"the first section is {m.get('heading')!r}, not 'At a glance'")
    if not m.get("verdict") or "adequate" not in m["verdict"].lower():
        problems.append(f"no verdict after the first heading (found {m.get('verdict')!r})")
    elif m["verdict_bottom"] > height:
        problems.append(f"the verdict ends at {m['verdict_bottom']:.0f} px, below the "
                        f"first screen ({height} px)")
    if m.get("table_bottom") is None:
        problems.append("no parameter table in the first section")
    elif m["table_bottom"] > height:
        problems.append(f"the parameter table ends at {m['table_bottom']:.0f} px, below "
                        f"the first screen ({height} px)")
    if m["page_width"] > m["viewport"][0]:
        problems.append(f"the page is {m['page_width']} px wide, wider than the window")
    return problems


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", type=Path, help="a run directory (holding report.html)")
    ap.add_argument("--screenshot", type=Path, help="also save the first screen as PNG")
    args = ap.parse_args(argv)
    report = args.run / "report.html" if args.run.is_dir() else args.run
    if not report.is_file():
        print(f"{report}: no such report; pass a run directory", file=sys.stderr)
        return 2
    try:
        m = measure(report, args.screenshot)
    except FileNotFoundError as exc:
        print(f"{exc}; install one (Debian: apt-get install chromium)", file=sys.stderr)
        return 2
    print(f"page viewport {m['viewport'][0]}×{m['viewport'][1]}: "
          f"verdict ends at {m.get('verdict_bottom') or 0:.0f} px, parameter table "
          f"({', '.join(m.get('table_rows', [])[1:])}) ends at "
          f"{m.get('table_bottom') or 0:.0f} px; the whole first section ends at "
          f"{m.get('section_bottom') or 0:.0f} px")
    problems = verdict(m)
    for p in problems:
        print(f"FIRST SCREEN: {p}")
    if not problems:
        print("first screen: the verdict and the parameter headline are in view")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
