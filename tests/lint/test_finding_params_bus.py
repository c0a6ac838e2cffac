"""Bus (B001-B009), uart (F008) and direction (F009) findings are made from typed parameters: the text as before,
a key that no measured value (time, offset, count, byte) moves."""

from __future__ import annotations

import io

from hypothesis import given, settings
from hypothesis import strategies as st

from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.lint import RULES, Linter
from rs30x_sniff.lint.params import DURATION, OFFSET, Measured, Message, key_of
from rs30x_sniff.protocol.chunks import FRAMING_ERROR, HOST, PARITY_ERROR, SERVO, Marked
from rs30x_sniff.protocol.wire import encode_read, encode_return, encode_short
from rs30x_sniff.sinks.pipeline import drive
from rs30x_sniff.sources import foreign

from .helpers import CAPTURES, lint_chunks, parse

MINE = {"B001", "B002", "B003", "B004", "B005", "B006", "B007", "B008", "B009", "F008", "F009"}
READ1, READ2 = encode_read(1, 0x2A, 2), encode_read(2, 0x2A, 2)
RET1, RET2 = encode_return(1, 0x2A, b"\x84\x03"), encode_return(2, 0x2A, b"\x84\x03")
WRITE1 = encode_short(1, 0, 0x1E, b"\x84\x03")  # goal_position, asks for no reply
POLL = encode_short(1, 0x09, 0, b"", length=0, count=1)

# Each rule's example capture, the findings of these rules and their text before messages were typed (the
# reference lint of every bundled capture made before the change).
TODAY = {
    "B001": [(26, "B001", "sent 0.306 ms after request @18 to ID 1, whose reply was still due"),
             (44, "B002", "ID 1 did not answer; the request asked for a return of present_position")],
    "B002": [(0, "B002", "ID 1 did not answer; the request asked for a return of present_position"),
             (26, "B002", "ID 3 did not answer; the request asked for an ACK"),
             (53, "B002", "ID 4 did not answer; the request asked for a return of present_position")],
    "B003": [(10, "B003", ("return from ID 1 that no request asked for; after request @0 to ID 1, which asked for "
                           "no reply"))],
    "B004": [(8, "B004", "return from ID 2 answers request @0 to ID 1")],
    "B005": [(8, "B005", "returns 2 byte(s) from address 44; request @0 asked for 2 from 42"),
             (26, "B005", "returns 4 byte(s) from address 42; request @18 asked for 2 from 42"),
             (81, "B005", "return where request @72 asked for an ACK")],
    "B006": [(26, "B006", "reply 9.906 ms after the request; return_delay 0 (assumed) means 0.100 ms")],
    "B007": [(6, "B003", "return from ID 1 that no request asked for"),
             (6, "B007", "frame starts inside the 6-byte frame cut short at @0")],
    "B008": [(10, "B008", "NACK from ID 1 to request @0")],
    "B009": [(18, "B009", ("return from ID 1 is a second reply to request @0 to ID 1, 1.206 ms after it: two servos "
                           "answer to ID 1")),
             (46, "B003", ("return from ID 3 that no request asked for; 80.106 ms after request @28 to ID 1, which "
                           "had its reply")),
             (74, "B003", ("return from ID 1 that no request asked for; 80.106 ms after request @56 to ID 1, which "
                           "had its reply")),
             (102, "B003", ("return from ID 3 that no request asked for; 1.206 ms after request @84 to ID 1, which "
                            "had its reply"))],
}
CODES = sorted(TODAY)


def example(code: str) -> list[tuple[bytes, float | None]]:
    (path,) = [p for p in (CAPTURES / "lint").glob(f"{code}-*") if p.suffix in (".hex", ".thex")]
    return parse(path.read_text())[0]


def mine(linter: Linter) -> list:
    return [f for f in linter.findings if f.code in MINE]


def typed(findings) -> list:
    assert findings and all(isinstance(f.message, Message) for f in findings)
    return findings


def keys(findings) -> list[tuple[str, str | None]]:
    return [(f.code, key_of(f.message)) for f in findings]


def moved(chunks, garbage: int, shift: float, scale: float):
    """The same capture after ``garbage`` noise bytes (every stream offset moves) with its clock started
    elsewhere and running a little fast or slow (every time and duration moves)."""
    noise = b"\x00" * garbage
    (data, t0), rest = chunks[0], chunks[1:]
    out = [(noise + data, t0)] + rest
    return [(d, None if t is None else shift + t * scale) for d, t in out]


def lint_marked(chunks) -> Linter:
    linter = Linter()
    drive(chunks, Decoder(DecodeOptions(), linter))
    return linter


def test_each_example_capture_says_what_it_said_before():
    for code in CODES:
        found = typed(mine(lint_chunks(example(code))))
        assert [(f.offset, f.code, str(f.message)) for f in found] == TODAY[code], code


@settings(max_examples=60, deadline=None)
@given(code=st.sampled_from(CODES), garbage=st.integers(0, 40), shift=st.floats(0, 2e6),
       scale=st.floats(0.97, 1.03))
def test_keys_stay_when_offsets_and_times_move(code, garbage, shift, scale):
    chunks = example(code)
    if code == "B007":
        garbage = 0  # noise before its cut frame makes that frame the capture's ragged start (a seam): no collision
    before = typed(mine(lint_chunks(chunks)))
    after = typed(mine(lint_chunks(moved(chunks, garbage, shift, scale))))
    assert [(f.offset + garbage, f.code) for f in before] == [(f.offset, f.code) for f in after]
    assert keys(before) == keys(after)
    # What moved is in the words (an offset after noise, a duration on a faster or slower clock), and only that.
    for b, a in zip(before, after):
        units = {v.unit for v in b.params.values() if isinstance(v, Measured)}
        if (garbage and OFFSET in units) or (abs(scale - 1) > 0.005 and DURATION in units):
            assert str(b.message) != str(a.message)
        elif not units:
            assert str(b.message) == str(a.message)


def test_a_held_clock_is_right_after_with_the_key_of_any_gap():
    held = mine(lint_chunks([(READ1, 0.0), (READ2, 0.0), (RET2, 0.0012)]))
    timed = mine(lint_chunks(example("B001")))
    assert [(f.code, str(f.message)) for f in held] == [
        ("B001", "sent right after request @0 to ID 1, whose reply was still due")]
    assert key_of(held[0].message) == key_of(timed[0].message) == \
        "sent * after request @* to ID 1, whose reply was still due"
    assert held[0].params["gap"].unit == DURATION  # the typed gap is kept


def test_a_gap_or_latency_the_capture_cannot_give_leaves_the_key_as_it_is():
    # B003: the gap to the latest request, written when the clock gives one.
    untimed = mine(lint_chunks([(WRITE1 + RET1, None)]))
    timed = mine(lint_chunks([(WRITE1, 0.0), (RET1, 0.002)]))
    assert str(untimed[0].message) == "return from ID 1 that no request asked for; after request @0 to ID 1, " \
                                      "which asked for no reply"
    assert str(timed[0].message) == "return from ID 1 that no request asked for; 1.132 ms after request @0 to " \
                                    "ID 1, which asked for no reply"
    assert keys(untimed) == keys(timed)
    # B009: the second reply's latency.
    untimed = mine(lint_chunks([(READ1 + RET1 + RET1, None)]))
    timed = mine(lint_chunks([(READ1, 0.0), (RET1, 0.0008), (RET1, 0.0019)]))
    assert str(untimed[0].message) == "return from ID 1 is a second reply to request @0 to ID 1: two servos " \
                                      "answer to ID 1"
    assert ", 1.206 ms after it:" in timed[0].message and keys(untimed) == keys(timed)


@given(st.integers(0, 255), st.integers(0, 255))
def test_b006_return_delay_read_off_the_wire_is_measured(rd1, rd2):
    def late(rd):  # the host writes return_delay, then the reply comes 30 ms after its request
        return mine(lint_chunks([(encode_short(1, 0, 0x07, bytes((rd,))), 0.0), (READ1, 0.1), (RET1, 0.1306)]))
    a, b = typed(late(rd1)), typed(late(rd2))
    assert [f.code for f in a] == [f.code for f in b] == ["B006"] and keys(a) == keys(b)
    expected = (100e-6 + 50e-6 * rd1) * 1e3
    assert str(a[0].message) == f"reply 29.906 ms after the request; return_delay {rd1} means {expected:.3f} ms"
    assert key_of(a[0].message) == "reply * after the request; return_delay * means *"
    # A return_delay never seen is assumed, in words of the rule's own: another finding than a measured one.
    assumed = typed(mine(lint_chunks(example("B006"))))
    assert key_of(assumed[0].message) == "reply * after the request; return_delay 0 (assumed) means *"


@given(st.sampled_from([2, 3, 4, 6, 7]), st.integers(0, 3))  # (5 bytes of this poll: a header of no frame, F002)
def test_b007_where_the_cut_fell_is_measured(cut, polls):
    at = polls * len(READ1 + RET1)
    found = typed([f for f in mine(lint_chunks([((READ1 + RET1) * polls + POLL[:cut] + RET1, None)]))
                   if f.code == "B007"])
    assert str(found[0].message) == f"frame starts inside the {cut}-byte frame cut short at @{at}"
    assert key_of(found[0].message) == "frame starts inside the *-byte frame cut short at @*"


def test_b005_the_ranges_name_the_finding():
    # Which range came back where which was asked is the mismatch itself: another range, another key.
    a = typed(mine(lint_chunks([(READ1 + encode_return(1, 0x2C, b"\0\0"), None)])))
    b = typed(mine(lint_chunks([(READ1 + encode_return(1, 0x2E, b"\0\0"), None)])))
    assert keys(a) != keys(b)
    assert key_of(a[0].message) == "returns 2 byte(s) from address 44; request @* asked for 2 from 42"


def test_b008_and_b004_mask_only_the_offset():
    nack = typed(mine(lint_chunks([(WRITE1[:3] + b"\x01" + WRITE1[4:-1] + bytes((WRITE1[-1] ^ 1,)) + b"\x08",
                                    None)])))
    assert keys(nack) == [("B008", "NACK from ID 1 to request @*")]
    other = typed(mine(lint_chunks([(READ1 + RET2, None)])))
    assert keys(other) == [("B004", "return from ID 2 answers request @* to ID 1")]


# ---- F008: the flagged byte's value is measured, the kind of error is not --------------------------------

def test_f008_example_says_what_it_said_before():
    text = RULES["F008"].example
    fmt = foreign.sniff(text.encode())
    found = typed(mine(lint_marked(fmt.read(io.BytesIO(text.encode()), foreign.ReadContext("example.csv")))))
    assert [str(f.message) for f in found] == [
        ("byte 0x84 flagged by the capturing tool with a framing error (its stop bit was low): its value cannot be "
         "trusted, and a frame it falls in is lost")]


@given(byte=st.integers(0, 255), other=st.integers(0, 255), error=st.sampled_from([FRAMING_ERROR, PARITY_ERROR]),
       t=st.floats(0, 1e6))
def test_f008_key_does_not_hold_the_byte(byte, other, error, t):
    def flagged(b):
        return typed(mine(lint_marked([(WRITE1, t), Marked(bytes((b,)), t + 0.002, error=error),
                                       (encode_short(2, 0, 0x1E, b"\x84\x03"), t + 0.003)])))
    a, b = flagged(byte), flagged(other)
    assert keys(a) == keys(b) and "0x*" in key_of(a[0].message)
    why = "a framing error (its stop bit was low)" if error == FRAMING_ERROR else \
        "a parity error (the bus has no parity bit: is the analyzer set to 8N1?)"
    assert str(a[0].message) == f"byte 0x{byte:02X} flagged by the capturing tool with {why}: its value cannot " \
                                "be trusted, and a frame it falls in is lost"


# ---- F009: the counts are measured, whether every packet disagreed is not --------------------------------

def test_f009_example_says_what_it_said_before():
    text = RULES["F009"].example.encode()
    fmt = foreign.sniff(text)
    found = typed(mine(lint_marked(fmt.read(io.BytesIO(text), foreign.ReadContext("example")))))
    assert [str(f.message) for f in found] == [
        ("every packet checked disagrees with the capture about who sent it; first here, a request (FA AF) the "
         "capture says the servo sent: the capture's directions are the wrong way round (was the logger on the "
         "servo's side, or RX and TX swapped?)")]


def senders(right: int, wrong: int, t0: float) -> list:
    """``right`` polls and returns logged the right way round, then ``wrong`` returns the host 'sent'."""
    chunks = []
    for k in range(right + wrong):
        t = t0 + 0.01 * k
        chunks += [Marked(READ1, t, sender=HOST), Marked(RET1, t + 0.001, sender=SERVO if k < right else HOST)]
    return chunks


@given(right=st.integers(1, 6), wrong=st.integers(1, 6), right2=st.integers(1, 6), wrong2=st.integers(1, 6),
       t0=st.floats(0, 1e6))
def test_f009_key_does_not_hold_the_counts(right, wrong, right2, wrong2, t0):
    a = typed(mine(lint_marked(senders(right, wrong, 0.0))))
    b = typed(mine(lint_marked(senders(right2, wrong2, t0))))
    assert keys(a) == keys(b)
    assert str(a[0].message).startswith(f"{wrong} of {2 * (right + wrong)} packets checked disagree with the capture")
    assert key_of(a[0].message).startswith("* of * packets checked disagree with the capture")


@given(n=st.integers(2, 8), m=st.integers(2, 8))
def test_f009_a_capture_the_wrong_way_round_keeps_its_key_at_any_length(n, m):
    def reversed_log(k):
        return [c for i in range(k) for c in (Marked(READ1, 0.01 * i, sender=SERVO),
                                              Marked(RET1, 0.01 * i + 0.001, sender=HOST))]
    a, b = typed(mine(lint_marked(reversed_log(n)))), typed(mine(lint_marked(reversed_log(m))))
    assert keys(a) == keys(b) and str(a[0].message) == key_of(a[0].message)  # nothing measured is written


@given(late=st.floats(0.06, 0.5), t0=st.floats(0, 1e6))
def test_a_nack_nobody_waited_for_names_no_id(late, t0):
    # An ACK or NACK carries no ID: the words name none; only the time since the request is measured.
    ack_me = encode_short(1, 0x01, 0x1E, b"\x84\x03")
    found = typed(mine(lint_chunks([(ack_me, t0), (b"\x08", t0 + late)])))
    assert [(f.code, key_of(f.message)) for f in found] == [
        ("B002", "ID 1 did not answer within the reply timeout; the request asked for an ACK"),
        ("B008", "NACK"),
        ("B003", "NACK that no request asked for; after request @* to ID 1, past its reply timeout")]
    assert str(found[2].message).startswith("NACK that no request asked for; ")
    assert str(found[2].message).endswith(" ms after request @0 to ID 1, past its reply timeout")
