"""Times in any unit, and rates, checked against the wire: the same capture in s, ms, us or epoch ms reads the same."""

from __future__ import annotations

import argparse
import json
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader

from rs30x_sniff.cli import main
from rs30x_sniff.commands.common import settings_for
from rs30x_sniff.sources.captures import write_capture
from rs30x_sniff.sim import run
from rs30x_sniff.sim.scenarios import SCENARIOS

from ..sources.gait_capture import gait

EPOCH = 1_732_550_000  # 2024-11-25 15:53:20 UTC


def _written(us: int, unit: str) -> str:
    if unit == "s":
        return f"{us // 10**6}.{us % 10**6:06d}"
    if unit == "ms":
        return f"{us // 1000}.{us % 1000:03d}"
    return str(us)


def _thex(path: Path, chunks, unit: str, offset_us: int = 0) -> str:
    """The chunks as timestamped hex in ``unit``, their times on one microsecond grid (so every unit
    writes the same instants exactly)."""
    path.write_text("".join(f"{_written(round(t * 1e6) + offset_us, unit)} {d.hex(' ').upper()}\n"
                            for d, t in chunks if d))
    return str(path)


def _lint(capsys, path: str, *argv: str) -> list[dict]:
    main(["lint", path, "--format", "json", "--isolated", *argv])
    return [{k: v for k, v in f.items() if k not in ("t", "file")} for f in json.loads(capsys.readouterr().out)]


def _info(capsys, path: str, *argv: str) -> tuple[dict, str]:
    assert main(["info", path, "--format", "json", "--isolated", *argv]) == 0
    cap = capsys.readouterr()
    return json.loads(cap.out), cap.err


def _figures(info: dict) -> dict:
    return {k: v for k, v in info.items() if k not in ("input", "settings")}


_NUM = re.compile(r"(-?\d+\.\d+)")
_WALL = re.compile(r" \[\d{4}-\d\d-\d\d [^]]* UTC\]")


def _same_but_rounding(a, b, where: str = "") -> None:
    """``b``, from the epoch capture, is ``a`` up to float rounding: a float holds an epoch time to
    0.24 us, so times within a microsecond or a last printed digit, and figures made from spans
    (loads, rates) to 1e-4 of themselves; capture times EPOCH later; wall-clock fields in ``b`` only."""
    if isinstance(a, dict):
        assert set(a) == set(b), where
        for k in a:
            if k in ("wall", "first_wall"):  # only a moment with a time has a wall clock
                assert a[k] is None and (b[k] is None or b[k].startswith("2024-11-25T")), (where, k, b[k])
            elif k in ("t", "first_t") and isinstance(a[k], float):
                assert b[k] - EPOCH == pytest.approx(a[k], abs=2e-6), (where, k, a[k], b[k])
            else:
                _same_but_rounding(a[k], b[k], f"{where}/{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            _same_but_rounding(x, y, f"{where}[{i}]")
    elif isinstance(a, float) and isinstance(b, float):
        assert math.isclose(a, b, rel_tol=1e-4, abs_tol=2e-6), (where, a, b)
    elif isinstance(a, str) and isinstance(b, str):
        b = _WALL.sub("", b)
        pa, pb = _NUM.split(a), _NUM.split(b)
        assert pa[::2] == pb[::2], (where, a, b)
        for x, y in zip(pa[1::2], pb[1::2]):
            digits = len(x.partition(".")[2])
            off = min(abs(float(x) - float(y)), abs(float(x) + EPOCH - float(y)))  # a duration, or a capture time
            assert off <= 1.01 * 10.0 ** -digits, (where, a, b)
    else:
        assert a == b, where


# ---- the same capture in every unit -------------------------------------------------------------------
# Each example runs eight commands: no shrinking (minutes); a failure prints the scenario, seed and rate.
@settings(max_examples=6, deadline=None, phases=[Phase.explicit, Phase.reuse, Phase.generate],
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(name=st.sampled_from(sorted(SCENARIOS)), seed=st.integers(0, 50),
       baud=st.sampled_from([9600, 57600, 115200, 230400]), duration=st.sampled_from([0.5, 0.8]))
def test_the_same_capture_in_every_unit_gives_the_same_findings_and_figures(tmp_path_factory, capsys, name, seed,
                                                                            baud, duration):
    d = tmp_path_factory.mktemp("units")
    chunks = list(run(name, baud=baud, seed=seed, duration=duration))
    files = {unit: _thex(d / f"{unit}.thex", chunks, unit) for unit in ("s", "ms", "us")}
    files["epoch-ms"] = _thex(d / "epoch-ms.thex", chunks, "ms", EPOCH * 10**6)
    findings = {k: _lint(capsys, p) for k, p in files.items()}
    infos = {k: _info(capsys, p)[0] for k, p in files.items()}
    for unit in ("ms", "us"):
        assert findings[unit] == findings["s"]
        assert _figures(infos[unit]) == _figures(infos["s"])
        assert infos[unit]["settings"]["time_unit"] == unit
    # Epoch times are kept as wall-clock seconds: the same figures up to float rounding, plus the wall clock.
    assert infos["epoch-ms"]["settings"]["time_unit"] == "ms"
    assert [(f["code"], f["offset"], f["id"]) for f in findings["epoch-ms"]] == \
        [(f["code"], f["offset"], f["id"]) for f in findings["s"]]
    _same_but_rounding(findings["s"], findings["epoch-ms"])
    _same_but_rounding(_figures(infos["s"]), _figures(infos["epoch-ms"]))


def test_an_epoch_ms_capture_is_anchored_at_its_wall_clock(tmp_path, capsys):
    path = _thex(tmp_path / "wall.thex", gait(), "ms", EPOCH * 10**6)
    info, err = _info(capsys, path)
    assert err.splitlines() == [f"rs30x-sniff: {path}: times in milliseconds since the epoch, told by the content "
                                "(--time-unit to say otherwise)"]
    assert info["settings"]["origin"]["time_unit"].startswith("capture (times in milliseconds since the epoch")
    plain, _ = _info(capsys, _thex(tmp_path / "s.thex", gait(), "s"))
    assert info["duration_s"] == pytest.approx(plain["duration_s"], abs=1e-6)
    out = tmp_path / "wall.mcap"
    assert main(["convert", path, "-o", str(out), "--isolated"]) == 0
    with open(out, "rb") as f:
        stats = make_reader(f).get_summary().statistics
    assert stats.message_start_time == pytest.approx((EPOCH + 0.5) * 1e9, abs=1e3)
    assert main(["table", path, "--of", "transactions", "-o", str(tmp_path / "t.csv"), "--isolated"]) == 0
    header, first = (tmp_path / "t.csv").read_text().splitlines()[:2]
    assert header.startswith("t,wall_time,") and ",2024-11-25T15:53:20.502457+00:00," in first  # the first poll


def test_time_unit_overrides_the_content_from_either_layer(tmp_path, capsys):
    path = _thex(tmp_path / "ms.thex", gait(), "ms")
    assert main(["decode", path, "--format", "jsonl", "--no-lint", "--isolated", "--time-unit", "s"]) == 0
    out, err = capsys.readouterr()
    assert [json.loads(line)["t"] for line in out.splitlines()[:2]] == [500.0, 502.457] and err == ""
    info, _ = _info(capsys, path, "--time-unit", "s")
    assert info["settings"]["time_unit"] == "s" and info["settings"]["origin"]["time_unit"] == "command line"
    conf = tmp_path / "rs30x-sniff.toml"
    conf.write_text('time-unit = "us"\n')
    plain = _thex(tmp_path / "s.thex", gait(), "s")
    assert main(["decode", plain, "--format", "jsonl", "--no-lint", "--config", str(conf)]) == 0
    assert json.loads(capsys.readouterr().out.splitlines()[1])["t"] == 0.502457e-6
    assert main(["info", plain, "--format", "json", "--config", str(conf)]) == 0
    assert json.loads(capsys.readouterr().out)["settings"]["origin"]["time_unit"] == str(conf)
    conf.write_text('time-unit = "minutes"\n')
    assert main(["info", plain, "--config", str(conf)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "time-unit = 'minutes': must be one of s, ms, us, ns" in err


def test_a_pipe_says_its_unit_itself():
    text = "".join(f"{_written(round(t * 1e6), 'us')} {d.hex(' ')}\n" for d, t in gait())
    proc = subprocess.run([sys.executable, "-m", "rs30x_sniff", "info", "-", "--isolated"], input=text.encode(),
                          capture_output=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    err = proc.stderr.decode().splitlines()
    assert err == ["rs30x-sniff: -: times in microseconds, told by the content (--time-unit to say otherwise)"]
    assert "at 115200 bit/s" in proc.stdout.decode()


# ---- bad times ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("bad,why", [("nan", "is not a finite, non-negative number"),
                                     ("inf", "is not a finite, non-negative number"),
                                     ("1e400", "is not a finite, non-negative number"),
                                     ("-1e300", "is not a finite, non-negative number"),
                                     ("5e9", "in seconds is after the year 2100"),
                                     ("1e300", "in seconds is after the year 2100")])
@pytest.mark.parametrize("command", ["decode", "info", "lint", "convert"])
def test_a_bad_time_is_one_line_naming_the_file_and_line(tmp_path, capsys, bad, why, command):
    path = tmp_path / "bad.thex"
    path.write_text(f"0.1 FA AF 01 03 00 00 01 03\n0.2 FA AF 01 03 00 00 01 03\n{bad} FA AF 01 03 00 00 01 03\n")
    argv = [command, str(path), "--isolated"] + (["-o", str(tmp_path / "x.mcap")] if command == "convert" else [])
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err == f"rs30x-sniff: error: {path}:3: time {bad!r} {why}" + \
        (" (--time-unit to read it in another unit)" if "2100" in why else "") + "\n"
    assert not (tmp_path / "x.mcap").exists()


# ---- rates the timestamps contradict ----------------------------------------------------------------------
def _settings(path: str, **options):
    return settings_for(argparse.Namespace(isolated=True, **options), path)


def test_a_baud_the_timestamps_contradict_is_warned_about_and_unsupported(tmp_path, capsys):
    path = _thex(tmp_path / "bus.thex", gait(), "s")
    s = _settings(path, baud=9600)
    err = capsys.readouterr().err
    assert s.baud == 9600  # the command line wins ...
    assert err.splitlines() == [f"rs30x-sniff: warning: {path}: its timestamps show 115200 bit/s, not the 9600 "
                                "given (command line): at 9600 bit/s, 299 of 299 chunks would start before the "
                                "previous one ended"]
    assert s.timing_unsupported == "the timestamps contradict --baud 9600: they show 115200 bit/s"
    # ... and a rate they allow is not contradicted, nor the capture read without --baud.
    for options in ({"baud": 115200}, {"baud": 230400}, {}):
        s = _settings(path, **options)
        assert s.timing_unsupported is None and capsys.readouterr().err == ""


def test_the_default_gives_way_to_the_rate_the_timestamps_allow(tmp_path, capsys):
    # At 230400 bit/s, with gaps that leave no run of back-to-back bytes to name the rate, but returns
    # that would overlap their polls at 115200 or 153600.
    path = tmp_path / "fast.thex"
    write_capture(path, gait(230400), "timestamped")
    info, err = _info(capsys, str(path))
    assert info["baud"] == 230400 and info["settings"]["origin"]["baud"].startswith("capture (its timestamps: ")
    assert err.splitlines() == [f"rs30x-sniff: {path}: 230400 bit/s, from its timestamps: at 115200 bit/s, 100 of "
                                "299 chunks would start before the previous one ended (--baud to say otherwise)"]
    s = _settings(str(path))
    assert s.baud == 230400 and s.timing_unsupported is None


def test_timestamps_that_fit_no_rate_leave_the_timing_unsupported(tmp_path, capsys):
    # Every chunk stamped 10 us after the one before: no rate of table 4.7 carries 8 bytes that fast.
    path = tmp_path / "bunched.thex"
    write_capture(path, [(d, 0.5 + k * 1e-5) for k, (d, _) in enumerate(gait())], "timestamped")
    s = _settings(str(path))
    err = capsys.readouterr().err
    assert s.baud == 115200 and s.timing_unsupported == ("the timestamps contradict the default 115200 bit/s: they "
                                                         "fit no rate of table 4.7")
    assert err.startswith(f"rs30x-sniff: warning: {path}: its timestamps fit no rate of table 4.7, not even the "
                          "default 115200 bit/s: at 115200 bit/s, ")


# ---- any unit, sparse or dense, since boot or not: the same figures (issue 32) ------------------------------
BOOT_US = 3_456_789_012  # microseconds since a device booted (57 min): as seconds it would be 2079


def _written_any(us: int, unit: str) -> str:
    return str(us * 1000) if unit == "ns" else _written(us, unit)


def _thex_any(path: Path, chunks, unit: str, offset_us: int) -> str:
    path.write_text("".join(f"{_written_any(round(t * 1e6) + offset_us, unit)} {d.hex(' ').upper()}\n"
                            for d, t in chunks if d))
    return str(path)


def _sparse(baud: int, split: bool, polls: int = 60) -> list[tuple[bytes, float]]:
    """One servo polled every 20 ms, its return 100 us after the poll's end: one line a poll, or two."""
    from rs30x_sniff.protocol.wire import byte_time, encode_read, encode_return

    req, ret = encode_read(1, 42, 2), encode_return(1, 42, b"\x10\x00")
    out = []
    for k in range(polls):
        t = 0.5 + k * 0.02
        out += [(req, t), (ret, round(t + len(req) * byte_time(baud) + 100e-6, 6))] if split else [(req + ret, t)]
    return out


@settings(max_examples=6, deadline=None, phases=[Phase.explicit, Phase.reuse, Phase.generate],
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(traffic=st.one_of(st.tuples(st.just("sim"), st.sampled_from(sorted(SCENARIOS)), st.integers(0, 50)),
                         st.tuples(st.just("sparse"), st.booleans(), st.just(0))),
       baud=st.sampled_from([57600, 115200]), boot=st.booleans())
def test_a_capture_rescaled_to_any_unit_gives_the_same_figures(tmp_path_factory, capsys, traffic, baud, boot):
    d = tmp_path_factory.mktemp("rescaled")
    kind, a, b = traffic
    chunks = list(run(a, baud=baud, seed=b, duration=0.5)) if kind == "sim" else _sparse(baud, a)
    offset = BOOT_US if boot else 0
    infos = {}
    for unit in ("s", "ms", "us", "ns"):
        info, err = _info(capsys, _thex_any(d / f"{unit}.thex", chunks, unit, offset), "--baud", str(baud))
        infos[unit] = info
        # The unit read is the one written, and said when it is not plain seconds.
        assert info["settings"].get("time_unit", "s") == unit, (unit, err)
        assert (unit == "s") == ("times in" not in err), err
    for unit in ("ms", "us", "ns"):
        assert _figures(infos[unit]) == _figures(infos["s"]), unit
    assert infos["s"]["segments"] == 1  # no unit made its gaps into time segments


def test_the_issues_sparse_boot_capture(tmp_path, capsys):
    # 3456789012.5, then 20,000 later for each poll: read as epoch seconds in 2079 it made 60 time segments, a
    # bus load of 100 % and a 0.047 s duration, and said nothing.
    from rs30x_sniff.protocol.wire import encode_read, encode_return

    poll = (encode_read(1, 42, 2) + encode_return(1, 42, b"\x10\x00")).hex(" ").upper()
    path = tmp_path / "boot.thex"
    path.write_text("".join(f"{3456789012.5 + k * 20000:.1f} {poll}\n" for k in range(60)))
    told, err = _info(capsys, str(path))
    assert err.splitlines() == [f"rs30x-sniff: {path}: times in microseconds, told by the content "
                                "(--time-unit to say otherwise)"]
    given_us, _ = _info(capsys, str(path), "--time-unit", "us")
    assert _figures(told) == _figures(given_us)
    assert told["segments"] == 1 and told["duration_s"] == pytest.approx(59 * 0.02 + 18 * 10 / 115200, rel=1e-3)
    assert told["bus_load"] < 0.1


def test_epoch_seconds_are_said_too(tmp_path, capsys):
    path = _thex(tmp_path / "epoch.thex", gait(), "s", EPOCH * 10**6)
    info, err = _info(capsys, path)
    assert err.splitlines() == [f"rs30x-sniff: {path}: times in seconds since the epoch, told by the content "
                                "(--time-unit to say otherwise)"]
    assert info["settings"]["time_unit"] == "s"
    assert main(["info", path, "--isolated"]) == 0
    out = capsys.readouterr().out
    assert "  times      in seconds since the epoch; stamped at " in out  # how: the line above, and origin
    plain = _thex(tmp_path / "plain.thex", gait(), "s")
    assert main(["info", plain, "--isolated"]) == 0
    cap = capsys.readouterr()
    assert "  times      in seconds, told by the content; stamped at " in cap.out and cap.err == ""


def test_a_whole_number_time_on_one_line_is_a_time_and_said(tmp_path, capsys):
    path = tmp_path / "one.txt"
    path.write_text("1767225600 FA AF 01 03 00 00 01 03\n")
    assert main(["decode", str(path), "--format", "jsonl", "--no-lint", "--isolated"]) == 0  # JSON: absolute times
    cap = capsys.readouterr()
    assert json.loads(cap.out.splitlines()[0])["t"] == 1767225600.0
    assert f"rs30x-sniff: warning: {path}: its first column (1767225600) is read as times, not hex bytes" in cap.err
    assert main(["decode", str(path), "--format", "jsonl", "--no-lint", "--isolated", "--input-format", "hex"]) == 0
    assert json.loads(capsys.readouterr().out.splitlines()[0])["offset"] == 0  # as bytes: 17 67 22 56 00 ...


# ---- an MCAP's times against --baud, as a timestamped capture's -----------------------------------------------
def test_an_mcap_with_a_contradicted_baud_is_told_as_a_text_capture_is(tmp_path, capsys):
    chunks = list(run("hexapod", baud=57600, seed=1, duration=1.0))
    thex = tmp_path / "bus.thex"
    write_capture(thex, chunks, "timestamped")
    mcap = tmp_path / "bus.mcap"
    assert main(["convert", str(thex), "-o", str(mcap), "--isolated", "--no-lint"]) == 0
    capsys.readouterr()
    results = {}
    for path in (thex, mcap):
        info, err = _info(capsys, str(path), "--baud", "28800")
        results[path.suffix] = info, err.replace(str(path), "FILE")
    (ti, terr), (mi, merr) = results[".thex"], results[".mcap"]
    assert merr == terr and terr.startswith("rs30x-sniff: warning: FILE: its timestamps show 57600 bit/s, not the "
                                            "28800 given (command line): ")
    why = "the timestamps contradict --baud 28800: they show 57600 bit/s"
    for info in (ti, mi):
        assert info["timing_unsupported"] == why and info["bus_load"] is None
        assert info["latency_s"]["absent"] == why and info["latency_s"]["p50"] is None
    # Its own rate, recorded, is neither warned about nor said to come from the timestamps.
    info, err = _info(capsys, str(mcap))
    assert err == "" and info["baud"] == 57600 and info["timing_unsupported"] is None


# ---- the latency floor: code and docs say one number ------------------------------------------------------------
def test_the_latency_floor_is_one_number_in_code_and_docs(tmp_path, capsys):
    from rs30x_sniff.decode.pairing import MIN_REPLY_LATENCY
    from rs30x_sniff.protocol.wire import byte_time, encode_read, encode_return

    root = Path(__file__).resolve().parents[2]
    us = round(MIN_REPLY_LATENCY * 1e6)
    readme = " ".join((root / "README.md").read_text().split())
    live = " ".join((root / "docs" / "live-capture.md").read_text().split())
    assert f"less than {us} us after it, has no latency" in readme and "table 4.6 No. 7" in readme
    assert f"less than {us} µs after its request" in live
    assert not re.search(r"sooner after it than a servo can answer \(100 us", readme)
    # A reply 10 us inside the floor has no latency; 10 us outside it has its own.
    req, ret = encode_read(1, 42, 2), encode_return(1, 42, b"\x10\x00")
    for gap, expected in ((MIN_REPLY_LATENCY - 10e-6, None), (MIN_REPLY_LATENCY + 10e-6, MIN_REPLY_LATENCY + 10e-6)):
        chunks = []
        for k in range(20):
            t = 0.5 + k * 0.02
            chunks += [(req, t), (ret, t + len(req) * byte_time(115200) + gap)]
        path = tmp_path / f"floor{k}{gap}.thex"
        write_capture(path, chunks, "timestamped")
        info, _ = _info(capsys, str(path), "--baud", "115200")
        if expected is None:
            assert info["latency_s"]["p50"] is None and info["latency_s"]["unmeasured"] == 20
        else:
            assert info["latency_s"]["p50"] == pytest.approx(expected, abs=2e-6)
