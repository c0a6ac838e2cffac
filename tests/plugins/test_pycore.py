"""The plug-ins' standalone core (rs30x_sniff/plugins/pycore.py) decodes as `rs30x-sniff decode --format jsonl` does."""

from __future__ import annotations

import ast
import contextlib
import io
import json
import sys
from functools import reduce
from operator import xor
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from rs30x_sniff.cli import build_parser, main
from rs30x_sniff.commands.common import open_input, settings_for
from rs30x_sniff.decode.framing import FrameDecoder
from rs30x_sniff.plugins import pycore
from rs30x_sniff.plugins.maps import plugin_maps
from rs30x_sniff.protocol.chunks import marks
from rs30x_sniff.protocol.wire import byte_time
from rs30x_sniff.sim import SCENARIOS

ROOT = Path(__file__).resolve().parents[2]
CAPTURES = sorted([*ROOT.glob("captures/*.hex"), *ROOT.glob("captures/*.thex"), *ROOT.glob("captures/lint/*")])
SEAM_GAP_S, SEAM_BACK_S = 10.0, 0.010  # rs30x_sniff.decode.framing SEAM_GAP_S / SEAM_BACK_S


def jsonl(path: Path) -> list[dict]:
    """`decode PATH --format jsonl` run in-process: one dict per event."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["decode", str(path), "--format", "jsonl", "--no-lint"]) == 0
    return [json.loads(line) for line in out.getvalue().splitlines()]


def core_frames(path: Path, maps: dict) -> list:
    """The core fed each byte of ``path`` as our decoder reads it: with its time where the capture has one
    (gap = gap_bytes byte times at the capture's rate), else with its index as position."""
    args = build_parser().parse_args(["decode", str(path)])
    s = settings_for(args, str(path))
    opts = s.decode_options()
    bt = byte_time(s.baud)
    chunks = list(open_input(str(path), None, s))
    timed = any(t is not None for _, t in chunks)
    core = pycore.Core(maps, s.default_model, gap=opts.gap_bytes * bt if timed else None,
                       seam=SEAM_GAP_S if timed else None, seam_back=SEAM_BACK_S if timed else None,
                       reply_timeout=opts.reply_timeout if timed else None)
    frames, offset, missing = [], 0, []
    for chunk in chunks:
        data, t = chunk
        error = marks(chunk)[1]
        for k, b in enumerate(data):
            start = t + k * bt if t is not None else offset
            end = start + (bt if t is not None else 1)
            frames += core.feed(b, start, end) if error is None else core.feed_flagged(b, start, end, error)
            missing += core.take_no_replies()
            offset += 1
    frames += core.flush()
    missing += core.take_no_replies()
    assert missing == [f for f in frames if f.status == "missing"]  # handed out once each, in order
    return frames


def value(v):
    return round(v, 6) if isinstance(v, float) else v


def as_jsonl(f: pycore.Frame) -> dict:
    """The parts of a Frame that `decode --format jsonl` also says, in its words."""
    d = {"type": f.kind, "offset": f.offset, "raw": f.raw.hex(), "checksum_ok": f.checksum_ok, "id": f.id,
         "flag": f.flag, "address": f.address, "length": f.length, "count": f.count, "flags": f.flags,
         "model": f.model,
         "fields": [{"id": x["id"], "address": x["address"], "name": x["name"], "raw": x["raw"],
                     "value": value(x["value"]), "unit": x["unit"],
                     **({"partial": x["partial"]} if x["partial"] else {})}
                    for x in f.fields]}
    if f.kind == "garbage":
        d["reason"] = f.reason
    return d


def expected(ev: dict) -> dict:
    keys = ("type", "offset", "raw", "checksum_ok", "id", "flag", "address", "length", "count", "flags", "model",
            "fields") + (("reason",) if ev["type"] == "garbage" else ())
    return {k: ev[k] for k in keys}


@pytest.fixture(scope="module")
def maps() -> dict:
    return plugin_maps()


def check_same(path: Path, maps: dict) -> None:
    frames = core_frames(path, maps)
    events = jsonl(path)
    want = [expected(ev) for ev in events]
    got = [as_jsonl(f) for f in frames]
    for k, (g, w) in enumerate(zip(got, want)):
        assert g == w, f"{path.name}: event {k} differs"
    assert len(got) == len(want), f"{path.name}: {len(got)} frames, decode has {len(want)}"
    # decode's NO-REPLY (status "missing") on the same requests
    assert [f.offset for f in frames if f.status == "missing"] == \
           [ev["offset"] for ev in events if ev.get("status") == "missing"], path.name


@pytest.mark.parametrize("path", CAPTURES, ids=lambda p: p.name)
def test_core_decodes_each_capture_as_decode_does(path: Path, maps: dict) -> None:
    check_same(path, maps)


def test_core_decodes_each_scenario_as_decode_does(scenario_files: list[Path], maps: dict) -> None:
    assert len(scenario_files) == len(SCENARIOS) >= 8
    for path in scenario_files:
        check_same(path, maps)


def test_the_corpus_has_what_the_comparison_needs(scenario_files: list[Path]) -> None:
    """The differential tests above see every kind of event, the garbage reasons, bad sums and more than one
    model (capture-start garbage is left to the random tests below: no capture starts mid-frame)."""
    kinds, reasons, models, bad = set(), set(), set(), 0
    for path in [*CAPTURES, *scenario_files]:
        for ev in jsonl(path):
            kinds.add(ev["type"])
            reasons.add(ev.get("reason"))
            models.add(ev["model"])
            bad += ev["type"] != "garbage" and not ev["checksum_ok"]
    assert {"short", "long", "return", "ack", "nack", "garbage"} <= kinds
    assert {"noise", "truncated", "capture-end"} <= reasons
    assert {"RS303MR", "RS304MD"} <= models and bad
    missing = [p for p in [*CAPTURES, *scenario_files] if any(ev.get("status") == "missing" for ev in jsonl(p))]
    assert len(missing) >= 3  # NO-REPLY is compared on more than one capture


# ---- random input -----------------------------------------------------------------------------------
def frame_bytes(draw_ints: list[int], header: bytes) -> bytes:
    body = bytes(draw_ints)
    return header + body + bytes((reduce(xor, body, 0),))


@st.composite
def bus_bytes(draw) -> bytes:
    """Byte strings rich in what the framer decides on: headers, whole frames (some corrupt), ACK/NACK."""
    parts = []
    for _ in range(draw(st.integers(0, 12))):
        what = draw(st.integers(0, 5))
        if what == 0:
            parts.append(draw(st.binary(max_size=12)))
        elif what == 1:
            parts.append(bytes(draw(st.lists(st.sampled_from([0xFA, 0xAF, 0xFD, 0xDF, 0x07, 0x08, 0x01, 0x00]),
                                             max_size=8))))
        else:
            n = draw(st.integers(0, 6))
            header = b"\xfa\xaf" if what in (2, 3) else b"\xfd\xdf"
            sid = draw(st.sampled_from([0, 1, 2, 255]))
            flag = draw(st.sampled_from([0x00, 0x01, 0x0F, 0x03, 0x80]))
            count = draw(st.integers(0, 3)) if header == b"\xfa\xaf" else 1
            length = n if sid or header != b"\xfa\xaf" else n + 1
            data = draw(st.binary(min_size=length * count if header == b"\xfa\xaf" else n,
                                  max_size=length * count if header == b"\xfa\xaf" else n))
            raw = frame_bytes([sid, flag, draw(st.integers(0, 60)), length, count, *data], header)
            if draw(st.booleans()) and what == 3:
                raw = raw[:-1] + bytes((raw[-1] ^ 1,))  # a bad Sum
            parts.append(raw)
    return b"".join(parts)


BT = 0.001  # the random tests' byte time (10,000 bit/s): its silences stay far from the 10 s of a seam


def timed_feed(core: pycore.Core, data: bytes, starts: list[float], idles: list[float | None]) -> list:
    out = []
    for b, t, idle in zip(data, starts, idles):
        if idle is not None:
            out += core.idle(idle)
        out += core.feed(b, t, t + BT)
    return out + core.flush()


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=bus_bytes(), rnd=st.randoms(use_true_random=False))
def test_random_input_agrees_with_our_framer_with_or_without_idle_calls(data: bytes, rnd, maps: dict) -> None:
    """Positions are seconds, BT a byte; some bytes come after an idle gap longer than ``gap`` (20 BT): the
    core's frames equal our FrameDecoder's events, whether or not idle() is called during the gaps, and every
    byte lands in exactly one frame."""
    starts, t = [], 0.0
    for _ in data:
        t += BT * (1.0 if rnd.random() < 0.8 else rnd.choice([5.0, 21.5, 40.0]))
        starts.append(t)
    # idle(at) before a byte, at some moment of the silence before it (past the previous byte's end)
    idles = [None if k == 0 or rnd.random() < 0.5
             else starts[k - 1] + BT + rnd.random() * (starts[k] - starts[k - 1] - BT)
             for k in range(len(data))]
    plain = timed_feed(pycore.Core(maps, gap=20 * BT), data, starts, [None] * len(data))
    idled = timed_feed(pycore.Core(maps, gap=20 * BT), data, starts, idles)
    assert [(f.kind, f.offset, f.raw, f.reason, f.checksum_ok) for f in idled] == \
           [(f.kind, f.offset, f.raw, f.reason, f.checksum_ok) for f in plain]
    assert b"".join(f.raw for f in plain) == data
    assert [f.offset for f in plain] == [sum(len(g.raw) for g in plain[:k]) for k in range(len(plain))]
    # Our own framer, fed the same bytes one chunk each at the same times: the same events.
    dec = FrameDecoder(baud=10_000, gap_bytes=20.0, kernel=False)
    events = []
    for b, s in zip(data, starts):
        events += dec.feed(bytes((b,)), s)
    events += dec.close()
    assert [(f.kind, f.offset, f.raw, f.reason if f.kind == "garbage" else f.checksum_ok) for f in plain] == \
           [(e.kind, e.offset, e.raw, getattr(e, "reason", None) if e.kind == "garbage" else e.checksum_ok)
            for e in events]


@settings(max_examples=100, deadline=None)
@given(data=bus_bytes())
def test_untimed_input_agrees_with_our_framer(data: bytes, maps: dict) -> None:
    core = pycore.Core(maps)
    frames = []
    for k, b in enumerate(data):
        frames += core.feed(b, k, k + 1)
    frames += core.flush()
    dec = FrameDecoder(kernel=False)
    events = dec.feed(data) + dec.close()
    assert [(f.kind, f.offset, f.raw, f.reason if f.kind == "garbage" else f.checksum_ok) for f in frames] == \
           [(e.kind, e.offset, e.raw, getattr(e, "reason", None) if e.kind == "garbage" else e.checksum_ok)
            for e in events]
    for f in frames:  # positions: each byte's own, the frame's from its first to its last
        assert f.byte_positions == [(f.offset + k, f.offset + k + 1) for k in range(len(f.raw))]
        assert (f.start, f.end) == (f.offset, f.offset + len(f.raw))


def test_idle_ends_a_cut_frame_without_waiting_for_the_next_byte(maps: dict) -> None:
    core = pycore.Core(maps, gap=20 * BT)
    head = bytes.fromhex("faaf010f2a02")  # a read request cut after 6 of its 8 bytes
    got = [f for k, b in enumerate(head) for f in core.feed(b, k * BT, (k + 1) * BT)]
    assert got == [] and core.idle(len(head) * BT + 19 * BT) == []  # not idle long enough yet
    cut = core.idle(len(head) * BT + 21 * BT)
    assert [(f.kind, f.reason, f.raw) for f in cut] == [("garbage", "truncated", head)]
    assert "truncated" in cut[0].warnings and cut[0].direction is None
    assert core.flush() == []


# ---- the source ---------------------------------------------------------------------------------------
def test_source_is_python_38_and_imports_only_the_standard_library() -> None:
    src = Path(pycore.__file__).read_text(encoding="utf-8")
    tree = ast.parse(src, feature_version=(3, 8))
    imported = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imported |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, "a relative import: the plug-ins carry this file alone"
            imported.add(node.module.split(".")[0])
    assert imported and imported <= set(sys.stdlib_module_names), imported - set(sys.stdlib_module_names)
    # No annotation that 3.8 would evaluate as X | Y at run time (it has no __future__ import either way).
    assert not any(isinstance(n, ast.BinOp) and isinstance(n.op, ast.BitOr) and isinstance(n.left, ast.Name)
                   and n.left.id in ("str", "int", "float", "bytes", "list", "dict") for n in ast.walk(tree))


def test_core_runs_from_its_source_text_alone(maps: dict) -> None:
    """What the generators do: the source text run on its own namespace decodes with a literal of the maps."""
    from rs30x_sniff.plugins.maps import py_literal

    ns: dict = {}
    exec(compile(Path(pycore.__file__).read_text(encoding="utf-8") + "\nMAPS = " + py_literal(maps) + "\n",
                 "<plug-in>", "exec"), ns)
    core = ns["Core"](ns["MAPS"])
    raw = bytes.fromhex("fdbf") + bytes.fromhex("fddf0100 2a02 01 8403".replace(" ", ""))
    raw += bytes((reduce(xor, raw[4:], 0),))
    frames = [f for k, b in enumerate(raw) for f in core.feed(b, k, k + 1)] + core.flush()
    assert [f.kind for f in frames] == ["garbage", "return"]
    ret = frames[1]
    assert ret.direction == "servo" and ret.id == 1 and ret.checksum_ok
    assert [(x["name"], x["value"], x["unit"], x["start"], x["end"]) for x in ret.fields] == \
           [("present_position", 90.0, "deg", 9, 11)]
    assert ret.as_dict()["raw"] == raw[2:].hex()
