"""Packet structure (P) and servo status (S) findings carry typed parameters: a Message whose key survives
another recording of the same behaviour (times shifted and scaled, the servo's status bits changed), and
whose text is the text these rules always wrote."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rs30x_sniff.lint.params import Message, key_of
from rs30x_sniff.protocol.wire import (
    RETURN_FLAGS_RESERVED, RETURN_HEADER, checksum, encode_read, encode_return, encode_short)

from .helpers import CAPTURES, lint_chunks, parse

# What each rule's capture under captures/lint said before its messages were made from parameters
# (lint --format json of each capture, taken before the change): the text must not move.
TEXTS = {
    "P001": ["flag 0x80 sets reserved bit 7"],
    "P002": ["long packet with flag 0x40 (must be 0)"],
    "P003": ["long packet with Length 1 and Count 0 writes nothing",
             "long packet with Length 1 and Count 2 writes nothing"],
    "P004": ["VID 1 appears more than once"],
    "P005": ["ID 200 outside 1-127 (255 is broadcast)", "VID 128 outside 1-127"],
    "P006": ["short write with Length 1 and Count 2 (Count must be 1)", "flag-0F read with Count 1 (must be 0)"],
    "P007": ["return mode 0010 is not in table 4.3"],
    "P008": [("flash command with Address 07, Count 1, Length 1, 1 data byte(s) (expected Address FF, Length 0, "
              "Count 0, no data)"),
             "reboot command with Address 00 (expected Address FF, Length 0, Count 0, no data)"],
    "P009": ["flash write and reboot in one packet; send the reboot separately, after the flash write"],
    "P010": ["broadcast packet asks every servo for a return"],
    "P011": ["read of 128-143 goes past address 139", "read of length 0"],
    "P012": ["return with Count 2 (always 1)"],
    "P013": ["return flags 0x40 set reserved bit(s) 0x40"],
    "S001": ["ID 1 passed its temperature limit and cut torque (a reboot clears it)"],
    "S002": ["ID 1 is within 10 degC of its temperature limit"] * 2,
    "S003": ["ID 1 failed to write its flash ROM"],
    "S004": ["ID 1 received a packet it could not accept"],
}
CODES = sorted(TEXTS)
_STATUS_BITS = 0xFF & ~RETURN_FLAGS_RESERVED  # table 4.4's status bits 7, 5, 3, 1


def _frames(code: str) -> list[bytes]:
    """The rule's capture, one frame a line."""
    (path,) = (CAPTURES / "lint").glob(f"{code}-*.hex")
    frames = []
    for line in path.read_text().splitlines():
        toks = line.partition("#")[0].split()
        if toks:
            frames.append(bytes.fromhex("".join(toks)))
    return frames


def _timed(frames: list[bytes], t0: float, gap: float) -> list[tuple[bytes, float]]:
    return [(f, t0 + i * gap) for i, f in enumerate(frames)]


def _messages(chunks, code: str) -> list:
    return [f.message for f in lint_chunks(chunks).findings if f.code == code]


def _with_status(frame: bytes, bits: int) -> bytes:
    """A return frame with ``bits`` added to its flags, its Sum made again."""
    if not frame.startswith(RETURN_HEADER):
        return frame
    body = bytearray(frame[2:-1])
    body[1] |= bits
    return RETURN_HEADER + bytes(body) + bytes((checksum(body),))


@pytest.mark.parametrize("code", CODES)
def test_text_is_unchanged_and_typed(code):
    path = next((CAPTURES / "lint").glob(f"{code}-*.hex"))
    msgs = _messages(parse(path.read_text())[0], code)
    assert [str(m) for m in msgs] == TEXTS[code]
    assert all(isinstance(m, Message) for m in msgs)


@pytest.mark.parametrize("code", CODES)
def test_key_survives_another_recording(code):
    frames = _frames(code)
    untimed = _messages([(b"".join(frames), None)], code)
    base = _messages(_timed(frames, 1000.0, 0.010), code)
    # shifted by an hour and a bit, slower by 7 %: the same behaviour recorded again
    other = _messages(_timed(frames, 4600.123, 0.0107), code)
    keys = [key_of(m) for m in untimed]
    assert None not in keys
    assert [key_of(m) for m in base] == keys
    assert [key_of(m) for m in other] == keys
    # the servo's status bits (what P013's flags byte measures) changed: still the same finding
    if code == "P013":
        hot = _messages(_timed([_with_status(f, 0x20) for f in frames], 1000.0, 0.010), code)
        assert [str(m) for m in hot] == ["return flags 0x60 set reserved bit(s) 0x40"]
        assert [key_of(m) for m in hot] == keys


def test_p013_key_masks_only_the_whole_flags_byte():
    (msg,) = _messages(parse(next((CAPTURES / "lint").glob("P013-*.hex")).read_text())[0], "P013")
    assert key_of(msg) == "return flags 0x* set reserved bit(s) 0x40"


@pytest.mark.parametrize("code", [c for c in CODES if c != "P013"])
def test_header_fields_stay_in_the_key(code):
    """What these rules name is what the host sent (flag, Length, Count, Address, IDs): nothing measured."""
    path = next((CAPTURES / "lint").glob(f"{code}-*.hex"))
    for m in _messages(parse(path.read_text())[0], code):
        assert key_of(m) == str(m)


def test_branches_no_capture_shows():
    """P005 for a return, P010 for an ACK: the same texts the f-strings wrote."""
    p005 = _messages([(encode_read(1, 0x2A, 2) + encode_return(0, 0x2A, b"\x84\x03"), None)], "P005")
    assert [str(m) for m in p005] == ["return from ID 0, outside 1-127"]
    p010 = _messages([(encode_short(255, 0x01, 0x1E, b"\x84\x03"), None)], "P010")
    assert [str(m) for m in p010] == ["broadcast packet asks every servo for an ACK"]
    assert all(isinstance(m, Message) for m in p005 + p010)


@settings(max_examples=40, deadline=None)
@given(status=st.integers(0, 255).map(lambda b: b & _STATUS_BITS),
       reserved=st.integers(1, 255).map(lambda b: b & RETURN_FLAGS_RESERVED).filter(bool),
       t0=st.floats(0.0, 1e6), gap=st.floats(0.004, 0.05))
def test_p013_family(status, reserved, t0, gap):
    """Any status bits, any clock: P013's key names only the reserved bits; the text is the f-string's."""
    flags = status | reserved
    frames = [encode_read(1, 0x2A, 2), encode_return(1, 0x2A, b"\x84\x03", flags=flags)]
    (msg,) = _messages(_timed(frames, t0, gap), "P013")
    assert str(msg) == f"return flags 0x{flags:02X} set reserved bit(s) 0x{reserved:02X}"
    assert key_of(msg) == f"return flags 0x* set reserved bit(s) 0x{reserved:02X}"


@settings(max_examples=25, deadline=None)
@given(code=st.sampled_from(CODES), t0=st.floats(0.0, 1e6), scale=st.floats(0.5, 2.0))
def test_keys_ignore_the_clock(code, t0, scale):
    """Every rule's capture at any start time and any pace: the same keys as untimed."""
    frames = _frames(code)
    keys = [key_of(m) for m in _messages([(b"".join(frames), None)], code)]
    assert [key_of(m) for m in _messages(_timed(frames, t0, 0.010 * scale), code)] == keys
