"""One grammar and one CLI (issue 33 s2-3): durations, IDs and operators alike in every option and filter; --format
and its aliases; each command's --help offers what applies, with no guard bound; one error prefix."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from rs30x_sniff import cli
from rs30x_sniff.errors import CliError
from rs30x_sniff.settings import load_config
from rs30x_sniff.sinks.parts import parse_keep, parse_span

ROOT = Path(__file__).resolve().parents[2]
SESSION = ROOT / "captures" / "session-mixed.thex"

# Spellings of one time, each of which every duration option and filter must read as the others.
SPELLINGS = {
    0.05: ("0.05", "50ms", "50 ms", "0.05s", "50000us", "50000µs", "5e-2", "50MS"),
    90.0: ("90", "90s", "1.5min", "90000ms", "0.025h"),
    7200.0: ("7200", "2h", "120min", "7200s"),
}
CASES = [(seconds, text) for seconds, texts in SPELLINGS.items() for text in texts]

# Every option that takes a duration, as (argv before the value, the option, where its value lands).
DURATION_OPTIONS = [
    (["decode", "x"], "--reply-timeout", "reply_timeout"),
    (["info", "x"], "--reply-timeout", "reply_timeout"),
    (["record", "/dev/null", "-o", "x.mcap"], "--reply-timeout", "reply_timeout"),
    (["decode", "x"], "--duration", "duration"),
    (["lint", "x"], "--duration", "duration"),
    (["info", "x"], "--duration", "duration"),
    (["record", "/dev/null", "-o", "x.mcap"], "--duration", "duration"),
    (["simulate"], "--duration", "duration"),
]


@pytest.mark.parametrize("seconds, text", CASES)
@pytest.mark.parametrize("argv, option, dest", DURATION_OPTIONS, ids=lambda v: v if isinstance(v, str) else None)
def test_every_duration_option_reads_every_spelling(argv, option, dest, seconds, text):
    args = cli.build_parser().parse_args([*argv, option, text])
    assert getattr(args, dest) == pytest.approx(seconds, rel=1e-12)


@pytest.mark.parametrize("seconds, text", CASES)
@pytest.mark.parametrize("option", ["--pre", "--post", "--split-time", "--keep"])
def test_the_record_times_read_every_spelling(option, seconds, text):
    if option == "--keep":
        if text.strip().replace(".", "").replace("e-", "").isdigit():
            pytest.skip("--keep takes a bare number as neither an age nor a size")
        assert parse_keep(text).seconds == pytest.approx(seconds, rel=1e-12)
    else:
        assert parse_span(option, text) == pytest.approx(seconds, rel=1e-12)


@pytest.mark.parametrize("seconds, text", CASES)
@pytest.mark.parametrize("key", ["reply-timeout", "latency-margin", "flash-write-time"])
def test_a_config_file_reads_every_spelling(tmp_path, key, seconds, text):
    if seconds > 3600:
        pytest.skip("beyond the settings' bound of an hour")
    conf = tmp_path / "rs30x-sniff.toml"
    conf.write_text(f'{key} = "{text}"\n', encoding="utf-8")
    assert load_config(conf)[key.replace("-", "_")] == pytest.approx(seconds, rel=1e-12)


@pytest.mark.parametrize("option, text", [("--reply-timeout", "50x"), ("--duration", "-1s"), ("--duration", "0"),
                                          ("--reply-timeout", "nan")])
def test_a_bad_duration_is_one_line_naming_the_option_and_value(capsys, option, text):
    assert cli.main(["decode", str(SESSION), f"{option}={text}"]) == 2  # "=": -1s is not taken for an option
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("rs30x-sniff: error: decode: ") and f"{option} {text}:" in err


def test_the_reply_timeout_reaches_the_settings_alike(capsys):
    said = []
    for text in ("0.002", "2ms", "2000us"):
        assert cli.main(["info", str(SESSION), "--isolated", "--format", "json", "--reply-timeout", text]) == 0
        said.append(json.loads(capsys.readouterr().out)["settings"]["reply_timeout"])
    assert said == [0.002] * 3


def _decode(capsys, *argv: str) -> str:
    assert cli.main(["decode", str(SESSION), "--isolated", *argv]) == 0
    return capsys.readouterr().out


@pytest.mark.parametrize("spellings", [
    ("latency>100us", "latency>0.1ms", "latency>0.0001", "latency>100000ns", "latency>0.0001s"),
    ("t<1min", "t<60", "t<60s", "t<60000ms", "t<0.0166666666667h"),
    ("t:1.5-3", "t:1500ms-3s", "t=1.5-3", "t:0.025min-0.05min"),
])
def test_a_filter_reads_every_time_spelling_alike(capsys, spellings):
    outputs = {text: _decode(capsys, "--filter", text) for text in spellings}
    first = outputs[spellings[0]]
    assert first.count("\n") > 1  # the filter keeps some lines, not none
    assert all(out == first for out in outputs.values()), [t for t, out in outputs.items() if out != first]


@pytest.mark.parametrize("one, other", [
    ("present_temperature=38", "present_temperature==38"),
    ("id=1", "id==1"),
    ("id:1", "id==1"),
    ("reg:present_temperature==38", "reg:present_temperature=38"),
    ("sev=info", "sev==info"),
])
def test_equality_is_one_operator_in_filters(capsys, one, other):
    out = _decode(capsys, "--filter", one)
    assert out == _decode(capsys, "--filter", other)
    if "sev" not in one:
        assert out.count("\n") > 1


def test_decode_id_reads_id_ranges_as_the_filters_do(capsys):
    by_option = _decode(capsys, "--id", "1-2,3")
    assert by_option == _decode(capsys, "--id", "1", "--id", "2-3")
    assert by_option.count("\n") > 1
    ids = {int(w.removeprefix("id=")) for line in by_option.splitlines() for w in line.split() if w.startswith("id=")}
    assert ids <= {1, 2, 3} and ids


# ---- --format and its aliases ----------------------------------------------------------------------------------
def test_convert_to_is_format(tmp_path):
    a, b = tmp_path / "a.pcapng", tmp_path / "b.pcapng"
    assert cli.main(["convert", str(SESSION), "--isolated", "-o", str(a), "--to", "pcapng"]) == 0
    assert cli.main(["convert", str(SESSION), "--isolated", "-o", str(b), "--format", "pcapng"]) == 0
    assert a.read_bytes() == b.read_bytes() and a.read_bytes()[:4] == b"\x0a\x0d\x0d\x0a"  # a pcapng block


def test_simulate_output_format_is_format(tmp_path):
    a, b = tmp_path / "a.out", tmp_path / "b.out"
    for path, option in ((a, "--output-format"), (b, "--format")):
        assert cli.main(["simulate", "--scenario", "setup", "--duration", "500ms", "-o", str(path), option, "hex"]) == 0
    assert a.read_text() == b.read_text() and a.read_text().startswith("FA AF")


def test_export_table_is_table_of(tmp_path, capsys):
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert cli.main(["export", str(SESSION), "--isolated", "--table", "states", "-o", str(a)]) == 0
    assert cli.main(["table", str(SESSION), "--isolated", "--of", "states", "-o", str(b)]) == 0
    assert cli.main(["export", str(SESSION), "--isolated", "--table=transactions", "-o", str(tmp_path / "t.csv")]) == 0
    assert a.read_text() == b.read_text() and a.read_text().startswith("t,")
    assert (tmp_path / "t.csv").exists()
    capsys.readouterr()
    assert cli.main(["export", str(SESSION), "-o", str(tmp_path / "c.csv")]) == 2  # a table's name: `table --of`
    assert "table --of" in capsys.readouterr().err


# ---- --help: what applies, and no guard bound --------------------------------------------------------------------
def _help(capsys, command: str, *, raw: bool = False) -> str:
    assert cli.main([command, "--help"]) == 0
    out = capsys.readouterr().out
    return out if raw else " ".join(out.split())


def _offered(capsys, command: str) -> set[str]:
    """The options a command's --help lists (each spelling of each)."""
    found = set()
    for line in _help(capsys, command, raw=True).splitlines():
        m = re.match(r"^  (-\S+(?: \S+)?(?:, -\S+(?: \S+)?)*)", line)
        if m:
            found.update(part.split()[0] for part in m[1].split(", "))
    return found


@pytest.mark.parametrize("command", cli.COMMANDS)
def test_help_shows_no_guard_bound(capsys, command):
    text = _help(capsys, command)
    for limit in cli.OPTION_MAX.values():
        assert f"at most {limit:g}" not in text
    assert "e+19" not in text and "65535" not in text


@pytest.mark.parametrize("command, absent, present", [
    ("diff", ("--duration", "--channel"), ("--model", "--baud", "--reply-timeout", "--format")),
    ("export", ("--model", "--baud", "--reply-timeout", "--select", "--no-lint", "--table"), ("--format", "--force")),
    ("record", ("--input-format", "--time-ref", "--time-unit", "--channel"), ("--model", "--baud", "--duration")),
    ("convert", ("--to",), ("--format", "--model")),
    ("simulate", ("--output-format",), ("--format", "--duration", "--seed")),
    ("decode", (), ("--format", "--duration", "--id IDS", "1-127")),
])
def test_a_command_offers_only_what_applies(capsys, command, absent, present):
    offered = _offered(capsys, command)
    for option in absent:
        assert option not in offered, f"{command} offers {option}"
    text = _help(capsys, command)
    for option in present:
        assert (option in offered) if re.fullmatch(r"--[a-z-]+", option) else (option in text), f"{command}: {option}"


def test_a_duration_option_says_a_duration(capsys):
    for command in ("decode", "info", "lint", "record", "simulate"):
        assert "--duration TIME" in _help(capsys, command)
    assert "--reply-timeout TIME" in _help(capsys, "decode")


# ---- one error prefix ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("argv", [
    [],                                                    # no command: the help, exit 2, nothing on stderr
    ["bogus"],                                             # argparse: an unknown command
    ["decode"],                                            # argparse: a required argument missing
    ["decode", str(SESSION), "--nope"],                    # argparse: an unknown option
    ["decode", str(SESSION), "--format", "xml"],           # argparse: an invalid choice
    ["decode", str(SESSION), "--id", "200"],               # an option's type
    ["decode", str(ROOT / "no-such.thex")],                # the command's own error
    ["decode", str(SESSION), "--filter", "latency>5parsecs"],
    ["simulate", "--scenario", "nope", "-o", "-"],
    ["lint", str(SESSION), "--select", "Z999"],
])
def test_every_error_line_has_the_one_prefix(capsys, argv):
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    if not argv:
        assert err == ""
        return
    assert err.count("\n") == 1 and err.startswith("rs30x-sniff: error: ") and "usage:" not in err, err


def test_the_prefix_and_exit_code_of_a_usage_error_from_the_shell():
    proc = subprocess.run([sys.executable, "-m", "rs30x_sniff", "decode", "--reply-timeout", "soon", "x"],
                          capture_output=True, text=True)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.splitlines() == [proc.stderr.strip()] and proc.stderr.startswith("rs30x-sniff: error: decode: ")
    assert "--reply-timeout soon: expected a duration" in proc.stderr


def test_a_cli_error_from_the_parts_names_its_option():
    with pytest.raises(CliError, match="--split-time 500ms: must be at least 1s"):
        parse_span("--split-time", "500ms", least=1.0)
