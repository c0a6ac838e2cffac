"""Framing (F001-F007), time-base (F005, F006, F010) and memory-map (M) findings carry typed parameters: a
Message whose key survives another recording of the same behaviour (times shifted and scaled, another
number of stray bytes, another corrupted Sum, another out-of-range value), and whose text is the text
these rules always wrote."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rs30x_sniff.lint import LintConfig
from rs30x_sniff.lint.params import Message, key_of
from rs30x_sniff.protocol.wire import encode_short
from rs30x_sniff.sim import run
from rs30x_sniff.sim.wire import retime

from .helpers import CAPTURES, lint_chunks, parse

# What each rule's capture under captures/lint said before its messages were made from parameters
# (lint --format json of each capture, taken before the change): the text must not move.
TEXTS = {
    "F001": ["Sum is 0x9C but the bytes from ID on XOR to 0x9B", "Sum is 0x00 but the bytes from ID on XOR to 0xAF"],
    "F002": ["3 byte(s) with no frame header"],
    "F003": ["frame cut short after 7 byte(s)"],
    "F004": ["0.753 ms (8.7 byte times) of idle line inside the frame"],
    "F005": ["the capture's clock goes backwards 2 times: first here, stamped 0.095000 s, 5.694 ms before the "
             "previous bytes ended (held at the previous chunk's time, so no time runs backwards)"],
    "F006": ["1 chunk stamped before the bytes ahead could have crossed the wire at 115200 bit/s (first here, "
             "368 us early): are the times each read's arrival (--time-ref arrival), or is the baud rate another?"],
    "F007": ["no valid frame in 73 bytes read at 115200 bit/s: is the bus at another rate? The bytes alone cannot "
             "tell which; try --baud auto on a port, or the other rates of table 4.7 (9600, 14400, 19200, 28800, "
             "38400, 57600, 76800, 153600, 230400)"],
    "F010": ["the capture's clock restarts here (stamped 0.000000 s, 3.001 s back): a new time segment begins"],
    "M001": ["writes read-only present_position of ID 1", "writes read-only model_number of ID 1",
             "writes read-only temperature_limit of ID 1"],
    "M002": ["writes reserved_16, reserved_17 of ID 1", "writes reserved_34 of ID 1"],
    "M003": ["max_torque=120 (raw) on ID 1 outside 0-100", "baud_rate=12 (raw) on ID 1 outside 0-9",
             "goal_position=1600 (raw) on ID 1 outside -1500-1500 (160.0deg)",
             "goal_time=20000 (raw) on ID 2 outside 0-16383 (200.0s)", "servo_id=0 (raw) on ID 1 outside 1-127"],
    "M004": ["writes only goal_position (high byte) of ID 1", "writes only goal_position (low byte) of IDs 1, 2"],
    "M005": ["ID 1 reports model number 0x300C, which no memory map knows (0x2040 RS204MD, 0x3010 RS301CR, 0x3020 RS302CD, "
             "0x3030 RS303MR, 0x3040 RS304MD, RS405CB, RS406CB by --model only); "
             "decoding it with the RS303MR map instead",
             "ID 3 reports model number 0x300C, which no memory map knows (0x2040 RS204MD, 0x3010 RS301CR, 0x3020 RS302CD, "
             "0x3030 RS303MR, 0x3040 RS304MD, RS405CB, RS406CB by --model only); "
             "decoding it with the RS303MR map instead"],
}
CODES = sorted(TEXTS)
# Rules whose messages hold nothing this recording measured: the key is the text.
NAMES_ONLY = ("M001", "M002", "M004", "M005")


def _capture(code: str) -> str:
    (path,) = (CAPTURES / "lint").glob(f"{code}-*.*hex")
    return path.read_text()


def _lines(text: str) -> list[tuple[bytes, float | None]]:
    """A capture one line a chunk (an untimed one too: its frames as they were written)."""
    out = []
    for line in text.splitlines():
        toks = line.partition("#")[0].split()
        if toks:
            t = float(toks.pop(0)) if "." in toks[0] else None
            out.append((bytes.fromhex("".join(toks)), t))
    return out


def _recorded(lines, shift: float, scale: float, gap: float = 0.010):
    """The same bytes recorded again: its times shifted and scaled (an untimed capture gets a line every
    ``gap`` seconds, scaled too)."""
    return [(d, shift + scale * (i * gap if t is None else t)) for i, (d, t) in enumerate(lines)]


def _messages(chunks, code: str, config: LintConfig | None = None) -> list:
    return [f.message for f in lint_chunks(chunks, config).findings if f.code == code]


def _keys(msgs) -> list:
    return [key_of(m) for m in msgs]


@pytest.mark.parametrize("code", CODES)
def test_text_is_unchanged_and_typed(code):
    msgs = _messages(parse(_capture(code))[0], code)
    assert [str(m) for m in msgs] == TEXTS[code]
    assert all(isinstance(m, Message) for m in msgs)


@pytest.mark.parametrize("code", CODES)
def test_key_survives_another_recording(code):
    lines = _lines(_capture(code))
    base = _messages(_recorded(lines, 0.0, 1.0), code)
    # an hour and a bit later, the clock 1.3 % fast: the same behaviour recorded again
    other = _messages(_recorded(lines, 4600.123, 1.013), code)
    assert base and None not in _keys(base)
    assert _keys(other) == _keys(base)
    assert all(isinstance(m, Message) for m in other)
    if code in NAMES_ONLY:
        assert _keys(base) == [str(m) for m in base]
    else:
        assert all("*" in k for k in _keys(base))
    if code in ("F004", "F005", "F006", "F010"):
        assert [str(m) for m in other] != [str(m) for m in base]  # what they measure moved; the key did not


def test_keys_mask_what_was_measured():
    def key(code):
        return _keys(_messages(parse(_capture(code))[0], code))
    assert key("F001") == ["Sum is 0x* but the bytes from ID on XOR to 0x*"] * 2
    assert key("F002") == ["* byte(s) with no frame header"]
    assert key("F004") == ["* ms (* byte times) of idle line inside the frame"]
    assert key("F005") == ["the capture's clock goes backwards *: first here, stamped * s, * ms before the previous "
                           "bytes ended (held at the previous chunk's time, so no time runs backwards)"]
    assert key("F006")[0].startswith("* stamped before the bytes ahead could have crossed the wire at 115200 bit/s "
                                     "(first here, * us early)")
    assert key("F007")[0].startswith("no valid frame in * bytes read at 115200 bit/s: ")
    assert key("F010") == ["the capture's clock restarts here (stamped * s, * s back): a new time segment begins"]
    assert key("M003")[2:4] == ["goal_position=* (raw) on ID 1 outside -1500-1500 (*)",
                                "goal_time=* (raw) on ID 2 outside 0-16383 (*)"]


def _edit(code: str, old: str, new: str) -> list[tuple[bytes, float | None]]:
    text = _capture(code)
    assert text.count(old) == 1
    return parse(text.replace(old, new))[0]


def test_another_corrupted_sum_is_the_same_f001():
    # the bad Sums off by other bits: other hex in the text, the same finding
    chunks = _edit("F001", "FA AF 01 00 1E 02 01 84 03 9C", "FA AF 01 00 1E 02 01 84 03 A7")
    chunks = [(d.replace(bytes.fromhex("FDDF0100 2A020184 0300"), bytes.fromhex("FDDF0100 2A020184 0311")), t)
              for d, t in chunks]
    msgs = _messages(chunks, "F001")
    assert [str(m) for m in msgs] == ["Sum is 0xA7 but the bytes from ID on XOR to 0x9B",
                                      "Sum is 0x11 but the bytes from ID on XOR to 0xAF"]
    assert _keys(msgs) == _keys(_messages(parse(_capture("F001"))[0], "F001"))


@pytest.mark.parametrize("code, old, new, text", [
    ("F002", "00 55 AA", "00 55 AA 01 02", "5 byte(s) with no frame header"),
    ("F003", "0.010000 FA AF 02 00 1E 02 01", "0.010000 FA AF 02 00 1E 02", "frame cut short after 6 byte(s)"),
    ("F004", "0.011100 1E", "0.011500 1E", "1.153 ms (13.3 byte times) of idle line inside the frame"),
])
def test_another_measurement_is_the_same_finding(code, old, new, text):
    msgs = _messages(_edit(code, old, new), code)
    assert [str(m) for m in msgs] == [text]
    assert _keys(msgs) == _keys(_messages(parse(_capture(code))[0], code))


def test_once_and_three_times_are_one_key():
    """F005 counts in words ("once", "3 times") and F006 with its noun's plural: the key masks the count."""
    base = _keys(_messages(parse(_capture("F005"))[0], "F005"))
    once = _messages(_edit("F005", "0.196000 FA AF 02", "0.300000 FA AF 02"), "F005")
    thrice = _messages(parse(_capture("F005") + "0.195000 FA AF 03 00 1E 02 01 84 03 99\n")[0], "F005")
    assert "goes backwards once: first here" in once[0] and "goes backwards 3 times: first here" in thrice[0]
    assert _keys(once) == _keys(thrice) == base
    f006 = _keys(_messages(parse(_capture("F006"))[0], "F006"))
    two = _messages(parse(_capture("F006") + "0.010300 FA AF 04 00 1E 02 01 84 03 9E\n")[0], "F006")
    assert two[0].startswith("2 chunks stamped before the bytes ahead") and _keys(two) == f006


def test_more_stray_bytes_are_the_same_f007():
    extra = "3E 84 61 1E BC 08 0B 84 30 00 61 0D CE 09 0B B4 68 42 61 08 CA 09 0B E4\n"
    more = _messages(parse(_capture("F007") + extra)[0], "F007")
    assert len(more) == 1 and more[0].startswith("no valid frame in 97 bytes read at 115200 bit/s: ")
    assert _keys(more) == _keys(_messages(parse(_capture("F007"))[0], "F007"))  # 73 bytes there


def test_timed_wrong_rate_keeps_its_key_and_names_the_rate():
    """A timed capture of 115200 bit/s read at 57600: the span and the bytes' spacing are measured, the
    rate to try is the finding's advice and stays in the key."""
    chunks = list(retime(run("hexapod", baud=115200, duration=2.5), 115200, 57600))
    config = LintConfig(baud=57600)
    base = _messages(chunks, "F007", config)
    other = _messages([(d, 77.5 + 1.01 * t) for d, t in chunks], "F007", config)
    assert len(base) == 1 and isinstance(base[0], Message)
    assert base[0].params["span"] != other[0].params["span"] and _keys(base) == _keys(other)
    assert _keys(base)[0].startswith("no valid frame in * bytes (* s) read at 57600 bit/s: ")


def test_another_value_out_of_range_is_the_same_m003():
    frames = [encode_short(1, 0, 0x23, bytes((150,))), encode_short(1, 0, 0x06, bytes((13,))),
              encode_short(1, 0, 0x1E, (1700).to_bytes(2, "little", signed=True)),
              encode_short(2, 0, 0x1E, bytes.fromhex("8403") + (30000).to_bytes(2, "little")),
              encode_short(1, 0, 0x04, bytes((200,))), encode_short(1, 0, 0x23, bytes((100,)))]
    msgs = _messages([(b"".join(frames), None)], "M003")
    assert [str(m) for m in msgs] == [
        "max_torque=150 (raw) on ID 1 outside 0-100", "baud_rate=13 (raw) on ID 1 outside 0-9",
        "goal_position=1700 (raw) on ID 1 outside -1500-1500 (170.0deg)",
        "goal_time=30000 (raw) on ID 2 outside 0-16383 (300.0s)", "servo_id=200 (raw) on ID 1 outside 1-127"]
    assert _keys(msgs) == _keys(_messages(parse(_capture("M003"))[0], "M003"))


def test_an_unknown_model_number_is_named_in_the_key():
    """The model number tells which model the servo is, as a model's name would: another one is another finding."""
    other = _messages(parse(_capture("M005").replace("0C 30 3E", "0D 30 3F"))[0], "M005")
    assert other[0].startswith("ID 1 reports model number 0x300D,")
    assert key_of(other[0]) == str(other[0]) != _keys(_messages(parse(_capture("M005"))[0], "M005"))[0]


# ---- properties ---------------------------------------------------------------------------------
@settings(max_examples=60, deadline=None)
@given(shift=st.floats(0.0, 1e6), scale=st.floats(0.95, 1.05))
def test_clock_faults_keep_their_keys_whatever_the_time_base(shift, scale):
    """F004, F005, F006 and F010 at any start time and clock rate: the same keys, and never a negative figure."""
    for code in ("F004", "F005", "F006", "F010"):
        lines = _lines(_capture(code))
        msgs = _messages(_recorded(lines, shift, scale), code)
        assert _keys(msgs) == _keys(_messages(_recorded(lines, 0.0, 1.0), code)), code
        assert all(isinstance(m, Message) and " -" not in m for m in msgs)


_GOAL1, _GOAL2 = encode_short(1, 0, 0x1E, b"\x84\x03"), encode_short(2, 0, 0x1E, b"\x84\x03")
_NO_HEADER = st.integers(0, 255).filter(lambda b: b not in (0xFA, 0xFD))  # neither header's first byte


@settings(max_examples=60, deadline=None)
@given(noise=st.lists(_NO_HEADER, min_size=1, max_size=40), cut=st.integers(3, 9), timed=st.booleans())
def test_garbage_and_cut_frames_keep_their_keys(noise, cut, timed):
    """Any run of stray bytes is one F002 of one key; a frame cut anywhere is one F003 of one key."""
    chunks = [(_GOAL1, 0.0), (bytes(noise), 0.01), (_GOAL2[:cut], 0.02), (_GOAL2, 0.03)]
    if not timed:
        chunks = [(_GOAL1 + bytes(noise) + _GOAL2, None)]
    f002 = _messages(chunks, "F002")
    assert [str(m) for m in f002] == [f"{len(noise)} byte(s) with no frame header"]
    assert _keys(f002) == ["* byte(s) with no frame header"]
    if timed:
        f003 = _messages(chunks, "F003")
        assert [str(m) for m in f003] == [f"frame cut short after {cut} byte(s)"]
        assert _keys(f003) == ["frame cut short after * byte(s)"]


@settings(max_examples=60, deadline=None)
@given(torque=st.integers(101, 255), goal=st.integers(1501, 0x7FFF), sign=st.sampled_from((1, -1)))
def test_out_of_range_values_keep_their_keys(torque, goal, sign):
    goal *= sign
    frames = encode_short(1, 0, 0x23, bytes((torque,))) + encode_short(1, 0, 0x1E, goal.to_bytes(2, "little", signed=True))
    msgs = _messages([(frames, None)], "M003")
    assert str(msgs[0]) == f"max_torque={torque} (raw) on ID 1 outside 0-100"
    assert str(msgs[1]).startswith(f"goal_position={goal} (raw) on ID 1 outside -1500-1500 (")
    assert float(str(msgs[1]).rpartition("(")[2].removesuffix("deg)")) == pytest.approx(goal / 10)
    assert _keys(msgs) == ["max_torque=* (raw) on ID 1 outside 0-100",
                           "goal_position=* (raw) on ID 1 outside -1500-1500 (*)"]
