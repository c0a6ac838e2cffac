"""Pairing rules (B001-B009) and the provisioning rules (Q001, Q002) say only what the bytes show (issue 32 §1).

B009 ("two servos share an ID") is a second reply from the ID asked or the ID that answered, within the
request's reply window; a return from another ID, or after the reply timeout, answers nothing (B003); the
first reply within the window is the request's answer, whatever its ID (B004 if another). A reboot with no
flash write since an ID or baud_rate write loses the change: Q002/Q001 say so at the reboot, whatever follows.
"""

from __future__ import annotations

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rs30x_sniff.decode.pairing import DEFAULT_REPLY_TIMEOUT, EXTRA, UNSEEN, UNSOLICITED
from rs30x_sniff.protocol.wire import (
    FLAG_REBOOT, FLAG_WRITE_FLASH, NACK, byte_time, encode_command, encode_read, encode_return, encode_short)
from tests.decode.test_columnar import assert_same
from tests.lint.helpers import lint_chunks

BT = byte_time(115200)
POS = bytes.fromhex("8403")


def read(sid: int) -> bytes:
    return encode_read(sid, 0x2A, 2)


def ret(sid: int) -> bytes:
    return encode_return(sid, 0x2A, POS)


def timed(*frames: tuple[float, bytes]) -> list[tuple[bytes, float]]:
    return [(f, t) for t, f in frames]


def findings(chunks, code: str | None = None):
    lint = lint_chunks(chunks)
    return [f for f in lint.findings if code is None or f.code == code]


def at(chunks, k: int) -> int:
    """Stream offset of frame ``k``."""
    return sum(len(d) for d, _ in chunks[:k])


def codes_at(chunks, k: int) -> list[str]:
    return sorted(f.code for f in findings(chunks) if f.offset == at(chunks, k))


# ---- B009 and its neighbours --------------------------------------------------------------------------------
def test_a_return_from_another_id_after_the_reply_timeout_is_unsolicited():
    """The issue's case: ID 1's read answered, then a return from ID 3 80 ms later (past the 50 ms timeout)."""
    chunks = timed((0.0, read(1)), (0.0008, ret(1)), (0.0808, ret(3)))
    assert codes_at(chunks, 2) == ["B003"]
    (f,) = findings(chunks, "B003")
    assert f.id == 3
    assert f.message == ("return from ID 3 that no request asked for; 80.106 ms after request @0 to ID 1, "
                         "which had its reply")
    assert not findings(chunks, "B009")


def test_a_return_from_another_id_inside_the_window_after_the_answer_is_unsolicited():
    chunks = timed((0.0, read(1)), (0.0008, ret(1)), (0.0030, ret(3)))
    assert codes_at(chunks, 2) == ["B003"] and not findings(chunks, "B009")


def test_the_first_return_inside_the_window_from_another_id_is_b004():
    chunks = timed((0.0, read(1)), (0.0012, ret(3)))
    assert codes_at(chunks, 1) == ["B004"]
    assert findings(chunks, "B004")[0].message == "return from ID 3 answers request @0 to ID 1"


def test_a_second_return_from_the_id_asked_inside_the_window_is_b009():
    chunks = timed((0.0, read(1)), (0.0008, ret(1)), (0.0018, ret(1)))
    (f,) = findings(chunks)
    assert (f.code, f.id, f.offset) == ("B009", 1, at(chunks, 2))
    assert f.message == ("return from ID 1 is a second reply to request @0 to ID 1, 1.106 ms after it: "
                         "two servos answer to ID 1")


def test_a_second_return_from_the_id_that_answered_is_b009_for_that_id():
    """ID 1 asked, ID 3 answered (B004), ID 3 again: two returns of ID 3 to one request."""
    chunks = timed((0.0, read(1)), (0.0008, ret(3)), (0.0018, ret(3)))
    assert codes_at(chunks, 1) == ["B004"] and codes_at(chunks, 2) == ["B009"]
    assert findings(chunks, "B009")[0].id == 3
    # ... and the ID asked, after another ID answered: two servos answered the packet for ID 1.
    chunks = timed((0.0, read(1)), (0.0008, ret(3)), (0.0018, ret(1)))
    assert codes_at(chunks, 2) == ["B009"] and findings(chunks, "B009")[0].id == 1


def test_a_second_return_from_the_same_id_after_the_timeout_is_unsolicited():
    chunks = timed((0.0, read(1)), (0.0008, ret(1)), (0.0808, ret(1)))
    assert codes_at(chunks, 2) == ["B003"] and not findings(chunks, "B009")


def test_a_late_reply_to_a_request_that_got_none():
    """The wait ended by time: B002 says 'within the reply timeout' (it did answer, too late), B003 says how late."""
    chunks = timed((0.0, read(1)), (0.0808, ret(1)))
    b002, b003 = findings(chunks, "B002"), findings(chunks, "B003")
    assert b002[0].message == "ID 1 did not answer within the reply timeout; the request asked for a return of present_position"
    assert b003[0].message == ("return from ID 1 that no request asked for; 80.106 ms after request @0 to ID 1, "
                               "past its reply timeout")


def test_a_return_after_a_request_that_asked_for_none_claims_no_timeout():
    """Read ID 1 (no reply), then a write to ID 1 asking nothing 1 ms later, then a return 1 ms after that:
    the return is unsolicited because the latest request asked for nothing, not because any timeout passed."""
    write = encode_short(1, 0x00, 0x1E, POS)
    chunks = timed((0.0, read(1)), (0.001, write), (0.002, ret(1)))
    (b003,) = findings(chunks, "B003")
    assert "timeout" not in b003.message
    assert b003.message.endswith(f"after request @{at(chunks, 1)} to ID 1, which asked for no reply")


def test_after_a_nack():
    """A write asking for an ACK is NACKed; a return from the ID asked inside the window is a second reply,
    one from another ID or after the window answers nothing."""
    write = encode_short(1, 0x01, 0x1E, POS)
    same = timed((0.0, write), (0.0012, bytes((NACK,))), (0.0024, ret(1)))
    assert codes_at(same, 1) == ["B008"] and codes_at(same, 2) == ["B009"]
    other = timed((0.0, write), (0.0012, bytes((NACK,))), (0.0024, ret(4)))
    assert codes_at(other, 2) == ["B003"]
    late = timed((0.0, write), (0.0012, bytes((NACK,))), (0.0900, ret(1)))
    assert codes_at(late, 2) == ["B003"]


def test_at_the_start_of_a_second_time_segment():
    """The clock restarts (F010) between an answered read and a return: the return opens the new segment and
    answers a request from before it; nothing pairs across the seam, so neither B009 nor B003."""
    chunks = timed((10.0, read(1)), (10.0008, ret(1)), (2.0, ret(1)), (2.001, read(2)), (2.0018, ret(2)))
    assert [f.code for f in findings(chunks)] == ["F010"]
    # A second return at the start of the segment: nothing in the capture asked for it.
    chunks = timed((10.0, read(1)), (10.0008, ret(1)), (2.0, ret(1)), (2.001, ret(1)))
    assert codes_at(chunks, 3) == ["B003"]
    assert findings(chunks, "B003")[0].message == "return from ID 1 that no request asked for"


def test_b006_reads_the_return_delay_of_the_servo_that_answered():
    """ID 3's return_delay is 100 (5.1 ms): its reply to ID 1's read 5.1 ms later is on time (B004 only); ID 1's
    own reply that late is B006."""
    rd = encode_short(3, 0x00, 0x07, bytes((100,)))
    chunks = timed((0.0, rd), (0.01, read(1)), (0.01 + 8 * BT + 0.0051, ret(3)))
    assert codes_at(chunks, 2) == ["B004"]
    chunks = timed((0.0, rd), (0.01, read(1)), (0.01 + 8 * BT + 0.0051, ret(1)))
    assert codes_at(chunks, 2) == ["B006"]


def test_untimed_second_returns():
    """Without times there is no window: a second return from the ID asked is B009, from another ID B003."""
    assert codes_at([(read(1) + ret(1) + ret(1), None)], 0) == []
    lint = lint_chunks([(read(1) + ret(1) + ret(1), None)])
    assert [(f.code, f.offset) for f in lint.findings] == [("B009", 18)]
    lint = lint_chunks([(read(1) + ret(1) + ret(3), None)])
    assert [(f.code, f.offset) for f in lint.findings] == [("B003", 18)]


IDS = st.sampled_from([1, 2, 3, 7])


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(asked=IDS, first=IDS, second=IDS, nack=st.booleans(), seam=st.booleans(),
       gap=st.one_of(st.floats(0.0005, DEFAULT_REPLY_TIMEOUT - 0.002), st.floats(DEFAULT_REPLY_TIMEOUT + 0.002, 2.0)),
       t0=st.floats(1.0, 1e6))
def test_b009_only_when_the_same_id_answers_twice_within_the_window(asked, first, second, nack, seam, gap, t0):
    """A request, its first reply (a return from ``first``, or a NACK), then a return from ``second`` ``gap``
    after the request (across a seam when ``seam``): B009 exactly when, in one time segment and within the reply
    window, ``second`` is the ID asked or the ID that answered; otherwise the second return is B003 (or, opening
    a new segment, nothing). Both decoding paths agree."""
    request = encode_short(asked, 0x01, 0x1E, POS) if nack else read(asked)
    reply = bytes((NACK,)) if nack else ret(first)
    end = t0 + len(request) * BT
    t2 = t0 - 5.0 if seam else end + max(gap, 0.0002 + len(reply) * BT + 0.0003)
    chunks = [(request, t0), (reply, end + 0.0002), (ret(second), t2)]
    lint = lint_chunks(chunks)
    second_at = at(chunks, 2)
    got = sorted(f.code for f in lint.findings if f.offset == second_at)
    answered = asked if nack else first
    in_window = t2 - end <= DEFAULT_REPLY_TIMEOUT
    if not seam and in_window and second in (asked, answered):
        assert got == ["B009"]
        assert [f.id for f in lint.findings if f.code == "B009"] == [second]
    elif seam:
        assert "B009" not in got and "B003" not in got
    else:
        assert got == ["B003"]
    assert all(f.code != "B009" or f.offset == second_at for f in lint.findings)
    for groups in ([1], [3]):
        assert_same(chunks, groups, lint=True)


# ---- Q001 / Q002: a reboot settles it ------------------------------------------------------------------------
FLASH, REBOOT = FLAG_WRITE_FLASH, FLAG_REBOOT


def test_provisioning_flash_then_id_write_then_reboot_is_q002_at_the_reboot():
    """A real client's provisioning: flash, write ID 1 to 2, reboot, the capture ends 0.36 s later. The reboot
    settles it (the ID in flash is still 1), so the end-of-capture exemption does not apply."""
    chunks = timed((0.0, encode_command(1, FLASH)), (0.2, encode_short(1, 0, 0x04, b"\x02")),
                   (0.3, encode_command(2, REBOOT)), (0.66, read(2)))
    (f,) = findings(chunks, "Q002")
    assert (f.offset, f.id) == (at(chunks, 2), 1)
    assert f.message == ("a reboot of ID 2 before any flash write undoes the change of ID 1 to 2 "
                         f"@{at(chunks, 1)}: the servo comes back on the ID in its flash, not 2")


def test_q002_at_the_reboot_whatever_follows():
    """A flash write after the reboot comes too late (and reaches nobody at ID 2): still one Q002, at the reboot."""
    chunks = timed((0.0, encode_short(1, 0, 0x04, b"\x02")), (0.1, encode_command(255, REBOOT)),
                   (0.5, encode_command(2, FLASH)), (0.6, read(1)))
    assert [(f.code, f.offset) for f in findings(chunks) if f.code.startswith("Q")] == [("Q002", at(chunks, 1))]
    assert findings(chunks, "Q002")[0].message.startswith("a reboot of every servo (ID 255) before any flash write")


def test_q002_still_waits_while_nothing_settles_it():
    """A reboot sent to the old ID reaches nobody: nothing is settled, and a capture that ends 0.3 s after the
    write may have stopped before the flash write (no finding); flashed first, no finding either."""
    assert not findings(timed((0.0, encode_short(1, 0, 0x04, b"\x02")), (0.1, encode_command(1, REBOOT)),
                              (0.3, read(2))), "Q002")
    assert not findings(timed((0.0, encode_short(1, 0, 0x04, b"\x02")), (0.1, encode_command(2, FLASH)),
                              (0.3, encode_command(2, REBOOT))), "Q002")


def test_q001_reboot_before_the_flash_write_is_said_at_the_reboot():
    baud = encode_short(1, 0, 0x06, b"\x04")
    chunks = timed((0.0, baud), (0.1, encode_command(1, REBOOT)), (0.2, read(1)))
    (f,) = findings(chunks, "Q001")
    assert (f.offset, f.id) == (at(chunks, 1), 1)
    assert f.message == ("a reboot of ID 1 before any flash write of the baud_rate code 4 written to ID 1 @0: "
                         "the change is lost, it keeps its old rate")
    # Flashed, then rebooted: applied, nothing to say; a flash write after the reboot does not bring it back.
    assert not findings(timed((0.0, baud), (0.1, encode_command(1, FLASH)), (0.3, encode_command(1, REBOOT))), "Q001")
    late = timed((0.0, baud), (0.1, encode_command(255, REBOOT)), (0.2, encode_command(1, FLASH)),
                 (0.5, encode_command(1, REBOOT)))
    assert [(f.code, f.offset) for f in findings(late, "Q001")] == [("Q001", at(late, 1))]


def test_q001_reboot_of_one_servo_leaves_a_broadcast_change_to_the_others():
    """baud_rate written to ID 255, then ID 1 rebooted: lost for ID 1, but the others may still be flashed and
    rebooted after the capture ends (0.3 s later: no finding for them)."""
    chunks = timed((0.0, encode_short(255, 0, 0x06, b"\x04")), (0.1, encode_command(1, REBOOT)), (0.3, read(2)))
    assert not findings(chunks, "Q001")
