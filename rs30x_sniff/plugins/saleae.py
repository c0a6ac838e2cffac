"""The Saleae Logic 2 High Level Analyzer: an 'RS30x' extension on the Async Serial analyzer, made from the maps.

The extension is a folder of three files: ``extension.json`` (Logic 2's manifest, Saleae's "Extension File Format":
name, apiVersion 1.0.0, author, version, description, and one HighLevelAnalyzer entry point), ``HighLevelAnalyzer.py``
(one self-contained module: rs30x_sniff/plugins/pycore.py verbatim, the maps as a ``MAPS = {...}`` literal from
:func:`~rs30x_sniff.plugins.maps.py_literal`, and the analyzer class, a fixed text written here) and ``README.md``.
No name, unit or label of a map is ever written into code: they reach the analyzer only inside MAPS, so a hostile
map can only be data.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from .maps import py_literal
from ..version import __version__

MODULE = "HighLevelAnalyzer"  # the entry point's file (without .py) and class: "HighLevelAnalyzer.Rs30x"
CLASS = "Rs30x"
EXTENSION = "RS30x"            # the analyzer's name in Logic 2's "Add Analyzer" list

HEADER = """\
# RS30x (Futaba command-type servo bus): a High Level Analyzer for Saleae Logic 2.
# Written by `rs30x-sniff plugin saleae`: write it again rather than editing it.
# SPDX-License-Identifier: MIT
#
# Three parts: the decoding core of rs30x-sniff (a copy of rs30x_sniff/plugins/pycore.py), the memory maps as one
# literal (MAPS), and the Logic 2 analyzer (class Rs30x, at the end).

from saleae.analyzers import AnalyzerFrame, ChoicesSetting, HighLevelAnalyzer, NumberSetting

"""

# The analyzer class: fixed text, nothing of the maps in it (they are read from MAPS as it runs).
ANALYZER = '''

# ---- the Logic 2 analyzer ---------------------------------------------------------------------------------
# Every model a user may name: each map's own name, then another name of a map (also_named) once.
MODEL_NAMES = tuple(m["name"] for m in MAPS["models"])
MODEL_NAMES += tuple(sorted(set(n for m in MAPS["models"] for n in m.get("also_named") or () if n not in MODEL_NAMES)))
BITS_PER_BYTE = 10   # 8N1: start, 8 data bits, stop (manual table 4.7)
FRAME_BITS = 9.5     # an Async Serial frame runs from the start bit to the middle of the stop bit
GAP_BYTES = 20       # the idle gap that cuts a frame when the setting is 0: rs30x-sniff's own default
KIND_WORDS = {"short": "REQ", "long": "LONG", "return": "RET", "ack": "ACK", "nack": "NACK", "garbage": "GARBAGE"}
UART_ERRORS = (("fram", "framing-error"), ("parit", "parity-error"))


def uart_error(text):
    """The reason of a byte the Async Serial analyzer flagged, in rs30x-sniff's words."""
    low = str(text).lower()
    for key, reason in UART_ERRORS:
        if key in low:
            return reason
    return "uart-error"


def summary(f):
    """One line of text for the bubble: the ID, each shown field as label=value, the flags and warnings."""
    parts = [KIND_WORDS.get(f.kind, f.kind.upper())]
    if f.kind == "garbage":
        return "%s %dB %s" % (parts[0], len(f.raw), f.reason)
    if f.id is not None and f.kind != "long":
        parts.append("id=%d" % f.id)
    for x in f.fields:
        if x["name"] is not None or x["raw_value"] != 0:  # reserved bytes only when they carry something
            label = x["label"] if f.kind != "long" else "%d:%s" % (x["id"], x["label"])
            parts.append("%s=%s" % (label, x["text"]))
    parts += f.flags
    parts += [w for w in f.warnings if w not in f.flags]
    return " ".join(parts)


def field_key(f, x):
    """A field's column: its register's label (with the servo's VID in a long packet)."""
    return x["label"] if f.kind != "long" else "%d:%s" % (x["id"], x["label"])


class Rs30x(HighLevelAnalyzer):
    """RS30x packets from the bytes of an Async Serial analyzer (8N1, LSB first, at the bus rate)."""

    model = ChoicesSetting(choices=MODEL_NAMES, label="Servo model (until a servo returns its model number)")
    gap = NumberSetting(min_value=0, max_value=60000, label="Idle gap that ends a frame, in ms (0: 20 byte times)")

    # One bubble per packet: its summary (the data table shows every column).
    result_types = {
        "short": {"format": "{{data.summary}}"},
        "long": {"format": "{{data.summary}}"},
        "return": {"format": "{{data.summary}}"},
        "ack": {"format": "{{data.summary}}"},
        "nack": {"format": "{{data.summary}}"},
        "garbage": {"format": "{{data.summary}}"},
    }

    def __init__(self):
        self.core = None    # made at the first byte, when the byte time is known
        self.t0 = None      # the first byte's start: positions are seconds from it
        self.times = {}     # input offset of a byte -> (start_time, end_time) of its Async Serial frame
        self.offset = 0

    def _make_core(self, byte_time):
        model = getattr(self, "model", None)
        model = model if model in MODEL_NAMES else None
        try:
            gap_ms = float(getattr(self, "gap", 0) or 0)
        except (TypeError, ValueError):
            gap_ms = 0.0
        gap = gap_ms / 1000.0 if gap_ms > 0 else GAP_BYTES * byte_time
        return Core(MAPS, model, gap=gap)

    def decode(self, frame):
        if frame.type != "data":
            return None
        data = frame.data.get("data", b"")
        if isinstance(data, int):
            data = bytes((data & 0xFF,))
        if self.t0 is None:
            self.t0 = frame.start_time
        start = float(frame.start_time - self.t0)
        row = float(frame.end_time - frame.start_time)
        byte_time = row * BITS_PER_BYTE / FRAME_BITS if row > 0 else 0.0
        if self.core is None:
            self.core = self._make_core(byte_time)
        out = self.core.idle(start)  # a gap before this byte ends what was pending
        error = frame.data.get("error")
        for b in bytearray(data):
            self.times[self.offset] = (frame.start_time, frame.end_time)
            self.offset += 1
            if error:
                out += self.core.feed_flagged(b, start, start + byte_time, uart_error(error))
            else:
                out += self.core.feed(b, start, start + byte_time)
        return [self._result(f) for f in out] or None

    def flush(self):
        """What is still pending (Logic 2 says nothing at the end of a capture: a last cut frame waits)."""
        if self.core is None:
            return []
        return [self._result(f) for f in self.core.flush()]

    def _result(self, f):
        first = self.times.pop(f.offset)
        last = first
        for k in range(f.offset + 1, f.offset + len(f.raw)):
            last = self.times.pop(k)
        data = {"summary": summary(f), "raw": " ".join("%02X" % b for b in f.raw)}
        if f.direction is not None:
            data["direction"] = f.direction
        for key in ("id", "flag", "address", "length", "count", "model", "reason"):
            value = getattr(f, key)
            if value is not None:
                data[key] = value
        if f.kind != "garbage":
            data["checksum"] = "ok" if f.checksum_ok else "bad"
        data["flags"] = ", ".join(f.flags)
        data["warnings"] = ", ".join(f.warnings)
        for x in f.fields:
            key = field_key(f, x)
            if key in data:
                key = "%s (register)" % key
            data[key] = x["text"]
        return AnalyzerFrame(f.kind, first[0], last[1], data)
'''

README = """\
# RS30x High Level Analyzer for Saleae Logic 2

Decodes the Futaba RS30x command-type servo bus (RS301CR, RS303MR, RS304MD, ...) on top of Logic 2's
Async Serial analyzer: short and long packets from the host, return packets, ACK and NACK, with the memory
map's register names, scaled values and units. Written by `{generator}` (`rs30x-sniff plugin saleae`);
write it again rather than editing it.

## Install

In Logic 2, open the Extensions panel (the puzzle-piece button on the right), click its "three dots" menu,
choose **Load Existing Extension...** and select this folder's `extension.json`.

## Use

1. Add an **Async Serial** analyzer on the bus wire: the bus rate (115200 bit/s unless the servos were set to
   another, manual table 4.7), 8 bits, 1 stop bit, no parity, LSB first, non-inverted.
2. Add the **{extension}** analyzer and choose that Async Serial analyzer as its input.
3. Settings: **Servo model** decodes every servo as that map until a servo returns its model number (then that
   servo's own map); **Idle gap** (ms) is the silence that ends a frame early (a cut frame); 0 means 20 byte
   times, measured from the bytes.

Each packet is one bubble (`REQ id=1 goal_position=90.0deg ...`); the data table has its direction, id, flag,
address, length, count, checksum (ok/bad), flags, warnings and one column per register it carries. A frame is
shown when its last byte is seen; Logic 2 tells an analyzer nothing at the end of a capture, so a frame cut by
the end stays unshown.

Memory maps: {models}.
"""


def core_source() -> str:
    """The standalone core, as the plug-in carries it."""
    return Path(__file__).with_name("pycore.py").read_text(encoding="utf-8")


def generate(maps: dict[str, Any]) -> dict[str, str]:
    """The extension's files (relative path -> text) for ``maps`` (rs30x_sniff.plugins.maps.plugin_maps)."""
    manifest = {
        "name": "RS30x servo bus",
        "apiVersion": "1.0.0",
        "author": "rs30x-sniff",
        "version": __version__,
        "description": "Futaba RS30x servo bus packets with named, scaled registers, on the Async Serial analyzer",
        "extensions": {EXTENSION: {"type": "HighLevelAnalyzer", "entryPoint": f"{MODULE}.{CLASS}"}},
    }
    source = HEADER + core_source() + "\n\n# The memory maps and the wire's constants (data only).\nMAPS = " \
        + py_literal(maps) + "\n" + ANALYZER
    models = ", ".join(f"`{m['name']}`" for m in maps["models"])
    return {
        "extension.json": json.dumps(manifest, indent=2) + "\n",
        f"{MODULE}.py": source,
        "README.md": README.format(generator=maps["generator"], extension=EXTENSION, models=models),
    }


def install_hint(out: Path) -> str:
    return (f"wrote the Logic 2 extension {out}/ (analyzer {EXTENSION!r})\n"
            f"install: Logic 2 > Extensions panel > the three-dots menu > Load Existing Extension... > "
            f"{out.resolve() / 'extension.json'}\n"
            "use: add an Async Serial analyzer on the bus (8N1, LSB first, the bus rate), "
            f"then add {EXTENSION!r} on it")
