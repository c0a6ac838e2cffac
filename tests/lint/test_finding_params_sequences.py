"""The sequence rules (Q001-Q009, lint/rules/sequences.py) give typed parameters (issue 32 §4): each message is a
lint.params.Message whose key keeps what names the finding (servo IDs, registers, the model, a configured
limit) and masks what this recording measured (times, offsets, register values, counts), and whose text is
the one these rules wrote before they gave parameters."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rs30x_sniff.lint.params import Message, key_of
from rs30x_sniff.protocol.wire import encode_command, encode_short
from rs30x_sniff.sim import run as simulate

from .helpers import CAPTURES, lint_chunks

CODES = [f"Q00{i}" for i in range(1, 10)]

# Each capture's Q findings as the lint command wrote them before the rules gave typed parameters
# (lint --isolated --format json, the reference made before the change).
REFERENCE = {
    "lint/Q001-baud-change-not-applied.hex": [
        "baud_rate code 4 written to ID 2 but it was flashed but the servo was never rebooted: it keeps its old rate",
        "baud_rate code 9 written to ID 3 but no flash write followed: it keeps its old rate",
        ("a reboot of ID 4 before any flash write of the baud_rate code 4 written to ID 4 @51: the change is lost, "
         "it keeps its old rate"),
    ],
    "lint/Q002-id-change-not-persisted.hex": [
        "ID 2 changed to 6 but no flash write to ID 6 followed: it reverts at the next power-up",
        ("a reboot of ID 7 before any flash write undoes the change of ID 3 to 7 @42: the servo comes back on the "
         "ID in its flash, not 7"),
    ],
    "lint/Q003-reboot-too-soon-after-flash.thex": [
        "reboot 1.3 ms after the flash write @0; allow 100 ms (or wait for its ACK)",
    ],
    "lint/Q004-goal-while-torque-off.hex": [
        "goal_position 90.0deg to ID 1, whose torque is off",
        "goal_position 60.0deg to ID 1, whose torque is off",
    ],
    "lint/Q005-torque-on-with-goal.hex": [
        "torque on and goal_position 90.0deg in one packet to ID 1: the servo will not move",
    ],
    "lint/Q006-goal-beyond-angle-limit.hex": [
        "goal_position 120.0deg to ID 1 beyond its cw_angle_limit 100.0deg",
        "goal_position -60.0deg to ID 1 beyond its ccw_angle_limit -50.0deg",
    ],
    "lint/Q007-goal-time-too-fast.hex": [
        "90.0 deg in 100 ms on ID 1 asks 900 deg/s; RS303MR tops out at 545 deg/s",
    ] * 2,
    "lint/Q008-too-many-servos.hex": ["25 servo IDs on the bus; a TTL bus carries at most 24"],
    "lint/Q009-torque-on-after-temperature-limit.hex": [
        "torque on for ID 1, which tripped its temperature limit and was not rebooted since",
    ],
    "lint/M003-value-out-of-range.hex": [
        "baud_rate code 12 written to ID 1 but no flash write followed: it keeps its old rate",
        "ID 1 changed to 0 but no flash write to ID 0 followed: it reverts at the next power-up",
    ],
    "manual-examples.hex": [
        "goal_position 10.0deg to ID 1, whose torque is off",
        "ID 1 changed to 5 but no flash write to ID 5 followed: it reverts at the next power-up",
        "goal_position 90.0deg to ID 1, whose torque is off",
    ],
    "session-mixed.thex": [
        "108.3 deg in 50 ms on ID 2 asks 2166 deg/s; RS303MR tops out at 545 deg/s",
        "reboot 4.0 ms after the flash write @7501; allow 100 ms (or wait for its ACK)",
        "baud_rate code 9 written to ID 5 but no flash write followed: it keeps its old rate",
    ],
}

OVERHEAT = "torque on for ID 2, which tripped its temperature limit and was not rebooted since"

# The keys of the example captures' findings: what the measured values are masked out of.
KEYS = {
    "Q001": [
        "baud_rate code * written to ID 2 but it was flashed but the servo was never rebooted: it keeps its old rate",
        "baud_rate code * written to ID 3 but no flash write followed: it keeps its old rate",
        ("a reboot of ID 4 before any flash write of the baud_rate code * written to ID 4 @*: the change is lost, "
         "it keeps its old rate"),
    ],
    "Q002": [
        "ID 2 changed to 6 but no flash write to ID 6 followed: it reverts at the next power-up",
        ("a reboot of ID 7 before any flash write undoes the change of ID 3 to 7 @*: the servo comes back on the "
         "ID in its flash, not 7"),
    ],
    "Q003": ["reboot * the flash write @*; allow 100 ms (or wait for its ACK)"],
    "Q004": ["goal_position *deg to ID 1, whose torque is off"] * 2,
    "Q005": ["torque on and goal_position *deg in one packet to ID 1: the servo will not move"],
    "Q006": ["goal_position *deg to ID 1 beyond its cw_angle_limit *deg",
             "goal_position *deg to ID 1 beyond its ccw_angle_limit *deg"],
    "Q007": ["* deg in * ms on ID 1 asks * deg/s; RS303MR tops out at 545 deg/s"] * 2,
    "Q008": ["* servo IDs on the bus; a TTL bus carries at most 24"],
    "Q009": ["torque on for ID 1, which tripped its temperature limit and was not rebooted since"],
}


def frames(path) -> list[tuple[float | None, bytes]]:
    """A capture's frames, one a line (the bundled captures write them so), with their times if timed."""
    out = []
    for line in path.read_text().splitlines():
        toks = line.partition("#")[0].split()
        if toks:
            t = float(toks.pop(0)) if "." in toks[0] else None
            out.append((t, bytes.fromhex("".join(toks))))
    return out


def lint(fr, code=None):
    """The findings (of ``code``, or all) of the frames, fed as a reader gives them: one timed chunk per
    frame, or the untimed bytes as one stream."""
    if fr[0][0] is None:
        chunks = [(b"".join(d for _, d in fr), None)]
    else:
        chunks = [(d, t) for t, d in fr]
    found = sorted(lint_chunks(chunks).findings, key=lambda f: f.offset)  # in the reports' order
    return [f for f in found if code is None or f.code == code]


def example(code):
    return frames(next((CAPTURES / "lint").glob(f"{code}-*")))


def retimed(fr, shift=12.345, scale=1.07):
    """The same frames a little later and on a slightly faster clock (an untimed capture stays untimed)."""
    return [(None if t is None else shift + t * scale, d) for t, d in fr]


def prefixed(fr):
    """Two harmless writes first (goal_time to IDs 100 and 101): every offset moves, and two more servo
    IDs are on the bus."""
    head = [encode_short(sid, 0, 0x20, (50).to_bytes(2, "little")) for sid in (100, 101)]
    t0 = fr[0][0]
    return [(None if t0 is None else t0 - 0.02 + 0.01 * i, d) for i, d in enumerate(head)] + fr


def edited(fr, fn):
    """The frames with each plain short write's data ``fn(address, data)`` (its checksum made anew)."""
    out = []
    for t, d in fr:
        if d[:2] == b"\xfa\xaf" and len(d) > 8 and d[3] == 0 and d[2] != 0:
            d = encode_short(d[2], 0, d[4], fn(d[4], d[7:-1]))
        out.append((t, d))
    return out


def _word(data, i, fn):
    """``data`` with the signed 16-bit value at ``i`` replaced by ``fn(value)``."""
    v = int.from_bytes(data[i:i + 2], "little", signed=True)
    return data[:i] + fn(v).to_bytes(2, "little", signed=True) + data[i + 2:]


def _baud(address, data):
    return bytes((data[0] + 1,)) if address == 0x06 else data  # another rate code


def _angles(address, data):
    # goal_position (30) and the angle limits (8, 10) all 5.0 deg higher: the same order between them
    return _word(data, 0, lambda v: v + 50) if address in (0x08, 0x0A, 0x1E) else data


def _quicker(address, data):
    # goal_time 20 % shorter (in the goal packet or alone) and the goals 3.0 deg further: still too fast
    if address == 0x1E and len(data) >= 4:
        data = _word(data, 2, lambda v: v * 4 // 5)
    if address == 0x20:
        data = _word(data, 0, lambda v: v * 4 // 5)
    return _word(data, 0, lambda v: v + 30 if v else v) if address == 0x1E else data


# How each example's measured values are changed (Q002's IDs and Q009's servo name the finding: only
# their offsets and times move).
VALUES = {"Q001": _baud, "Q004": _angles, "Q005": _angles, "Q006": _angles, "Q007": _quicker}


@pytest.mark.parametrize("capture", sorted(REFERENCE))
def test_messages_are_typed_and_read_as_before(capture):
    got = [f.message for f in lint(frames(CAPTURES / capture)) if f.code.startswith("Q")]
    assert [str(m) for m in got] == REFERENCE[capture]
    assert all(isinstance(m, Message) for m in got)


def test_simulated_overheat_reads_as_before():
    """The overheat scenario (simulate --scenario overheat --seed 1 --duration 20) keeps switching torque
    on for a servo locked by its temperature limit: Q009 at every try, one text and one key."""
    got = [f.message for f in lint_chunks(list(simulate("overheat", seed=1, duration=20))).findings
           if f.code == "Q009"]
    assert [str(m) for m in got] == [OVERHEAT] * 17
    assert {key_of(m) for m in got} == {OVERHEAT}


@pytest.mark.parametrize("code", CODES)
def test_key_stays_when_times_offsets_and_values_move(code):
    base = example(code)
    moved = edited(retimed(prefixed(base)), VALUES.get(code, lambda a, d: d))
    before, after = lint(base, code), lint(moved, code)
    assert [key_of(f.message) for f in before] == KEYS[code]
    assert [key_of(f.message) for f in after] == KEYS[code]
    assert all(isinstance(f.message, Message) for f in before + after)
    if code != "Q009":  # every other rule writes something measured: the variant must really differ
        assert [str(f.message) for f in before] != [str(f.message) for f in after]


def test_q003_right_after_on_a_held_clock_has_the_gaps_key():
    """A held clock puts the reboot at the flash write's own time: the words say "right after", never
    0.0 ms or less, and the finding is the same one as at any gap."""
    held = [(5.0, encode_command(1, 0x40)), (5.0, encode_command(1, 0x20))]
    (f,) = lint(held, "Q003")
    assert str(f.message) == "reboot right after the flash write @0; allow 100 ms (or wait for its ACK)"
    assert key_of(f.message) == KEYS["Q003"][0]


@settings(max_examples=40, deadline=None)
@given(t0=st.floats(1, 1e5), gap=st.floats(0.0012, 0.09), lead=st.integers(0, 3))
def test_q003_key_is_the_same_for_any_gap_time_and_offset(t0, gap, lead):
    pad = [(t0 - 1 + 0.1 * i, encode_short(100 + i, 0, 0x20, b"\x32\x00")) for i in range(lead)]
    (f,) = lint(pad + [(t0, encode_command(1, 0x40)), (t0 + gap, encode_command(1, 0x20))], "Q003")
    assert key_of(f.message) == KEYS["Q003"][0]
    assert str(f.message).endswith(f" the flash write @{10 * lead}; allow 100 ms (or wait for its ACK)")


@settings(max_examples=60, deadline=None)
@given(limit=st.integers(-1400, 1400), over=st.integers(1, 100), cw=st.booleans())
def test_q006_text_and_key_over_the_angles(limit, over, cw):
    side, address, goal = ("cw", 0x08, limit + over) if cw else ("ccw", 0x0A, limit - over)
    fr = [(None, encode_short(1, 0, address, limit.to_bytes(2, "little", signed=True))),
          (None, encode_short(1, 0, 0x1E, goal.to_bytes(2, "little", signed=True)))]
    (f,) = lint(fr, "Q006")
    # the text as the rule wrote it before it gave parameters
    assert str(f.message) == (f"goal_position {goal / 10:.1f}deg to ID 1 beyond its {side}_angle_limit "
                              f"{limit / 10:.1f}deg")
    assert key_of(f.message) == f"goal_position *deg to ID 1 beyond its {side}_angle_limit *deg"


@settings(max_examples=60, deadline=None)
@given(start=st.integers(-1500, 1500), goal=st.integers(-1500, 1500), gt=st.integers(1, 300))
def test_q007_text_and_key_over_the_moves(start, goal, gt):
    dist = abs(goal - start)
    fr = [(None, encode_short(1, 0, 0x1E, start.to_bytes(2, "little", signed=True) + b"\x00\x00")),
          (None, encode_short(1, 0, 0x1E, goal.to_bytes(2, "little", signed=True) + gt.to_bytes(2, "little")))]
    found = lint(fr, "Q007")
    if dist * 0.11 <= 6 * gt:  # within the RS303MR's 60 deg in 0.11 s: no finding
        assert not found
        return
    (f,) = found
    assert str(f.message) == (f"{dist / 10:.1f} deg in {gt * 10} ms on ID 1 asks {dist * 10 / gt:.0f} deg/s; "
                              f"RS303MR tops out at 545 deg/s")
    assert key_of(f.message) == KEYS["Q007"][0]
