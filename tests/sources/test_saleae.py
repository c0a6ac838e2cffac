"""Saleae Logic exports: samples decode to their packets, every radix and time form round-trips, bad lines say where."""

from __future__ import annotations

import hashlib
import io
import json
from collections import Counter
from datetime import datetime, timedelta, timezone

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from rs30x_sniff.protocol.chunks import FRAMING_ERROR, HOST, PARITY_ERROR, SERVO, Marked, marks
from rs30x_sniff.cli import main
from rs30x_sniff.sources import foreign
from rs30x_sniff.sources.captures import CaptureError, detect_format, read_capture
from rs30x_sniff.sources.saleae import LOGIC1, LOGIC2, probe, sender_of_name, sniff_logic1, sniff_logic2
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.sim import scenarios
from rs30x_sniff.protocol.wire import byte_time

from .conftest import CAPTURES
from .saleae_writer import byte_rows, write_logic1, write_logic2

FOREIGN = CAPTURES / "foreign"
TWO = FOREIGN / "saleae-logic2.csv"        # setup scenario, analyzers TX and RX (RX echoes the host)
ISO = FOREIGN / "saleae-logic2-iso.csv"    # hexapod at 57600, ISO 8601 times, bytes 785-786 framing errors
V1 = FOREIGN / "saleae-logic1.csv"         # noise scenario, Logic 1.x export, byte 1245 a framing error
SAMPLES = [(TWO, LOGIC2), (ISO, LOGIC2), (V1, LOGIC1)]


def decode(path, fmt=None, baud=115200, options=None):
    """(records, decoder, reader) of a capture read with the given options (the decoder's baud by default)."""
    src = read_capture(str(path), fmt, warn=None, options={"baud": baud} if options is None else options)
    dec = Decoder(DecodeOptions(baud=baud))
    recs = []
    for c in src:
        recs += dec.feed(c[0], c[1], *marks(c))
    recs += dec.close()
    return recs, dec, src


def digest(recs) -> str:
    h = hashlib.sha256()
    for r in recs:
        e = r.event
        h.update(f"{e.kind} {e.offset} {e.raw.hex()} {e.t_start:.6f} {getattr(e, 'reason', '')}\n".encode())
    return h.hexdigest()[:16]


# ---- the samples ---------------------------------------------------------------------------------
# saleae-logic2.csv: offset, kind, id, who the table says sent it (every ACK and return from the RX side).
TWO_GOLDEN = """
0 short 1 host; 8 ack - servo; 9 short 1 host; 17 return 1 servo; 55 short 1 host; 64 short 10 host;
73 ack - servo; 74 short 10 host; 82 short 10 host; 90 short 10 host; 98 return 10 servo; 136 short 1 host;
144 ack - servo; 145 short 1 host; 153 return 1 servo; 191 short 1 host; 200 short 11 host; 209 ack - servo;
210 short 11 host; 218 short 11 host; 226 short 11 host; 234 return 11 servo; 272 short 1 host;
280 ack - servo; 281 short 1 host; 289 return 1 servo; 327 short 1 host; 336 short 12 host; 345 ack - servo;
346 short 12 host; 354 short 12 host; 362 short 12 host; 370 return 12 servo
"""


def test_two_analyzers_golden_with_senders():
    recs, dec, src = decode(TWO)
    got = "; ".join(f"{r.event.offset} {r.event.kind} {getattr(r.event, 'id', None) or '-'} "
                    f"{dec.senders.at(r.event.offset)}" for r in recs)
    assert got == " ".join(TWO_GOLDEN.split())
    assert all(r.event.checksum_ok for r in recs)
    assert src.context.found == {"analyzers": {"TX": HOST, "RX": SERVO}, "echo_bytes": 174}
    assert recs[0].event.t_start == pytest.approx(0.2) and recs[-1].event.t_start == pytest.approx(1.984002, abs=1e-6)


def test_two_analyzers_are_the_simulators_packets():
    """The setup scenario the sample was made from: the same frames at the same times (to 1/4 bit)."""
    ours, _, _ = decode(TWO)
    sim = Decoder(DecodeOptions())
    want = [r for c in scenarios.run("setup", seed=1) for r in sim.feed(*c)] + sim.close()
    assert [(r.event.kind, r.event.offset, r.event.raw) for r in ours] == \
        [(r.event.kind, r.event.offset, r.event.raw) for r in want]
    assert max(abs(a.event.t_start - b.event.t_start) for a, b in zip(ours, want)) < byte_time(115200) / 40


def test_iso_sample_golden():
    recs, _, src = decode(ISO, baud=57600)
    start = src.context.found["start_time"]
    assert start == datetime(2026, 11, 22, 14, 14, 50, 250050, tzinfo=timezone(timedelta(hours=1)))
    assert Counter(r.event.kind for r in recs) == {"short": 24, "return": 23, "long": 4, "garbage": 4}
    garbage = [(r.event.offset, len(r.event.raw), r.event.reason) for r in recs if r.event.kind == "garbage"]
    assert garbage == [(772, 13, "truncated"), (785, 1, FRAMING_ERROR), (786, 1, FRAMING_ERROR), (787, 11, "noise")]
    assert recs[0].event.t_start == 0.0  # the first row is time 0; the wall clock is in start_time
    assert digest(recs) == ISO_DIGEST


def test_logic1_sample_golden():
    recs, dec, _ = decode(V1)
    assert not dec.senders
    assert Counter(r.event.kind for r in recs) == {"short": 80, "return": 80, "long": 17, "garbage": 3}
    garbage = [(r.event.offset, r.event.raw.hex(), r.event.reason) for r in recs if r.event.kind == "garbage"]
    assert garbage == [(1244, "41", "noise"), (1245, "1e", FRAMING_ERROR), (1246, "7e", "noise")]
    assert digest(recs) == V1_DIGEST


# Every record's kind, offset, bytes, time (to the microsecond) and reason, hashed: the rest of each sample.
ISO_DIGEST = "b2e6c06091878844"
V1_DIGEST = "eb5479de04fc83c4"


@pytest.mark.parametrize(("path", "fmt"), SAMPLES, ids=lambda x: getattr(x, "name", x))
def test_samples_are_detected_by_content(path, fmt):
    assert detect_format(str(path)) == fmt


def test_sniffing_is_strict():
    assert sniff_logic2(b"name,type,start_time,duration,data\n")
    assert sniff_logic2(b"\xef\xbb\xbfname,type,start_time,duration,data,error\r\n")
    assert sniff_logic2(b'"name","type","start_time","duration","data"\n')
    assert not sniff_logic2(b"name,type,start_time,duration,data,ack,address,read\n")  # an I2C table
    assert not sniff_logic2(b"start_time,data\n")  # too little to be sure
    assert not any(sniff_logic2(h) for h in (b"time,value\n0.1,3\n", b"FA AF 01\n", b"\xfa\xaf\x01", b""))
    assert sniff_logic1(b"Time [s],Value,Parity Error,Framing Error\n0.1,0xFA,,\n")
    assert not sniff_logic1(b"Time [s],Packet ID,Address,Data,Framing Error\n")  # multi-processor mode, not 8N1
    assert not sniff_logic1(b"Time [s],Channel 0,Channel 1\n")  # a digital export


# ---- round trips: simulator bytes -> writer -> reader --------------------------------------------
def _sim(scenario="setup", baud=115200, **kw):
    return list(scenarios.run(scenario, baud=baud, seed=3, **kw))


def _read_text(text: str, fmt: str | None = None, options: dict | None = None, warn=None):
    """Chunks and context of a table given as text (read through the registry, as a file would be)."""
    data = text.encode("utf-8", "surrogateescape")
    other = foreign.get(fmt) if fmt else foreign.sniff(data)
    assert other is not None
    ctx = foreign.ReadContext("t.csv", dict(options or {}), warn)
    return list(other.read(io.BytesIO(data), ctx)), ctx


def _bytes_and_times(chunks, baud):
    out = []
    for c in chunks:
        for k, b in enumerate(c[0]):
            out.append((b, c[1] + k * byte_time(baud), marks(c)))
    return out


def _check_round_trip(chunks, rows, got, baud, senders: bool):
    want = b"".join(d for d, _ in chunks)
    assert b"".join(c[0] for c in got) == want
    bt = byte_time(baud)
    flat = _bytes_and_times(got, baud)
    assert max(abs(t - r[0]) for (_, t, _), r in zip(flat, rows)) < bt  # each byte within one byte time
    assert [m[0] for _, _, m in flat] == ([r[2] for r in rows] if senders else [None] * len(rows))


@pytest.mark.parametrize("radix", ["hex", "decimal", "binary", "ascii"])
@pytest.mark.parametrize("baud", [115200, 9600])
def test_logic2_round_trip(radix, baud):
    chunks = _sim(baud=baud)
    rows = byte_rows(chunks, baud, sample_rate=12.5e6)
    out = io.StringIO()
    write_logic2(out, rows, baud=baud, radix=radix, sample_rate=12.5e6)
    for options in ({}, {"baud": baud}):  # one chunk per byte, and runs merged at the decoder's rate
        got, ctx = _read_text(out.getvalue(), options=options)
        _check_round_trip(chunks, rows, got, baud, senders=False)
        assert "start_time" not in ctx.found


def test_logic2_two_analyzers_round_trip_with_echo():
    chunks = _sim()
    rows = byte_rows(chunks, 115200)
    out = io.StringIO()
    write_logic2(out, rows, names=("Async Serial [1]", "Async Serial [2]"), echo=True)
    got, ctx = _read_text(out.getvalue())  # neither name tells: the content does
    _check_round_trip(chunks, rows, got, 115200, senders=True)
    assert ctx.found["analyzers"] == {"Async Serial [1]": HOST, "Async Serial [2]": SERVO}
    assert ctx.found["echo_bytes"] == sum(1 for r in rows if r[2] == HOST)


def test_logic2_iso_round_trip():
    chunks = _sim()
    rows = byte_rows(chunks, 115200)
    start = datetime(2026, 3, 1, 23, 59, 59, 999000, tzinfo=timezone.utc)  # crosses midnight and a month
    out = io.StringIO()
    write_logic2(out, rows, iso=start)
    got, ctx = _read_text(out.getvalue())
    first = rows[0][0]
    _check_round_trip(chunks, [(t - first, v, s) for t, v, s in rows], got, 115200, senders=False)
    assert ctx.found["start_time"] == start + timedelta(seconds=first)
    assert got[0][1] == 0.0


@pytest.mark.parametrize("radix", ["hex", "decimal", "binary", "ascii"])
def test_logic1_round_trip(radix):
    chunks = _sim()
    rows = byte_rows(chunks, 115200, sample_rate=12.5e6)
    out = io.StringIO()
    write_logic1(out, rows, radix=radix)
    for fmt in (None, LOGIC2):  # detected as Logic 1.x, and read by --input-format saleae too
        got, _ = _read_text(out.getvalue(), fmt)
        _check_round_trip(chunks, rows, got, 115200, senders=False)


def test_merged_runs_give_the_same_events_as_single_bytes():
    chunks = _sim("hexapod", duration=1.1)
    rows = byte_rows(chunks, 115200, sample_rate=24e6)
    out = io.StringIO()
    write_logic2(out, rows, names=("host", "servo"))
    text = out.getvalue()
    single, _ = _read_text(text)
    merged, _ = _read_text(text, options={"baud": 115200})
    assert len(merged) < len(single) / 5

    def events(cs):
        dec = Decoder(DecodeOptions())
        return [r.event for c in cs for r in dec.feed(c[0], c[1], *marks(c))] + [r.event for r in dec.close()]

    a, b = events(single), events(merged)
    assert [(e.kind, e.offset, e.raw) for e in a] == [(e.kind, e.offset, e.raw) for e in b]
    assert max(abs(x.t_start - y.t_start) for x, y in zip(a, b)) < byte_time(115200) / 40


def test_a_sender_whose_clock_is_off_is_not_merged_into_drift():
    # Bytes 1 % slow: each joins the run only while it is within a quarter bit of its place.
    bt = byte_time(115200) * 1.01
    text = "name,type,start_time,duration,data\n" + "".join(
        f'"A","data",{k * bt!r},8.2e-05,0x{k:02X}\n' for k in range(40))
    got, _ = _read_text(text, options={"baud": 115200})
    assert len(got) > 1
    for c in got:
        for k in range(len(c[0])):
            assert abs(c[1] + k * byte_time(115200) - c[0][k] * bt) <= byte_time(115200) / 40 + 1e-12


# ---- forms a table may take ----------------------------------------------------------------------
HEADER = "name,type,start_time,duration,data,error\n"


def test_exponent_times_quoted_cells_and_a_missing_error_cell():
    text = HEADER + '"Async Serial","data",5e-05,8.2e-05,0xFA,\n"Async Serial","data",1.368E-4,8.2e-05,0xAF\n'
    got, _ = _read_text(text)
    assert got == [(b"\xfa", 5e-05), (b"\xaf", 1.368e-4)]


def test_error_rows_are_their_own_marked_chunks():
    text = HEADER + "".join(f'"RX","data",{k * 1e-4},8.2e-05,0x{b:02X},{e}\n'
                            for k, (b, e) in enumerate([(0xFA, ""), (0x55, "framing"), (0x56, "parity"), (0xAF, "")]))
    got, _ = _read_text(text, options={"baud": 115200})
    assert [(c[0], marks(c)[1]) for c in got] == [
        (b"\xfa", None), (b"\x55", FRAMING_ERROR), (b"\x56", PARITY_ERROR), (b"\xaf", None)]
    assert all(type(c) is Marked for c in got[1:3])


@pytest.mark.parametrize(("cell", "value"), [
    ("0xC8", 0xC8), ("0xc8", 0xC8), ("0x7", 7), ("200", 200), ("0b11001000", 0xC8), ("0b1100 1000", 0xC8)])
def test_radixes(cell, value):
    got, _ = _read_text(HEADER + f'"A","data",0,8.2e-05,{cell},\n')
    assert got == [(bytes((value,)), 0.0)]


@pytest.mark.parametrize(("cell", "value"), [
    ("A", 0x41), ('" "', 0x20), ('","', 0x2C), ('""""', 0x22), ("\\r", 13), ("\\n", 10), ("\\t", 9), ("\\0", 0),
    ("\\xFA", 0xFA), ("'8'", 8), ("' '", 32), ("COMMA", 44), ("ú", 0xFA), ("'ú'", 0xFA)])
def test_ascii_forms(cell, value):
    # The first cell (a letter) tells the radix: ASCII.
    got, _ = _read_text(HEADER + '"A","data",0,8.2e-05,Z,\n' + f'"A","data",0.001,8.2e-05,{cell},\n')
    assert got[1][0] == bytes((value,))


def test_a_byte_that_is_not_utf8_is_itself():
    data = (HEADER + '"A","data",0,8.2e-05,Z,\n"A","data",0.001,8.2e-05,').encode() + b"\xfa,\n"
    ctx = foreign.ReadContext("t.csv")
    got = list(foreign.get(LOGIC2).read(io.BytesIO(data), ctx))
    assert got[1][0] == b"\xfa"


def test_lone_digits_wait_for_the_radix():
    # "7" could be decimal 7 or the character '7' (0x37); the next value decides.
    got, _ = _read_text(HEADER + '"A","data",0,8.2e-05,7,\n"A","data",0.001,8.2e-05,250,\n')
    assert [c[0] for c in got] == [b"\x07", b"\xfa"]
    got, _ = _read_text(HEADER + '"A","data",0,8.2e-05,7,\n"A","data",0.001,8.2e-05,x,\n')
    assert [c[0] for c in got] == [b"7", b"x"]
    got, _ = _read_text(HEADER + '"A","data",0,8.2e-05,7,\n')
    assert [c[0] for c in got] == [b"\x07"]  # nothing else tells: decimal


@pytest.mark.parametrize(("stamp", "start"), [
    ("2026-11-22T14:14:50.000529253Z", datetime(2026, 11, 22, 14, 14, 50, 529, tzinfo=timezone.utc)),
    ("2026-11-22T14:14:50.5+0130", datetime(2026, 11, 22, 14, 14, 50, 500000, tzinfo=timezone(timedelta(minutes=90)))),
    ('"2026-11-22 14:14:50,25-05:00"',
     datetime(2026, 11, 22, 14, 14, 50, 250000, tzinfo=timezone(timedelta(hours=-5)))),
])
def test_iso_zones(stamp, start):
    got, ctx = _read_text(HEADER + f'"A","data",{stamp},8.2e-05,0xFA,\n')
    assert ctx.found["start_time"] == start and got == [(b"\xfa", 0.0)]


def test_iso_without_a_zone_is_local_time_and_keeps_nanoseconds():
    text = HEADER + '"A","data",2026-11-22T14:14:59.999999999,8.2e-05,0xFA,\n' \
                    '"A","data",2026-11-22T14:15:00.000086805,8.2e-05,0xAF,\n'
    got, ctx = _read_text(text)
    assert ctx.found["start_time"].tzinfo is not None
    assert ctx.found["start_time"].replace(tzinfo=None) == datetime(2026, 11, 22, 14, 14, 59, 999999)
    assert got[1][1] == pytest.approx(86.806e-6, abs=1e-12)


def test_times_before_the_trigger_are_moved_to_start_at_zero():
    said = []
    got, _ = _read_text(HEADER + '"A","data",-0.5,8.2e-05,0xFA,\n"A","data",-0.4,8.2e-05,0xAF,\n', warn=said.append)
    assert [c[1] for c in got] == [0.0, pytest.approx(0.1)]
    assert len(said) == 1 and "before the trigger" in said[0]


# ---- direction -----------------------------------------------------------------------------------
@pytest.mark.parametrize(("name", "sender"), [
    ("TX", HOST), ("RX", SERVO), ("tx1", HOST), ("Host", HOST), ("Servo bus", SERVO), ("Host TX", HOST),
    ("Host RX", SERVO), ("servo_tx", SERVO), ("MCU RXD", SERVO), ("host->servo", HOST), ("servo to host", SERVO),
    ("Async Serial", None), ("Async Serial [2]", None), ("TX/RX", None), ("D0", None)])
def test_sender_of_name(name, sender):
    assert sender_of_name(name) == sender


def _two(names, first_bytes=b"\xfa\xaf", second_bytes=b"\xfd\xdf"):
    rows = [(0.0 + k * 1e-4, names[0], b) for k, b in enumerate(first_bytes)]
    rows += [(0.01 + k * 1e-4, names[1], b) for k, b in enumerate(second_bytes)]
    return HEADER + "".join(f'"{n}","data",{t!r},8.2e-05,0x{b:02X},\n' for t, n, b in sorted(rows))


def test_one_name_tells_the_other():
    _, ctx = _read_text(_two(("Async Serial", "host")))
    assert ctx.found["analyzers"] == {"Async Serial": SERVO, "host": HOST}


def test_content_tells_when_names_do_not():
    _, ctx = _read_text(_two(("ch 3", "ch 5"), b"\xfd\xdf", b"\xfa\xaf"))
    assert ctx.found["analyzers"] == {"ch 3": SERVO, "ch 5": HOST}


def test_undecidable_analyzers_are_read_without_senders():
    said = []
    got, ctx = _read_text(_two(("a", "b"), b"\x01\x02", b"\x03"), warn=said.append)
    assert [marks(c) for c in got] == [(None, None)] * 3 and "analyzers" not in ctx.found
    assert len(said) == 1 and "cannot tell" in said[0]


def test_one_analyzer_has_no_senders_whatever_its_name():
    got, ctx = _read_text(HEADER + '"TX","data",0,8.2e-05,0xFA,\n')
    assert got == [(b"\xfa", 0.0)] and "analyzers" not in ctx.found


def test_a_third_analyzer_is_an_error():
    text = HEADER + "".join(f'"{n}","data",{k},8.2e-05,0x01,\n' for k, n in enumerate("ABC"))
    with pytest.raises(CaptureError) as e:
        _read_text(text)
    assert e.value.line == 4 and "third analyzer 'C'" in str(e.value)


# ---- bad lines -----------------------------------------------------------------------------------
BAD_LOGIC2 = [
    ('"A","data",zero,8.2e-05,0xFA,', "not a time in seconds"),
    ('"A","data",nan,8.2e-05,0xFA,', "finite"),
    ('"A","data",1_0,8.2e-05,0xFA,', "finite"),
    ('"A","data",1.0,8.2e-05,0xGG,', "not a hex byte"),
    ('"A","data",1.0,8.2e-05,0x1FF,', "not a hex byte"),
    ('"A","data",1.0,8.2e-05,200,', "not a hex byte"),
    ('"A","data",1.0,8.2e-05,,', "not a hex byte"),
    ('"A","start",1.0,8.2e-05,0xFA,', "type 'start'"),
    ('"A","data",1.0,8.2e-05,0xFA,glitch', "unknown error 'glitch'"),
    ('"A","data",1.0,long,0xFA,', "not a time in seconds"),
    ('"A","data",1.0', "expected 6 fields, got 3"),
    ('"A","data",1.0,8.2e-05,0xFA,,extra', "expected 6 fields, got 7"),
    ('"A","data","unclosed', "expected 6 fields"),  # the open quote takes in the lines after it
]


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(good=st.integers(1, 30), bad=st.sampled_from(BAD_LOGIC2), tail=st.integers(0, 3))  # row 1 tells the radix
def test_a_bad_logic2_line_is_one_line_naming_it(good, bad, tail):
    line, why = bad
    rows = [f'"A","data",{k * 1e-4!r},8.2e-05,0x{k:02X},' for k in range(good)]
    text = HEADER + "\n".join(rows + [line] + [f'"A","data",{k},8.2e-05,0x00,' for k in range(tail)]) + "\n"
    with pytest.raises(CaptureError) as e:
        _read_text(text, LOGIC2)
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(f"t.csv:{good + 2}: ") and why in msg, msg
    assert e.value.line == good + 2


BAD_LOGIC1 = [
    ("x,0xFA,,", "not a time in seconds"), ("0.1,0xFA,,,", "expected 4 fields"), ("0.1,0xFA", "expected 4 fields"),
    ("0.1,0xZZ,,", "not a hex byte"), ("0.1,0xFA,Yes,", "not Error or nothing"), ("inf,0xFA,,", "finite"),
]


@settings(max_examples=40, deadline=None)
@given(good=st.integers(1, 30), bad=st.sampled_from(BAD_LOGIC1), crlf=st.booleans())
def test_a_bad_logic1_line_is_one_line_naming_it(good, bad, crlf):
    line, why = bad
    nl = "\r\n" if crlf else "\n"
    text = nl.join(["Time [s],Value,Parity Error,Framing Error"] + [f"{k * 1e-4:.15f},0x{k:02X},," for k in range(good)]
                   + [line, "9.0,0x00,,"]) + nl
    for fmt in (LOGIC1, LOGIC2):
        with pytest.raises(CaptureError) as e:
            _read_text(text, fmt)
        msg = str(e.value)
        assert "\n" not in msg and msg.startswith(f"t.csv:{good + 2}: ") and why in msg, msg
        assert e.value.line == good + 2


@pytest.mark.parametrize(("header", "why"), [
    ("name,type,start_time,duration,data,ack\n", "column 'ack'"),
    ("name,type,duration,data\n", "start_time and data"),
])
def test_a_bad_header_when_forced(header, why):
    with pytest.raises(CaptureError) as e:
        _read_text(header + '"A","data",0,1,0xFA,\n', LOGIC2)
    assert e.value.line == 1 and why in str(e.value)


def test_a_logic2_table_forced_as_logic1_says_which_to_use():
    with pytest.raises(CaptureError) as e:
        _read_text(HEADER + '"A","data",0,8.2e-05,0xFA,\n', LOGIC1)
    assert "--input-format saleae" in str(e.value) and e.value.line == 1


def test_an_empty_file_has_no_chunks():
    assert _read_text("", LOGIC2)[0] == [] and _read_text("", LOGIC1)[0] == []
    assert _read_text(HEADER, LOGIC2)[0] == []


# ---- the bit rate --------------------------------------------------------------------------------
def test_probe_reads_the_rate_off_the_durations():
    got = probe(str(ISO), {})
    assert got["baud"] == 57600 and "frame durations" in got["baud_note"]
    assert probe(str(TWO), {})["baud"] == 115200
    got = probe(str(V1), {})  # no durations: back-to-back bytes
    assert got["baud"] == 115200 and "back-to-back" in got["baud_note"]


def test_probe_says_nothing_when_durations_disagree_or_fit_no_rate(tmp_path):
    p = tmp_path / "mixed.csv"
    p.write_text(HEADER + "".join(f'"A","data",{k},{d},0x01,\n' for k, d in enumerate([8.2e-05, 1.65e-4] * 20)))
    got = probe(str(p), {})
    assert "baud" not in got and "no one rate" in got["baud_note"]
    p.write_text(HEADER + "".join(f'"A","data",{k},{9.5 / 100000},0x01,\n' for k in range(20)))
    got = probe(str(p), {})
    assert "baud" not in got and "no rate of table 4.7" in got["baud_note"]
    assert probe("-", {}) == {} and probe(str(tmp_path / "missing.csv"), {}) == {}


# ---- the commands --------------------------------------------------------------------------------
@pytest.mark.parametrize(("path", "fmt"), SAMPLES, ids=lambda x: getattr(x, "name", x))
@pytest.mark.parametrize("forced", [False, True])
def test_cli_decode_info_lint(capsys, path, fmt, forced):
    extra = ["--input-format", "saleae"] if forced else []
    assert main(["decode", str(path), *extra]) == 0
    out, err = capsys.readouterr()
    lines = out.splitlines()
    assert "host  " in out and "servo RETURN" in out
    baud = "57600" if path == ISO else "115200"
    assert f"{baud} bit/s" in err
    assert len([ln for ln in lines if " lint  " not in ln]) == {TWO: 33, ISO: 55, V1: 180}[path]
    assert main(["info", str(path), "--format", "json", *extra]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["settings"]["baud"] == int(baud) and info["settings"]["origin"]["baud"].startswith("capture (")
    assert info["timed"] and info["bytes"] == {TWO: 408, ISO: 866, V1: 3255}[path]
    code = main(["lint", str(path), *extra])
    out = capsys.readouterr().out
    if path == TWO:
        assert code == 0 and "0 findings" in out
    else:
        assert code == 1 and "F008 uart-error" in out


def test_cli_forced_logic1_name(capsys):
    assert main(["decode", str(V1), "--input-format", "saleae-v1"]) == 0
    assert main(["decode", str(TWO), "--input-format", "saleae-v1"]) == 2
    assert "--input-format saleae" in capsys.readouterr().err


def test_cli_a_bad_line_is_exit_2_one_line(capsys, tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text(HEADER + '"A","data",0,8.2e-05,0xFA,\n"A","data",x,8.2e-05,0xAF,\n')
    assert main(["decode", str(p)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("rs30x-sniff: error: ") and f"{p}:3: not a time in seconds" in err[-1]
