"""The unit of a capture's plain-number times, told by their spacing on the wire; the readers that use it."""

from __future__ import annotations

from pathlib import Path

import pytest

from rs30x_sniff.protocol.baud import rate_fit
from rs30x_sniff.sources.captures import CaptureError, read_capture
from rs30x_sniff.sim import run
from rs30x_sniff.sources.timeunit import (
    ASSUMED, EPOCH_MAX, GIVEN, SIZE, SPACING, detect_unit, epoch_unit, given, problem, resolution, seconds)
from rs30x_sniff.protocol.wire import BAUD_RATES, encode_read

from .gait_capture import gait

EPOCH = 1_732_550_000  # 2024-11-25 15:53:20 UTC, a whole second


def _micros(chunks):
    """Times on a microsecond grid, as whole numbers: each unit below is written from them exactly."""
    return [(d, round(t * 1e6)) for d, t in chunks]


def _in(unit_exp: int, chunks, offset_us: int = 0):
    return [(d, (us + offset_us) / 10 ** (6 - unit_exp)) for d, us in _micros(chunks)]


def _written(us: int, unit: str) -> str:
    """A time of ``us`` microseconds as a capture in ``unit`` writes it (a decimal, never a float's digits)."""
    if unit == "s":
        return f"{us // 10**6}.{us % 10**6:06d}"
    if unit == "ms":
        return f"{us // 1000}.{us % 1000:03d}"
    return str(us) if unit == "us" else str(us * 1000)


def _thex(path: Path, chunks, unit: str, offset_us: int = 0) -> Path:
    path.write_text("".join(f"{_written(us + offset_us, unit)} {d.hex(' ').upper()}\n" for d, us in _micros(chunks)))
    return path


def _session():
    return gait()


# ---- the detector ------------------------------------------------------------------------------------
@pytest.mark.parametrize("exp,unit", [(0, "s"), (3, "ms"), (6, "us"), (9, "ns")])
@pytest.mark.parametrize("baud", [9600, 115200, 230400])
def test_the_spacing_tells_the_unit_at_every_rate(exp, unit, baud):
    chunks = list(run("hexapod", baud=baud, duration=0.6, seed=1))
    found = detect_unit(_in(exp, chunks), step=10.0 ** (exp - 6))
    assert (found.unit, found.how, found.epoch) == (unit, SPACING, False)
    assert found.scale == 10.0 ** -exp and found.start == pytest.approx(chunks[0][1], abs=1e-6)
    assert f"{baud} bit/s" in found.evidence


@pytest.mark.parametrize("exp,unit", [(0, "s"), (3, "ms"), (6, "us"), (9, "ns")])
def test_epoch_times_are_told_and_anchor_the_capture(exp, unit):
    found = detect_unit(_in(exp, _session(), EPOCH * 10**6), step=10.0 ** (exp - 6))
    assert (found.unit, found.epoch) == (unit, True)
    assert found.start == pytest.approx(EPOCH + 0.5, abs=1e-6)  # the first byte's wall clock
    assert found.describe() == f"times in {['seconds', 'milliseconds', 'microseconds', 'nanoseconds'][exp // 3]} " \
                               "since the epoch"


def test_too_few_chunks_go_by_the_size_of_an_epoch_time_else_seconds():
    req = encode_read(1, 0, 30)
    found = detect_unit([(req, 1732550000123.0), (req, 1732550000124.0)])
    assert (found.unit, found.epoch, found.how) == ("ms", True, SIZE)
    assert "2024-11-25" in found.evidence
    found = detect_unit([(req, 500.0), (req, 500.8)])
    assert (found.unit, found.how) == ("s", ASSUMED) and "too few" in found.evidence
    assert detect_unit([(req, None), (req, None)]).how == ASSUMED
    assert detect_unit([]).unit == "s"


def test_sparse_polls_in_seconds_are_not_taken_for_milliseconds():
    # One 8-byte request every 2 s, never answered: read in ms they would fit 38400 bit/s back to back,
    # but nothing of two lengths follows closely: the sample cannot tell, and seconds are assumed.
    req = encode_read(1, 42, 18)
    found = detect_unit([(req, 2.0 * k) for k in range(50)])
    assert (found.unit, found.how) == ("s", ASSUMED)


def test_the_spacing_wins_over_a_first_time_that_looks_like_epoch_seconds():
    # A device's uptime in ms (12 days: 1.0e9 ms) falls where epoch seconds would: the spacing says ms.
    found = detect_unit(_in(3, _session(), 10**12), step=1e-3)
    assert (found.unit, found.how, found.epoch) == ("ms", SPACING, False)


def test_whole_milliseconds_are_not_taken_for_gaps_or_overlaps():
    # Written to the whole ms, a reply 0.794 ms after its request may be stamped 1 ms or 0 ms later;
    # read in seconds, those whole numbers could not show a single frame.
    rounded = [(d, float(round(us / 1000))) for d, us in _micros(_session())]
    found = detect_unit(rounded, step=1.0)
    assert (found.unit, found.how) == ("ms", SPACING)


def test_times_after_2100_or_not_finite_are_problems():
    assert problem(EPOCH_MAX + 1) == "is after the year 2100"
    assert problem(float("nan")) == problem(float("inf")) == "is not a finite number"
    assert problem(-1.0) == "is negative" and problem(0.5) is None
    assert epoch_unit(1732550000123.0) == "ms" and epoch_unit(1.7e9) == "s" and epoch_unit(500.0) is None
    assert given("ms", 1732550000123.0).epoch and given("ms", 1732550000123.0).how == GIVEN
    assert not given("s", 12.5).epoch


def test_a_time_is_shifted_as_a_decimal():
    # 500.794 ms is exactly the float 0.500794 s is: a capture reads the same in every unit.
    assert seconds("500.794", "ms") == float("0.500794")
    assert seconds("500794", "us") == float("0.500794")
    assert seconds("1732550000500794000", "ns") == float("1732550000.500794")
    assert seconds("0.5") == 0.5
    assert resolution("0.000123") == pytest.approx(1e-6) and resolution("500") == 1.0 and resolution("5e3") == 1000.0
    assert resolution("nan") == 0.0


# ---- rates the timestamps rule out -------------------------------------------------------------------
def test_the_spacing_rules_out_slow_rates():
    fit = rate_fit(_session())
    # Each poll's return follows it closer than 8 bytes take below 115200 bit/s.
    assert [r for r in BAUD_RATES if fit.rules_out(r)] == [9600, 14400, 19200, 28800, 38400, 57600, 76800]
    assert fit.slowest() == 115200 and fit.overlaps(115200) == 0 and fit.overlaps(76800) == 100
    assert fit.evidence(76800) == "at 76800 bit/s, 100 of 299 chunks would start before the previous one ended"
    few = rate_fit(_session()[:5])
    assert not few.rules_out(9600) and few.slowest() is None


# ---- the text reader ---------------------------------------------------------------------------------
@pytest.mark.parametrize("unit", ["ms", "us", "ns"])
def test_the_reader_gives_seconds_whatever_the_unit(tmp_path, unit):
    base = _session()
    path = _thex(tmp_path / f"x.{unit}.thex", base, unit)
    reader = read_capture(str(path))
    assert list(reader) == [(d, float(_written(us, "s"))) for d, us in _micros(base)]
    assert reader.time_unit.unit == unit and reader.time_unit.told
    assert reader.context.found["time_unit"] is reader.time_unit


def test_the_reader_keeps_epoch_times_as_wall_clock_seconds(tmp_path):
    path = _thex(tmp_path / "wall.thex", _session(), "ms", EPOCH * 10**6)
    reader = read_capture(str(path))
    first = next(iter(reader))
    assert first[1] == EPOCH + 0.5
    assert reader.time_unit.epoch and reader.time_unit.start == EPOCH + 0.5


def test_a_given_unit_overrides_the_content(tmp_path):
    path = _thex(tmp_path / "ms.thex", _session(), "ms")
    reader = read_capture(str(path), options={"time_unit": "s"})
    assert next(iter(reader))[1] == 500.0 and reader.time_unit.how == GIVEN


def test_the_reader_says_a_told_unit_once_when_asked(tmp_path, capsys):
    path = _thex(tmp_path / "ms.thex", _session(), "ms")
    list(read_capture(str(path), options={"say_time_unit": True}))
    list(read_capture(str(path)))  # a sample read: silent
    err = capsys.readouterr().err.splitlines()
    assert err == [f"rs30x-sniff: {path}: times in milliseconds, told by the content (--time-unit to say otherwise)"]


def test_lines_before_a_bad_line_in_the_sample_are_read_first(tmp_path):
    text = "".join(f"{500 + k}.000 FA AF 01 03 00 00 01 03\n" for k in range(5)) + "505.000 FA ZZ\n"
    path = tmp_path / "bad.thex"
    path.write_text(text)
    got = []
    with pytest.raises(CaptureError) as e:
        for chunk in read_capture(str(path)):
            got.append(chunk)
    assert len(got) == 5 and (e.value.line, e.value.column) == (6, 12)


@pytest.mark.parametrize("bad", ["5e9", "1e300", "99999999999"])
def test_a_time_after_2100_is_an_error_naming_its_line(tmp_path, bad):
    path = tmp_path / "late.thex"
    path.write_text(f"0.1 FA AF\n0.2 FA AF\n  {bad} FA AF\n")
    with pytest.raises(CaptureError) as e:
        list(read_capture(str(path)))
    assert str(e.value) == (f"{path}:3: time {bad!r} in seconds is after the year 2100 "
                            "(--time-unit to read it in another unit)")
    assert (e.value.line, e.value.column) == (3, 3)


def test_epoch_milliseconds_read_as_seconds_are_an_error_at_once(tmp_path):
    path = _thex(tmp_path / "wall.thex", _session(), "ms", EPOCH * 10**6)
    with pytest.raises(CaptureError, match=r":1: time '1732550000500.000' in seconds is after the year 2100"):
        list(read_capture(str(path), options={"time_unit": "s"}))


def test_another_tools_absurd_time_is_an_input_error(tmp_path):
    table = tmp_path / "logic.csv"
    rows = ["name,type,start_time,duration,data"] + [f'"RX","data",{0.1 + k * 1e-4:.6f},8.24e-05,0xFA' for k in range(4)]
    rows[3] = '"RX","data",1e300,8.24e-05,0xFA'
    table.write_text("\n".join(rows) + "\n")
    with pytest.raises(CaptureError) as e:
        list(read_capture(str(table)))
    assert "\n" not in str(e.value) and str(e.value).startswith(f"{table}: the time 1e+300 s")
    assert "after the year 2100" in str(e.value)


def test_a_text_capture_cut_mid_line_is_still_read_in_seconds(tmp_path):
    # `tail -c` of a timestamped capture: its first line is the tail of a line, whose first hex byte
    # ("01") reads as a whole-number time. That one line must not make the capture's times look whole.
    session = Path(__file__).resolve().parents[2] / "captures" / "session-mixed.thex"
    text = session.read_bytes()[2000:20000]
    path = tmp_path / "cut.thex"
    path.write_bytes(text[:text.rindex(b"\n") + 1])
    reader = read_capture(str(path))
    times = [t for _, t in reader]
    assert reader.time_unit.unit == "s"
    assert 1.0 <= times[1] < 2.0  # seconds of the session, not milliseconds


# ---- sparse times and the wall clock (issue 32) ------------------------------------------------------------
BOOT_US = 3_456_789_012.5   # the first time: microseconds since a device booted (57 min)
NOW = 1_767_225_600.0       # 2026-01-01 UTC, the wall clock the reader is given
POLL_US = 20_000            # one poll every 20 ms


def _sparse_polls(n: int = 60, split: bool = False):
    """A poll and its return every POLL_US, as us since boot: one chunk a poll, or the request and the return."""
    from rs30x_sniff.protocol.wire import encode_return

    req, ret = encode_read(1, 42, 2), encode_return(1, 42, b"\x10\x00")
    out = []
    for k in range(n):
        t = BOOT_US + k * POLL_US
        out += [(req, t), (ret, t + 794.0)] if split else [(req + ret, t)]
    return out


@pytest.mark.parametrize("split", [False, True])
def test_sparse_microseconds_since_boot_are_not_epoch_seconds(split):
    # As seconds, 3456789012.5 is 2079: more than a day after now, so no epoch; and the spacing rules out
    # seconds and ms (every poll a time segment apart) and ns (polls overlapping at every rate).
    found = detect_unit(_sparse_polls(split=split), step=0.5, now=NOW)
    assert (found.unit, found.how, found.epoch) == ("us", SPACING, False)
    assert found.start == pytest.approx(3456.7890125)
    assert "read in nanoseconds" in found.evidence and "start before the previous one ended" in found.evidence
    assert "more than 10 s after the previous one" in found.evidence


def test_a_first_time_more_than_a_day_ahead_is_no_epoch():
    ahead = [(d, NOW + 2 * 86400 + k * 0.02) for k, (d, _) in enumerate(_sparse_polls())]
    assert epoch_unit(ahead[0][1], now=NOW) is None and epoch_unit(ahead[0][1]) == "s"  # the clock decides
    found = detect_unit(ahead, now=NOW)
    assert (found.unit, found.epoch) == ("s", False) and "is more than a day after now" in found.evidence
    within = [(d, NOW + 3600 + k * 0.02) for k, (d, _) in enumerate(_sparse_polls())]
    found = detect_unit(within, now=NOW)
    assert (found.unit, found.how, found.epoch) == ("s", SIZE, True)
    assert given("s", ahead[0][1], NOW).epoch is False and given("s", within[0][1], NOW).epoch is True


def test_a_wall_clock_reading_the_wire_rules_out_is_not_taken():
    # Epoch ms in size, but written in us: read in ms, polls 20 us apart would overlap at every rate.
    found = detect_unit([(d, EPOCH * 1e6 + k * POLL_US) for k, (d, _) in enumerate(_sparse_polls())], now=NOW)
    assert found.unit == "us" and found.epoch


def test_the_reader_takes_now_from_its_caller_and_reads_the_clock_itself_otherwise(tmp_path):
    p = tmp_path / "boot.thex"
    p.write_text("".join(f"{t:.1f} {d.hex(' ')}\n" for d, t in _sparse_polls()))
    r = read_capture(str(p), options={"now": NOW})
    chunks = list(r)
    assert r.time_unit.unit == "us" and chunks[0][1] == pytest.approx(3456.7890125)
    assert chunks[1][1] - chunks[0][1] == pytest.approx(0.02)
    r = read_capture(str(p))  # no "now": the reader's own clock, at the edge
    list(r)
    assert r.time_unit.unit == "us"
    # Given a clock in 2080, 3456789012.5 s (2079) is a wall-clock time a day's polls could have (a sparse log
    # stamps its lines hours apart): the clock it is given is what rules the epoch out.
    r = read_capture(str(p), options={"now": 3.5e9})
    list(r)
    assert (r.time_unit.unit, r.time_unit.epoch) == ("s", True)


def test_the_core_reads_no_clock():
    import ast
    import inspect

    from rs30x_sniff.sources import timeunit

    tree = ast.parse(inspect.getsource(timeunit))
    called = {n.func.attr for n in ast.walk(tree) if isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute)}
    imported = {a.name for n in ast.walk(tree) if isinstance(n, (ast.Import, ast.ImportFrom)) for a in n.names}
    assert "time" not in imported and not called & {"now", "today", "utcnow", "time", "monotonic"}


def test_seam_gap_is_the_decoders():
    from rs30x_sniff.decode.framing import SEAM_GAP_S
    from rs30x_sniff.sources.timeunit import SEAM_GAP

    assert SEAM_GAP == SEAM_GAP_S
