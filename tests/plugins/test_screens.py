"""PulseView and Wireshark, run under Xvfb on a capture with faults (tests/plugins/screens.py), show them as
issue 34 asks: the pixels of their windows are looked at. Skips where the programs are missing (Debian:
xvfb pulseview wireshark-qt imagemagick sigrok-cli)."""

from __future__ import annotations

import colorsys
import shutil
import subprocess
import sys
import types
from pathlib import Path

import pytest

np = pytest.importorskip("numpy", reason="the screenshots' pixels are read with numpy")

from rs30x_sniff.plugins import sigrok  # noqa: E402
from rs30x_sniff.plugins.maps import plugin_maps  # noqa: E402
from tests.plugins.screens import missing_programs, take  # noqa: E402

pytestmark = pytest.mark.skipif(bool(missing_programs()) or shutil.which("convert") is None,
                                reason=f"needs {', '.join(missing_programs() or ['convert'])} (apt-get install "
                                       "xvfb pulseview wireshark-qt imagemagick sigrok-cli)")


@pytest.fixture(scope="module")
def shots(tmp_path_factory) -> dict[str, Path]:
    return take(tmp_path_factory.mktemp("screens"))


def pixels(png: Path):
    """The PNG's pixels as an array (rows, columns, RGB), read through ImageMagick as a binary PPM."""
    ppm = subprocess.run(["convert", str(png), "ppm:-"], capture_output=True, check=True).stdout
    magic, size, depth, data = ppm.split(b"\n", 3)
    assert magic == b"P6" and depth == b"255"
    w, h = (int(x) for x in size.split())
    return np.frombuffer(data, np.uint8)[:w * h * 3].reshape(h, w, 3)


# ---- PulseView ------------------------------------------------------------------------------------------
def decoder_classes() -> tuple[dict[str, int], dict[str, int]]:
    """Our decoder's annotation classes: name -> index, and name -> index of its row (as PulseView reads them)."""
    stub = types.ModuleType("sigrokdecode")
    stub.Decoder = object
    ns: dict = {}
    saved = sys.modules.get("sigrokdecode")
    sys.modules["sigrokdecode"] = stub
    try:
        files = sigrok.generate(plugin_maps())
        pd = files[f"{sigrok.PACKAGE}/pd.py"].replace("from .core import Core", "Core = None").replace(
            "from .maps import MAPS", "MAPS = " + files[f"{sigrok.PACKAGE}/maps.py"].split("MAPS = ", 1)[1])
        exec(compile(pd, "pd.py", "exec"), ns)
    finally:
        if saved is None:
            sys.modules.pop("sigrokdecode", None)
        else:
            sys.modules["sigrokdecode"] = saved
    dec = ns["Decoder"]
    index = {name: k for k, (name, _) in enumerate(dec.annotations)}
    row = {dec.annotations[c][0]: r for r, (_, _, classes) in enumerate(dec.annotation_rows) for c in classes}
    return index, row


def fill_hues(img) -> list[tuple[int, dict[int, int]]]:
    """Each band of annotation rows, top to bottom: (first row y, {hue in degrees: pixels}). PulseView fills an
    annotation with one saturation and lightness (its channels span 0x6E..0xE6), only the hue varies."""
    flat = img.reshape(-1, 3).astype(int)
    fill = (flat.max(axis=1) == 0xE6) & (flat.min(axis=1) == 0x6E)
    rgb = flat / 255.0
    hue = np.array([round(colorsys.rgb_to_hsv(*p)[0] * 360) % 360 if f else -1 for p, f in zip(rgb, fill)])
    hue = hue.reshape(img.shape[:2])
    bands, current = [], None
    for y in range(hue.shape[0]):
        row = hue[y][hue[y] >= 0]
        if len(row) < 20:
            current = None
            continue
        if current is None:
            current = (y, {})
            bands.append(current)
        for h in row:
            current[1][int(h)] = current[1].get(int(h), 0) + 1
    return bands


def has_hue(hues: dict[int, int], want: float, slack: int = 4) -> bool:
    return any(min(abs(h - want) % 360, 360 - abs(h - want) % 360) <= slack and n >= 30 for h, n in hues.items())


def check_pulseview(png: Path, shown: list[str]) -> None:
    index, row = decoder_classes()
    img = pixels(png)
    bands = fill_hues(img)
    assert len(bands) >= 4, "the UART rows, and our three rows below them"
    packets, fields, warnings = (b[1] for b in bands[-3:])
    # The decoder's hue: that of the first request (the leftmost fill of the packets row).
    y0 = bands[-3][0] + 3
    x = next(x for x in range(img.shape[1]) if max(img[y0, x]) == 0xE6 and min(img[y0, x]) == 0x6E)
    base = colorsys.rgb_to_hsv(*(img[y0, x] / 255.0))[0] * 360
    band = {0: packets, 1: fields, 2: warnings}

    def hue(name: str) -> float:
        return (base + 20 * row[name] + 55 * index[name]) % 360

    for name in shown:
        assert has_hue(band[row[name]], hue(name)), (name, hue(name), sorted(band[row[name]]))

    def apart(a: str, b: str) -> float:
        d = abs(hue(a) - hue(b)) % 360
        return min(d, 360 - d)

    # What issue 34 saw: a bad sum coloured as a good one, a warning as a return packet.
    assert apart("bad-sum", "checksum") >= 90 and apart("error", "return") >= 90
    assert apart("warning", "return") >= 90 and apart("error", "warning") >= 45 and apart("no-reply", "error") >= 45


def test_pulseview_shows_a_bad_sum_and_a_missing_reply_in_their_own_colours(shots):
    check_pulseview(shots["pulseview"], ["request", "return", "header", "register", "checksum", "bad-sum",
                                         "error", "no-reply"])


def test_pulseview_at_a_wider_zoom_shows_the_warning_and_the_garbage(shots):
    check_pulseview(shots["pulseview-overview"], ["request", "return", "bad-sum", "error", "no-reply", "warning"])


# ---- Wireshark ------------------------------------------------------------------------------------------
def rgb16(r: int, g: int, b: int) -> tuple[int, int, int]:
    """A colorfilters colour (16-bit channels) as the 8-bit pixel Qt draws."""
    return r >> 8, g >> 8, b >> 8


def count(img, colour: tuple[int, int, int]) -> int:
    return int(np.all(img == np.array(colour, np.uint8), axis=2).sum())


def test_wireshark_colours_the_bad_sum_red_and_the_alarm_yellow_as_its_own_rules_do(shots):
    img = pixels(shots["wireshark"])
    background = rgb16(4718, 10030, 11796)
    error_text, warning_text = rgb16(63479, 34695, 34695), rgb16(65535, 64764, 40092)
    rows = count(img, background) / img.shape[1]
    # Three coloured rows (the bad sum, the temperature alarm, the noise), each about 15 pixels high.
    assert 30 <= rows <= 60, rows
    assert count(img, error_text) > 100 and count(img, warning_text) > 100
