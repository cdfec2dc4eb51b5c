"""The verdict box's colour follows the verdict (issue 29, item 8), as a user sees it: an identify
report.html rendered by headless Chromium, the box found on the page and its colour read from the
pixels of a screenshot.

"better" must look green, "worse" red, "not to be trusted" amber and "no better" / "no verdict"
neutral grey; before the fix every verdict was green. The hues are judged from the pixels, not
from droneid's own CSS table, so a change of the table that makes "worse" look green fails here.

Skipped with a reason where no Chromium is installed (``make browser`` or ``apt-get install
chromium``; ``DRONEID_CHROMIUM`` names another binary).
"""
from __future__ import annotations

import colorsys
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
WINDOW = (1280, 2400)
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--hide-scrollbars", "--force-color-profile=srgb", "--force-device-scale-factor=1",
         f"--window-size={WINDOW[0]},{WINDOW[1]}"]

#: appended to a copy of report.html: writes the first verdict box's rectangle (CSS px) into the DOM
PROBE = ("<script>window.addEventListener('load', () => { const r = document.querySelector('.verdict')"
         ".getBoundingClientRect(); document.body.insertAdjacentHTML('beforeend', '<p id=probe>rect=' "
         "+ [r.left, r.top, r.width, r.height].map(Math.round).join(',') + '</p>'); });</script>")

#: verdict kind -> what a user must see (a hue family of the box's fill and border)
EXPECTED = {"better": "green", "worse": "red", "not to be trusted": "amber", "no better": "grey",
            "no verdict": "grey"}


def _chromium(tmp_path, *args) -> subprocess.CompletedProcess:
    return subprocess.run([CHROMIUM, *FLAGS, f"--user-data-dir={tmp_path / 'profile'}", *args],
                          capture_output=True, text=True, timeout=120)


def _family(rgb) -> str:
    """green / red / amber / grey from an (r, g, b) colour, by hue and saturation."""
    h, s, v = colorsys.rgb_to_hsv(*(c / 255 for c in rgb))
    if s < 0.08:
        return "grey"
    deg = h * 360
    if deg < 20 or deg >= 340:
        return "red"
    if 25 <= deg < 65:
        return "amber"
    if 90 <= deg < 170:
        return "green"
    return f"other (hue {deg:.0f} deg)"


def _render(kind: str, tmp_path):
    """(box fill colour, box left-edge colour) of the verdict of ``kind`` on a screenshot."""
    from PIL import Image
    result = ladder_result()
    tr = result["targets"]["vx_dot"]
    tr["verdict"] = f"vx_dot: a verdict of the kind {kind!r}, long enough to fill a line of the box"
    tr["verdict_kind"] = kind
    out = tmp_path / kind.replace(" ", "_")
    write(result, out)
    page = out / "report.html"
    probe = out / "probe.html"
    probe.write_text(page.read_text(encoding="utf-8").replace("</body>", PROBE + "</body>"), encoding="utf-8")
    dom = _chromium(tmp_path, "--virtual-time-budget=5000", "--dump-dom", probe.as_uri())
    m = re.search(r"rect=(\d+),(\d+),(\d+),(\d+)", dom.stdout)
    assert m, f"the probe did not run: {dom.stderr[-500:]}"
    left, top, width, height = map(int, m.groups())
    assert width > 100 and height > 10 and top + height < WINDOW[1], (left, top, width, height)
    shot = out / "shot.png"
    _chromium(tmp_path, f"--screenshot={shot}", page.as_uri())   # the page itself, no probe
    img = Image.open(shot).convert("RGB")
    assert img.size == WINDOW
    # the fill: the most common colour inside the box (text pixels are a minority)
    inner = img.crop((left + 8, top + 2, left + width - 2, top + height - 2))
    fill = max(inner.getcolors(maxcolors=1 << 20))[1]
    # the left border: the most common colour of the first columns of the box
    edge = img.crop((left, top + 2, left + 3, top + height - 2))
    border = max(edge.getcolors(maxcolors=1 << 16))[1]
    keep = os.environ.get("DRONEID_SCREENSHOT_DIR")
    if keep:   # for a person to look at
        shutil.copy(shot, os.path.join(keep, f"verdict_{kind.replace(' ', '_')}.png"))
    return fill, border


@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium on this machine (make browser, or apt-get install chromium)")
def test_the_verdict_box_colour_follows_the_verdict(tmp_path):
    from droneid.fitting.verdict import VERDICT_KINDS
    assert set(EXPECTED) == set(VERDICT_KINDS), "a verdict kind without an expected colour here"
    seen = {}
    for kind, family in EXPECTED.items():
        fill, border = _render(kind, tmp_path)
        seen[kind] = (fill, border)
        assert fill != (255, 255, 255), f"{kind}: the box has no fill"
        assert _family(border) == family, f"{kind}: border {border} looks {_family(border)}, not {family}"
        if family != "grey":
            # a pale fill of the same hue (its saturation is low but its hue is the border's)
            h, s, _ = colorsys.rgb_to_hsv(*(c / 255 for c in fill))
            assert s > 0.02 and _family(tuple(round(255 * c) for c in colorsys.hsv_to_rgb(h, 1, 1))) == family, \
                f"{kind}: fill {fill} is not a shade of {family}"
        else:
            assert _family(fill) == "grey", f"{kind}: fill {fill} is not grey"
    # a user tells them apart: every family has its own colours on the screen
    by_family = {}
    for kind, colours in seen.items():
        by_family.setdefault(EXPECTED[kind], set()).add(colours)
    flat = [c for cs in by_family.values() for c in cs]
    assert len({c for cs in by_family.values() for c in cs}) == len(by_family) and len(flat) == len(by_family)
