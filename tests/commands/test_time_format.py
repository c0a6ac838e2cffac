"""--time-format on the command line: decode's lines, info's text, a config file's time-format, and what keeps
the capture's own times (JSON)."""

from __future__ import annotations

import json

import pytest

from rs30x_sniff.cli import main
from rs30x_sniff.decode.decoder import Decoder
from rs30x_sniff.sim import run as simulate
from rs30x_sniff.sinks.mcap.writer import McapSink
from rs30x_sniff.sinks.pipeline import drive
from tests.conftest import CAPTURES

T0 = 1795832946.25  # 2026-11-28 02:29:06.25 UTC
SOCAT = str(CAPTURES / "foreign" / "socat.log")     # a log with wall-clock stamps (local time, no zone)
SESSION = str(CAPTURES / "session-mixed.thex")       # times counted from the capture's start



@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """An MCAP as `record` writes one from a port: the overheat scenario on wall-clock times."""
    path = tmp_path_factory.mktemp("rec") / "overheat.mcap"
    chunks = [(d, T0 + t) for d, t in simulate("overheat", duration=4, seed=1)]
    drive(iter(chunks), Decoder(), McapSink(str(path), source="/dev/ttyUSB0", baud=115200, time_base="wall"))
    return str(path)


def first_lines(capsys, *args: str, n: int = 2) -> list[str]:
    assert main(["decode", *args]) == 0
    return capsys.readouterr().out.splitlines()[:n]


def test_decode_of_a_recording_in_each_form(recorded, capsys, utc):
    req = "@0        host  READ id=1 read[model_number]"
    assert first_lines(capsys, recorded)[0] == f"    0.000000 {req}"  # the default: since the first byte
    assert first_lines(capsys, recorded, "--time-format", "relative")[1].startswith("    0.000800 @8 ")
    assert first_lines(capsys, recorded, "--time-format", "absolute")[0] == f"2026-11-28 02:29:06.250050 {req}"
    assert first_lines(capsys, recorded, "--time-format", "epoch")[0] == f"1795832946.250050 {req}"
    assert [line[:12] for line in first_lines(capsys, recorded, "--time-format", "delta", n=3)] == [
        "    0.000000", "    0.000800", "    0.000918"]


def test_jsonl_keeps_the_capture_times(recorded, capsys):
    assert main(["decode", recorded, "--format", "jsonl", "--time-format", "absolute"]) == 0
    first = json.loads(capsys.readouterr().out.splitlines()[0])
    assert first["t"] == pytest.approx(T0 + 0.00005, abs=1e-6)


def test_a_log_with_wall_clock_stamps(capsys):
    # The log's own stamp (local time) comes back as the time of day, whatever the zone; relative is its own 0.
    assert first_lines(capsys, SOCAT, "--time-format", "absolute")[0].startswith("2026-11-22 17:59:41.806102 @0 ")
    assert first_lines(capsys, SOCAT)[0].startswith("    0.000000 @0 ")


def test_a_capture_without_a_wall_clock_is_never_given_a_date(capsys):
    default = first_lines(capsys, SESSION, n=5)
    assert default[0].startswith("    0.500000 @0 ")  # its own times, as lint and info give them
    for mode in ("absolute", "epoch"):
        assert main(["decode", SESSION, "--time-format", mode]) == 0
        out, err = capsys.readouterr()
        assert out.splitlines()[:5] == default
        assert err.count(f"--time-format {mode}: the capture's times are not wall-clock times") == 1


def test_an_untimed_capture_has_no_times(capsys):
    for mode in ("relative", "absolute", "delta", "epoch"):
        assert first_lines(capsys, str(CAPTURES / "manual-examples.hex"), "--time-format", mode)[0].startswith(
            "           - @0 ")


def test_info_says_when_things_happened_in_the_form(recorded, capsys, utc):
    assert main(["info", recorded]) == 0
    out = capsys.readouterr().out
    assert "temperature_limit 25x, first at 3.43 s" in out
    assert "reached its temperature limit at 3.43 s [2026-11-28 02:29:09.678 UTC]" in out
    assert "179583" not in out  # no count of seconds since 1970 anywhere
    assert main(["info", recorded, "--time-format", "absolute"]) == 0
    out = capsys.readouterr().out
    assert "reached its temperature limit at 2026-11-28 02:29:09.68 " in out and " s [" not in out
    assert main(["info", recorded, "--time-format", "epoch"]) == 0
    assert "first at 1795832949.68 s" in capsys.readouterr().out
    assert main(["info", recorded, "--format", "json", "--time-format", "absolute"]) == 0
    happened = json.loads(capsys.readouterr().out)["what_happened"]
    hot = next(h for h in happened if "temperature limit" in h["text"])
    assert hot["t"] == pytest.approx(T0 + 3.428, abs=0.01) and hot["wall"].startswith("2026-11-28T02:29:09.6")


def test_info_of_a_file_is_unchanged_by_default(capsys):
    assert main(["info", SESSION]) == 0
    plain = capsys.readouterr().out
    assert main(["info", SESSION, "--time-format", "delta"]) == 0  # a summary has no previous line: since start
    assert capsys.readouterr().out == plain


def test_a_config_file_sets_the_form_and_the_command_line_wins(recorded, tmp_path, capsys, utc):
    conf = tmp_path / "rs30x-sniff.toml"
    conf.write_text('time-format = "epoch"\n')
    assert first_lines(capsys, recorded, "--config", str(conf))[0].startswith("1795832946.250050 ")
    assert first_lines(capsys, recorded, "--config", str(conf), "--time-format", "relative")[0].startswith(
        "    0.000000 ")
    conf.write_text('time-format = "local"\n')
    assert main(["decode", recorded, "--config", str(conf)]) == 2
    err = capsys.readouterr().err
    assert "time-format = 'local': must be one of relative, absolute, delta, epoch" in err
    assert "Traceback" not in err


def test_a_bad_form_on_the_command_line_is_one_line(recorded, capsys):
    assert main(["decode", recorded, "--time-format", "local"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--time-format: invalid choice: 'local'" in err


@pytest.mark.parametrize("command", ["decode", "info", "monitor", "record"])
def test_one_option_with_one_help(command, capsys):
    assert main([command, "--help"]) == 0
    help_text = " ".join(capsys.readouterr().out.split())
    assert "--time-format {relative,absolute,delta,epoch}" in help_text
    assert "relative (default): seconds since the capture's start" in help_text
