"""The edges of a capture are facts, not faults: its start, its end, a seam in its clock (single cases)."""

from __future__ import annotations

import json
import re

from rs30x_sniff.decode.pairing import MISSING, UNKNOWN, UNSEEN, UNSOLICITED
from rs30x_sniff.cli import main
from rs30x_sniff.protocol.events import CAPTURE_END, CAPTURE_START, TRUNCATED
from rs30x_sniff.sources.captures import read_capture, write_capture
from rs30x_sniff.lint import Linter
from rs30x_sniff.decode.decoder import Decoder
from rs30x_sniff.sinks.pipeline import Sink, drive
from rs30x_sniff.sinks.stats import CaptureStats
from rs30x_sniff.protocol.wire import byte_time, encode_long, encode_read, encode_return, encode_short

BT = byte_time(115200)
READ1, RET1 = encode_read(1, 0x2A, 2), encode_return(1, 0x2A, b"\x84\x03")
READ3 = encode_read(3, 0x2A, 2)


def decode(chunks, columnar=False):
    stats = CaptureStats(115200)
    dec = drive(chunks, Decoder(linter=Linter(), columnar=columnar), stats)
    return dec, stats


def timed(frames, t0=0.0, gap=0.0002):
    """Frames back to back but for ``gap`` seconds between them, from ``t0``."""
    out, t = [], t0
    for f in frames:
        out.append((f, t))
        t += len(f) * BT + gap
    return out


def records_of(chunks, columnar=False):
    recs = []

    class Keep(Sink):
        def batch(self, step):
            recs.extend(step.expanded())

    drive(chunks, Decoder(linter=Linter(), columnar=columnar), Keep())
    return recs


def test_a_tap_started_mid_frame_and_mid_transaction_says_nothing_is_wrong():
    # The capture starts 3 bytes into a poll, so its reply answers a request the capture never saw.
    chunks = timed([READ1[3:], RET1, READ1, RET1])
    recs = records_of(chunks)
    assert recs[0].event.kind == "garbage" and recs[0].event.reason == CAPTURE_START
    assert recs[1].status == UNSEEN and recs[1].request is None
    assert [f.code for r in recs for f in r.findings] == []


def test_a_reply_long_after_the_start_is_still_unsolicited():
    recs = records_of([(RET1, 0.0 + 1.0)] + timed([READ1, RET1], t0=1.1))
    assert recs[0].status == UNSEEN  # the first packet, right at the capture's start
    late = records_of([(b"\x00", 0.0), (RET1, 1.0)] + timed([READ1, RET1], t0=1.1))
    assert late[1].status == UNSOLICITED and "B003" in [f.code for f in late[1].findings]


def test_a_capture_that_ends_after_a_request_leaves_it_unknown_not_missing():
    for chunks in (timed([READ1, RET1, READ3]), [(READ1 + RET1 + READ3, None)]):
        dec, stats = decode(chunks)
        last = [f.code for f in dec.linter.findings]
        assert last == []
        assert stats.servos[3].missing == 0


def test_a_capture_that_runs_on_past_the_timeout_makes_it_missing():
    chunks = timed([READ1, RET1, READ3]) + [(b"\x00", 0.5)]  # a stray byte 0.5 s later: the line was watched
    recs = records_of(chunks)
    assert [r.status for r in recs if r.event.kind == "short"] == ["answered", MISSING]


def test_a_frame_cut_by_the_end_is_capture_end_and_one_cut_frame_is_no_wrong_baud():
    long = encode_long(0x1E, [(v, b"\x84\x03\x05\x00") for v in range(1, 19)])  # 98 bytes
    assert len(long) == 98
    dec, _ = decode(timed([READ1, RET1, long[:79]]))
    assert [f.code for f in dec.linter.findings] == []
    recs = records_of(timed([READ1, RET1, long[:79]]))
    assert recs[-1].event.reason == CAPTURE_END
    # Cut in the middle by the next frame: the truncated frame it is (F003), never F007.
    cut = records_of([(READ1, 0.0), (RET1, 0.001), (long[:79], 0.002), (READ1, 0.002 + 79 * BT)])
    assert cut[2].event.reason == TRUNCATED
    codes = [f.code for r in cut for f in r.findings]
    assert "F003" in codes and "F007" not in codes


def test_concatenated_captures_are_two_time_segments(tmp_path, capsys):
    part = [c for k in range(20) for c in timed([READ1, RET1], t0=k * 0.05)]
    part.append((READ3, 1.0))  # ID 3 never answers: the last request
    part_end = part[-1][1] + len(READ3) * BT
    path = tmp_path / "ab.thex"
    write_capture(path, part + part, "timestamped")
    assert main(["info", str(path), "--format", "json", "--isolated"]) == 0
    info = json.loads(capsys.readouterr().out)
    one = tmp_path / "a.thex"
    write_capture(one, part, "timestamped")
    assert main(["info", str(one), "--format", "json", "--isolated"]) == 0
    single = json.loads(capsys.readouterr().out)
    assert abs(info["duration_s"] - 2 * part_end) < 1e-6 and info["segments"] == 2
    assert info["latency_s"]["p50"] == single["latency_s"]["p50"] > 0
    assert info["bus_load"] == single["bus_load"] < 1
    assert info["servos"]["1"]["poll_rate_hz"] == single["servos"]["1"]["poll_rate_hz"]
    # ID 3's request at the seam: unknown; the one at the end: unknown; nothing is missing.
    assert info["servos"]["3"]["missing"] == 0
    assert info["findings_by_rule"] == {"F010 capture-seam": 1}


def test_a_missing_reply_counts_the_requests_asked_not_the_replies_heard(capsys, tmp_path):
    # ID 1: 3 polls, 2 answered, 1 not; plus 2 returns nobody asked for.
    frames = [READ1, RET1, READ1, RET1, READ1, encode_short(2, 0, 0x1E, b"\x00\x00"), RET1, RET1,
              encode_short(2, 0, 0x1E, b"\x00\x00")]
    path = tmp_path / "c.hex"
    write_capture(path, [(b"".join(frames), None)], "hex")
    assert main(["info", str(path), "--format", "json", "--isolated"]) == 0
    info = json.loads(capsys.readouterr().out)
    lines = [w["text"] for w in info["what_happened"]]
    assert any("ID 1 left 1 of 3 requests unanswered" in x for x in lines), lines


def test_a_serial_log_counting_from_its_first_arrival_has_no_negative_time(capsys):
    # socat's first stamp is the arrival of the first read: its bytes were on the wire before it.
    from datetime import datetime, timezone

    from rs30x_sniff.cli import build_parser
    from rs30x_sniff.commands.common import capture_start_time, open_input, settings_for
    from tests.conftest import CAPTURES

    log = str(CAPTURES / "foreign" / "socat.log")
    assert main(["decode", log, "--format", "jsonl"]) == 0
    events = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert events[0]["t"] == 0.0 and all(e["t"] >= 0 and e["t_end"] > e["t"] for e in events if e.get("t") is not None)
    args = build_parser().parse_args(["decode", log])
    source = open_input(log, None, settings_for(args, log))
    first = next(iter(source))
    # Time 0 is the first byte, one 8-byte read (at 115200 bit/s) before the log's first stamp, and the
    # wall clock of time 0 moved back with it: the stamp's own wall-clock time stays where it was.
    assert first[1] == 0.0 and len(first[0]) == 8
    stamp = datetime(2026, 11, 22, 17, 59, 41, 806796, tzinfo=timezone.utc).timestamp()  # the log's first line
    assert abs(capture_start_time(source) + 8 * BT - stamp) < 1e-6
    capsys.readouterr()


def test_no_load_is_measured_over_a_stall_of_the_reader():
    # 3 s of a quiet bus, then 1.6 s of bytes a reader that fell behind got at once (timed at the line
    # rate: back to back), then 2 s quiet again.
    quiet = [c for k in range(30) for c in timed([READ1, RET1], t0=k * 0.1)]
    burst_t0 = 3.0
    burst = timed([READ1, RET1] * 1000, t0=burst_t0, gap=0.0)
    after = [c for k in range(20) for c in timed([READ1, RET1], t0=burst[-1][1] + 0.1 + k * 0.1)]
    chunks = quiet + burst + after
    _, plain = decode(chunks)
    assert plain.load_peak[0] > 0.9  # the burst reads as a saturated bus
    stats = CaptureStats(115200)
    span = burst[-1][1] + len(RET1) * BT - burst_t0
    stats.stalls = [(burst_t0, span, sum(len(d) for d, _ in burst))]
    drive(chunks, Decoder(linter=Linter()), stats)
    peak = stats.load_peak[0]
    # No window over the stall: the busiest second is no busier than the whole capture's average (which
    # the bytes do support: they came within its time).
    assert peak == stats.bus_load < 0.3 and stats.as_dict()["reader_stalls"][0]["t"] == burst_t0


def test_the_bundled_session_joined_to_itself_lints_as_its_two_halves(tmp_path, capsys):
    from tests.conftest import CAPTURES

    session = CAPTURES / "session-mixed.thex"
    joined = tmp_path / "twice.thex"
    joined.write_bytes(session.read_bytes() * 2)
    size = len(b"".join(d for d, _ in read_capture(str(session), "timestamped", warn=None)))

    def findings(path):
        main(["lint", str(path), "--format", "json", "--isolated", "--fail-on", "never"])
        return [(f["offset"], f["code"], f["message"]) for f in json.loads(capsys.readouterr().out)]

    one = findings(session)
    two = findings(joined)
    seam = [f for f in two if f[1] == "F010"]
    assert len(seam) == 1 and seam[0][0] == size
    # Each half says what the session says alone: no shadow (torque, positions, a pending baud change)
    # and no rule's memory crosses the seam.
    # (Messages that name another packet's offset, "@N", name it in the second half's numbering.)
    shifted = [(o + size, c, re.sub(r"@(\d+)", lambda m: f"@{int(m.group(1)) + size}", msg)) for o, c, msg in one]
    assert sorted(f for f in two if f[1] != "F010") == sorted(one + shifted)
