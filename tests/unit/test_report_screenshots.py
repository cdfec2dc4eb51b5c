"""The identify report in a real browser: headless Chromium at a 1280 px wide viewport shows no
horizontal overflow (issue 13 item 5), and a screenshot is taken for a person to look at.

Skipped with a reason where no Chromium is installed (``apt-get install chromium``).
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess

import pytest

from droneid.report.identify import write
from test_report_identify import ladder_result

pytestmark = pytest.mark.slow

CHROMIUM = next((p for p in (os.environ.get("DRONEID_CHROMIUM"), shutil.which("chromium"),
                             shutil.which("chromium-browser"), shutil.which("google-chrome"))
                 if p and os.path.exists(p)), None)
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--hide-scrollbars", "--window-size=1280,900"]

#: appended to a copy of report.html: writes the page's and the viewport's widths into the DOM
PROBE = ("<script>window.addEventListener('load', () => { const d = document.documentElement;"
         "document.body.insertAdjacentHTML('beforeend', '<p id=probe>scrollWidth=' + d.scrollWidth"
         " + ' innerWidth=' + window.innerWidth + '</p>'); });</script>")


def _chromium(tmp_path, *args) -> subprocess.CompletedProcess:
    return subprocess.run([CHROMIUM, *FLAGS, f"--user-data-dir={tmp_path / 'profile'}", *args],
                          capture_output=True, text=True, timeout=120)


@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium on this machine (apt-get install chromium)")
def test_report_html_has_no_horizontal_overflow_at_1280px(tmp_path):
    result = ladder_result()
    tr = result["targets"]["vx_dot"]
    # the worst cases for width: a very long plain equation and a wide table cell
    tr["equation"] = "vx_dot = " + " + ".join(f"0.123456*signal_with_a_long_name_{i}" for i in range(40))
    tr["notes"].append("x" * 400)
    write(result, tmp_path / "rep")
    page = tmp_path / "rep" / "report.html"
    probe = tmp_path / "probe.html"
    probe.write_text(page.read_text(encoding="utf-8").replace("</body>", PROBE + "</body>"), encoding="utf-8")
    dom = _chromium(tmp_path, "--virtual-time-budget=5000", "--dump-dom", probe.as_uri())
    m = re.search(r"scrollWidth=(\d+) innerWidth=(\d+)", dom.stdout)
    assert m, f"the probe did not run: {dom.stderr[-500:]}"
    scroll, inner = int(m.group(1)), int(m.group(2))
    assert inner == 1280
    assert scroll <= inner, f"page is {scroll} px wide in a {inner} px viewport"
    shot = tmp_path / "report.png"
    _chromium(tmp_path, f"--screenshot={shot}", page.as_uri())
    assert shot.read_bytes()[:4] == b"\x89PNG"
    keep = os.environ.get("DRONEID_SCREENSHOT_DIR")
    if keep:  # for a person to look at
        shutil.copy(shot, os.path.join(keep, "report_identify_1280.png"))
