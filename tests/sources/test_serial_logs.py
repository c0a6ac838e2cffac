"""Serial loggers' logs as inputs: the samples decode to the simulated bus, every format round-trips, bad lines are named."""

from __future__ import annotations

import json
import shutil
from datetime import datetime
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from rs30x_sniff.protocol.chunks import HOST, SERVO, marks
from rs30x_sniff.cli import main
from rs30x_sniff.sources import foreign
from rs30x_sniff.sources.captures import CaptureError, detect_format, read_capture
from rs30x_sniff.sources.inputs import read_input
from rs30x_sniff.lint import LintConfig, Linter
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.sinks.pipeline import Sink, drive
from rs30x_sniff.protocol.wire import byte_time

from . import serial_log_writers as w
from .conftest import CAPTURES

FOREIGN = CAPTURES / "foreign"
NAMES = ("spy", "socat", "interceptty", "jpnevulator", "slsnif")
SAMPLES = {name: FOREIGN / f"{name}.log" for name in NAMES}
TIMED = {"spy", "socat", "interceptty", "jpnevulator"}


class _Keep(Sink):
    def __init__(self) -> None:
        self.records = []

    def batch(self, step) -> None:
        self.records += step


def decode(path: Path, fmt: str | None = None, baud: int = w.SAMPLE_BAUD):
    """(records, decoder) of a log read as the commands read it (times laid back to the first byte)."""
    keep = _Keep()
    src = read_input(str(path), fmt, baud=baud, warn=None, options={"baud": baud})
    dec = drive(src, Decoder(DecodeOptions(baud=baud), Linter(LintConfig(baud=baud))), keep)
    return keep.records, dec


def per_byte(chunks, baud: int):
    """(byte, time of that byte's start or None, sender) for every byte of some chunks."""
    bt = byte_time(baud)
    out = []
    for c in chunks:
        sender = marks(c)[0] if len(c) == 2 else c[2]
        for k, b in enumerate(c[0]):
            out.append((b, None if c[1] is None else c[1] + k * bt, sender))
    return out


# ---- the samples ----------------------------------------------------------------------------------
# The simulated hexapod's first 0.1 s (tests/sources/serial_log_writers.py): each servo's model read and
# return, then a torque-on and a goal long packet.
GOLDEN = [(kind, sid) for k in range(1, 19) for kind, sid in (("short", k), ("return", k))] + [("long", 0), ("long", 0)]


@pytest.mark.parametrize("name", NAMES)
def test_golden_sample(name):
    path = SAMPLES[name]
    assert detect_format(str(path)) == name
    recs, dec = decode(path)
    assert [(r.event.kind, r.event.id) for r in recs] == GOLDEN
    assert all(r.event.checksum_ok for r in recs)
    # Who sent each packet, as the log says, is who sends such packets: F009 has nothing to say.
    assert [dec.senders.at(r.event.offset) for r in recs] == [HOST if k in ("short", "long") else SERVO for k, _ in GOLDEN]
    assert [f.code for f in dec.linter.findings] == []
    assert b"".join(r.event.raw for r in recs) == b"".join(d for d, _, _ in w.simulated())
    times = [r.event.t_start for r in recs]
    if name in TIMED:
        assert all(b >= a for a, b in zip(times, times[1:]))
        if name == "spy":  # a write is stamped as it starts, in seconds since the port opened
            assert times[0] == float(path.read_text().split()[0])
        else:  # stamped at arrival: times count from the first request's first byte, its length before
            assert times[0] == 0.0  # the first stamp (no time is negative)
    else:
        assert times == [None] * len(recs)


def test_swapped_sample_gives_f009_once():
    recs, dec = decode(FOREIGN / "spy-swapped.log")
    assert [(r.event.kind, r.event.id) for r in recs] == GOLDEN
    found = [(f.code, f.offset) for f in dec.linter.findings]
    assert found == [("F009", 0)]
    assert "every packet checked" in dec.linter.findings[0].message


@pytest.mark.parametrize("name", ["socat", "jpnevulator"])
def test_wall_clock_start(name):
    reader = read_capture(str(SAMPLES[name]))
    first = next(iter(reader))
    start = reader.context.found["start_time"]
    assert isinstance(start, datetime) and start.tzinfo is not None
    assert first[1] == 0.0  # times run from the first stamp; start_time says when that was
    head = SAMPLES[name].read_text().split("\n", 1)[0]
    assert start.strftime("%Y/%m/%d %H:%M:%S" if name == "socat" else "%Y-%m-%d %H:%M:%S") in head
    reader.close()


def test_slsnif_start_is_its_first_stamp_to_the_second():
    reader = read_capture(str(SAMPLES["slsnif"]))
    list(reader)
    assert reader.context.found["start_time"].replace(tzinfo=None) == w.START.replace(microsecond=0)


# ---- detection: strict, and never another format ------------------------------------------------------
def _others() -> list[Path]:
    mine = set(SAMPLES.values()) | {FOREIGN / "spy-swapped.log"}
    return [p for p in sorted(CAPTURES.rglob("*")) if p.is_file() and p not in mine and p.suffix != ".md"]


@pytest.mark.parametrize("name", NAMES)
def test_each_sniffer_takes_its_own_sample_only(name):
    fmt = foreign.get(name)
    for other, path in SAMPLES.items():
        assert fmt.sniff(path.read_bytes()[:4096]) == (other == name), path
    for path in _others():  # our own captures, the logic analyzers' samples
        assert not fmt.sniff(path.read_bytes()[:4096]), path


@pytest.mark.parametrize("name", NAMES)
def test_the_registry_detects_each_sample(name):
    assert foreign.sniff(SAMPLES[name].read_bytes()[:4096]).name == name


@pytest.mark.parametrize("name", ["interceptty", "slsnif"])
def test_a_pipe_head_cut_at_a_raw_byte_is_still_recognised(name):
    # Both print bytes above 0x7F raw; a pipe's head stops at the first above 0xF7 (captures._read_head).
    data = SAMPLES[name].read_bytes()
    assert foreign.get(name).sniff(data[:data.index(b"\xfa") + 1])


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(chunks=st.lists(st.tuples(st.binary(min_size=1, max_size=24), st.floats(0, 1e6)), min_size=1, max_size=40),
       fmt=st.sampled_from(["hex", "timestamped"]))
def test_our_own_text_captures_are_never_a_serial_log(tmp_path, chunks, fmt):
    from rs30x_sniff.sources.captures import write_capture

    path = tmp_path / "own.txt"
    write_capture(path, sorted(chunks, key=lambda c: c[1]), fmt)
    head = path.read_bytes()[:4096]
    assert not [name for name in NAMES if foreign.get(name).sniff(head)]


def test_a_date_that_is_not_one_is_named(tmp_path):
    lines = w.socat_log(_SMALL, 115200).splitlines()
    k = max(i for i, ln in enumerate(lines) if ln.startswith(("<", ">")))
    lines[k] = lines[k].replace("/11/22 ", "/02/30 ")
    with pytest.raises(CaptureError, match=f":{k + 1}: not a valid date and time"):
        list(read_capture(str(_write(tmp_path, "\n".join(lines) + "\n"))))


def test_our_timestamped_hex_with_three_decimals_is_not_spy(tmp_path):
    p = tmp_path / "a.log"
    p.write_text("000123.500 FA AF 01 00 1E 02 01 84 03 9B\n000124.000 07\n")
    assert detect_format(str(p)) == "timestamped"


# ---- round trips: simulator bytes -> a tool's log -> the same bytes, senders and times -------------
def _round_trip(tmp_path, text, fmt: str, baud: int, sent, *, senders: bool = True, timed: bool = True):
    path = tmp_path / f"rt.{fmt}.log"
    path.write_bytes(text if isinstance(text, bytes) else text.encode("latin-1"))
    assert detect_format(str(path)) == fmt
    got = per_byte(read_input(str(path), None, baud=baud, warn=None, options={"baud": baud}), baud)
    if fmt != "spy":  # wall-clock stamps: times run from the first read's first byte
        first = sent[0][1]
        sent = [(d, t - first, who) for d, t, who in sent]
    want = per_byte(sent, baud)
    assert bytes(b for b, _, _ in got) == bytes(b for b, _, _ in want)
    assert [s for _, _, s in got] == ([s for _, _, s in want] if senders else [None] * len(want))
    if timed:
        worst = max(abs(tg - tw) for (_, tg, _), (_, tw, _) in zip(got, want))
        assert worst <= byte_time(baud), f"{worst * 1e6:.1f} us off"
    else:
        assert {t for _, t, _ in got} == {None}


SENT = w.simulated("hexapod", baud=115200, seconds=0.15)
SENT_9600 = w.simulated("hexapod", baud=9600, seconds=0.3)


@pytest.mark.parametrize("echo", [False, True])
def test_round_trip_spy(tmp_path, echo):
    # Stamps to the millisecond: at 9600 bit/s that is within a byte time.
    _round_trip(tmp_path, w.spy_log(SENT_9600, 9600, echo=echo), "spy", 9600, SENT_9600)


@pytest.mark.parametrize("verbose", [True, False])
@pytest.mark.parametrize("host_left", [True, False])
def test_round_trip_socat(tmp_path, verbose, host_left):
    _round_trip(tmp_path, w.socat_log(SENT, 115200, verbose=verbose, host_left=host_left), "socat", 115200, SENT)


@pytest.mark.parametrize("stamps", [True, False])
def test_round_trip_interceptty(tmp_path, stamps):
    _round_trip(tmp_path, w.interceptty_log(SENT, 115200, stamps=stamps), "interceptty", 115200, SENT, timed=stamps)


@pytest.mark.parametrize("names,ascii,byte_count,width", [
    (("host", "servo"), False, False, 16), (("host", "servo"), True, True, 16), (None, False, False, 16),
    (("pc:0", "bus"), True, False, 5)])
def test_round_trip_jpnevulator(tmp_path, names, ascii, byte_count, width):
    text = w.jpnevulator_log(SENT, 115200, names=names, ascii=ascii, byte_count=byte_count, width=width)
    _round_trip(tmp_path, text, "jpnevulator", 115200, SENT, senders=names is not None)


@pytest.mark.parametrize("hex_,stamps,totals", [(True, True, False), (False, False, True), (True, False, True)])
def test_round_trip_slsnif(tmp_path, hex_, stamps, totals):
    _round_trip(tmp_path, w.slsnif_log(SENT, 115200, hex=hex_, stamps=stamps, totals=totals), "slsnif", 115200,
                SENT, timed=False)


def test_jpnevulator_group_keeps_its_stamp_on_the_first_frame(tmp_path):
    # jpnevulator runs reads closer than --timing-delta together under the first read's stamp.
    req, ret = SENT[0][0], SENT[1][0]
    bt = byte_time(115200)
    arrival = 0.25 + len(req) * bt
    path = tmp_path / "g.log"
    path.write_text(f"2026-11-22 14:14:50.{round(arrival * 1e6):06d}:\n" + " ".join(f"{b:02X}" for b in req + ret) + "\n")
    chunks = list(read_input(str(path), "jpnevulator", baud=115200, warn=None, options={"baud": 115200}))
    assert [c[0] for c in chunks] == [req, ret]
    assert chunks[0][1] == 0.0  # the first frame arrived at the stamp: times count from its first byte
    assert chunks[1][1] == pytest.approx(len(req) * bt, abs=1e-9)  # the rest straight after it


def test_spy_echo_of_a_one_wire_adapter_is_dropped_even_inside_a_read(tmp_path):
    req, ret = SENT[0][0], SENT[1][0]
    lines = [f"000000.010 TX   0000  {next(w._spy_rows(req))[1]}",
             *(f"000000.012 RX   {off:04X}  {row}" for off, row in w._spy_rows(req[:3])),
             *(f"000000.013 RX   {off:04X}  {row}" for off, row in w._spy_rows(req[3:] + ret))]
    path = tmp_path / "echo.log"
    path.write_text("\n".join(lines) + "\n")
    reader = read_capture(str(path))
    chunks = list(reader)
    assert [(c[0], c.sender) for c in chunks] == [(req, HOST), (ret, SERVO)]
    assert reader.context.found["echo_bytes"] == len(req)


def test_socat_side_is_told_by_the_content(tmp_path):
    # socat's '>' is the first address's data, whichever side that is: the side that sends FA AF is the host.
    for host_left in (True, False):
        reader = read_capture(str(_write(tmp_path, w.socat_log(SENT[:4], 115200, host_left=host_left))))
        assert [c.sender for c in reader] == [HOST, SERVO, HOST, SERVO]


def test_socat_without_a_request_makes_no_claim(tmp_path):
    reader = read_capture(str(_write(tmp_path, w.socat_log([SENT[1], SENT[3]], 115200))))
    assert [marks(c) for c in reader] == [(None, None), (None, None)]


def test_spy_control_lines_and_empty_reads_are_skipped(tmp_path):
    text = ("000000.000 Q-RX reset_input_buffer\n000000.001 RTS  inactive\n" + w.spy_log(SENT[:2], 115200)
            + "000001.000 RX   <empty>\n000001.001 BRK  send_break 0.25s\n")
    assert b"".join(c[0] for c in read_capture(str(_write(tmp_path, text)))) == SENT[0][0] + SENT[1][0]


def test_socat_diagnostics_are_skipped(tmp_path):
    text = ("2026/11/22 14:14:49 socat[4242] N PTY is /dev/pts/7\n" + w.socat_log(SENT[:2], 115200)
            + "2026/11/22 14:14:51.123456 socat[4242] N exiting on signal 15\n")
    assert b"".join(c[0] for c in read_capture(str(_write(tmp_path, text)))) == SENT[0][0] + SENT[1][0]


def test_socat_missing_block_is_named(tmp_path):
    lines = w.socat_log(SENT[:6], 115200).splitlines(keepends=True)
    blocks = [i for i, ln in enumerate(lines) if ln.startswith(">")]
    del lines[blocks[1]:blocks[1] + 3]  # the second host block: header, its row, '--'
    text = "".join(lines)
    at = blocks[2] - 3 + 1  # the third host block's header, now the second
    with pytest.raises(CaptureError, match="a block is missing") as e:
        list(read_capture(str(_write(tmp_path, text))))
    assert e.value.line == at


def _write(tmp_path, text) -> Path:
    path = tmp_path / "x.log"
    path.write_bytes(text if isinstance(text, bytes) else text.encode("latin-1"))
    return path


# ---- bad lines: one line, naming the file and line --------------------------------------------------
_SMALL = w.simulated("hexapod", baud=115200, seconds=0.02)[:6]
WRITERS = {
    "spy": lambda: w.spy_log(_SMALL, 115200).encode(),
    "socat": lambda: w.socat_log(_SMALL, 115200).encode(),
    "interceptty": lambda: w.interceptty_log(_SMALL, 115200),
    "jpnevulator": lambda: w.jpnevulator_log(_SMALL, 115200, ascii=True, byte_count=True).encode(),
    "slsnif": lambda: w.slsnif_log(_SMALL, 115200),
}


def _corrupt(name: str, line: bytes) -> bytes | None:
    """A data line of format ``name`` with one hex digit made impossible (None if it is no data line)."""
    if name == "spy" and (b" TX " in line or b" RX " in line):
        return line[:22] + b"G" + line[23:]
    if name == "socat" and line.startswith(b" "):
        return b" g" + line[2:]
    if name == "socat" and line[:1] in b"<>" and line:
        return line.replace(b"length=", b"length=x")
    if name == "interceptty" and b"0x" in line:
        i = line.index(b"0x") + 2
        return line[:i] + b"g" + line[i + 1:]
    if name == "jpnevulator" and b"\t" in line:
        return line[:9] + b"G" + line[10:]
    if name == "jpnevulator" and line[:2] == b"20":
        return line.replace(b"-11-", b"-13-", 1)
    if name == "slsnif" and b"--> " in line:
        i = line.index(b" (") + 2
        return line[:i] + b"g" + line[i + 1:]
    return None


def _bad_line_error(name: str, lines: list[bytes], tmp_path) -> CaptureError:
    path = tmp_path / f"bad.{name}.log"
    path.write_bytes(b"\n".join(lines) + b"\n")
    with pytest.raises(CaptureError) as e:
        list(read_capture(str(path), name))
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(str(path))
    return e.value


@pytest.mark.parametrize("name", NAMES)
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_an_inserted_bad_line_is_named(tmp_path, name, data):
    lines = WRITERS[name]().split(b"\n")
    k = data.draw(st.integers(0, len(lines)), label="at")
    junk = data.draw(st.sampled_from("~!%=?") .flatmap(
        lambda c: st.text(st.characters(min_codepoint=32, max_codepoint=126), max_size=30).map(lambda s: c + s)))
    lines.insert(k, junk.encode())
    err = _bad_line_error(name, lines, tmp_path)
    assert err.line == k + 1 and f":{k + 1}:" in str(err)


@pytest.mark.parametrize("name", NAMES)
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_a_corrupted_line_is_named(tmp_path, name, data):
    lines = WRITERS[name]().split(b"\n")
    candidates = [i for i, ln in enumerate(lines) if _corrupt(name, ln) is not None]
    k = data.draw(st.sampled_from(candidates), label="line")
    lines[k] = _corrupt(name, lines[k])
    err = _bad_line_error(name, lines, tmp_path)
    assert err.line == k + 1 and f":{k + 1}:" in str(err)


# ---- every reading command, detected and forced ------------------------------------------------------
@pytest.fixture(autouse=True)
def _no_config(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no settings file from the repository


@pytest.mark.parametrize("forced", [False, True])
@pytest.mark.parametrize("name", NAMES)
def test_cli_commands(tmp_path, capsys, name, forced):
    path = str(SAMPLES[name])
    fmt = ["--input-format", name] if forced else []
    assert main(["decode", path, *fmt, "--format", "jsonl"]) == 0
    objs = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [(o["type"], o["id"]) for o in objs] == GOLDEN
    assert main(["lint", path, *fmt]) == 0
    assert "0 findings" in capsys.readouterr().out
    assert main(["info", path, *fmt, "--format", "json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["bytes"] == sum(len(d) for d, _, _ in w.simulated())
    out = tmp_path / f"{name}.mcap"
    assert main(["convert", path, *fmt, "-o", str(out)]) == 0
    capsys.readouterr()
    from rs30x_sniff.sources.mcap_reader import McapRawReader

    assert b"".join(r[0] for r in McapRawReader(str(out))) == b"".join(d for d, _, _ in w.simulated())


@pytest.mark.parametrize("name", NAMES)
def test_monitor_replay_keeps_bytes_and_senders(name):
    import threading

    from rs30x_sniff.sources.feeds import ReplaySource

    src = ReplaySource(str(SAMPLES[name]), speed=1000.0)
    try:
        chunks = list(src.chunks(threading.Event()))
    finally:
        src.close()
    want = w.simulated()
    assert b"".join(c[0] for c in chunks) == b"".join(d for d, _, _ in want)
    assert [marks(c)[0] for c in chunks for _ in c[0]] == [who for d, _, who in want for _ in d]


def test_cli_lint_of_the_swapped_sample_warns(capsys):
    assert main(["lint", str(FOREIGN / "spy-swapped.log")]) == 0  # a warning: below --fail-on error
    out = capsys.readouterr().out
    assert "F009 sender-mismatch: every packet checked" in out and "1 finding (1 warning)" in out
    assert main(["lint", str(FOREIGN / "spy-swapped.log"), "--fail-on", "warning"]) == 1


def test_cli_bad_line_is_one_line_and_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.log"
    bad.write_text(w.socat_log(_SMALL, 115200).replace(" fa af", " fa zz", 1))
    assert main(["decode", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{bad}:2: not a socat -x hex dump line" in err


# ---- the real tools -------------------------------------------------------------------------------
def _check_real(path: Path, sent) -> None:
    recs, dec = decode(path, baud=115200)
    assert b"".join(r.event.raw for r in recs) == b"".join(d for d, _, _ in sent)
    assert [dec.senders.at(r.event.offset) for r in recs] == [
        HOST if r.event.kind in ("short", "long") else SERVO for r in recs]
    assert not [f for f in dec.linter.findings if f.code == "F009"]


@pytest.mark.skipif(shutil.which("socat") is None, reason="socat is not installed (CI installs it: .ci/run)")
def test_real_socat_between_two_ptys(tmp_path):
    sent = w.simulated("hexapod", baud=115200, seconds=0.06)
    log = tmp_path / "socat.log"
    w.real_socat(sent, 115200, log)
    assert detect_format(str(log)) == "socat"
    _check_real(log, sent)


def test_real_pyserial_spy_on_a_pty(tmp_path):
    sent = w.simulated("hexapod", baud=115200, seconds=0.06)
    log = tmp_path / "spy.log"
    w.real_spy(sent, 115200, log)
    _check_real(log, sent)


@pytest.mark.skipif(shutil.which("jpnevulator") is None, reason="jpnevulator is not installed")
def test_real_jpnevulator_between_two_ptys(tmp_path):
    sent = w.simulated("hexapod", baud=115200, seconds=0.06)
    log = tmp_path / "jpnevulator.log"
    w.real_jpnevulator(sent, 115200, log)
    _check_real(log, sent)
