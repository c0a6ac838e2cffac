"""Every command gives the same answer for the same capture and options: decode, lint, info, convert, monitor."""

from __future__ import annotations

import json
import threading
from collections import Counter
from pathlib import Path

import pytest
from mcap.reader import make_reader

from rs30x_sniff.cli import build_parser, main
from rs30x_sniff.commands import monitor as monitor_command
from rs30x_sniff.protocol.mcap_names import DIAGNOSTICS_TOPIC, STATS_METADATA_NAME
from rs30x_sniff.tui.feed import Feeder
from rs30x_sniff.tui.store import Store

ROOT = Path(__file__).resolve().parents[2]
BUNDLED = [ROOT / "captures" / "manual-examples.hex", ROOT / "captures" / "session-mixed.thex"]
SCENARIOS = ("hexapod", "setup", "noise", "silent-servo", "duplicate-id", "request-before-return", "bad-checksum",
             "overheat")


def _out(capsys, argv: list[str]) -> str:
    code = main(argv)
    out = capsys.readouterr().out
    assert code in (0, 1), (argv, code)
    return out


def via_decode(capsys, path: Path, opts: list[str]) -> Counter:
    found = Counter()
    for line in _out(capsys, ["decode", str(path), "--format", "jsonl", *opts]).splitlines():
        obj = json.loads(line)
        if obj["type"] == "diagnostic":
            found[(obj["code"], obj["offset"])] += 1
        else:
            for d in obj["diagnostics"]:
                found[(d["code"], d["offset"])] += 1
    return found


def via_lint(capsys, path: Path, opts: list[str]) -> Counter:
    report = json.loads(_out(capsys, ["lint", str(path), "--format", "json", "--fail-on", "never", *opts]))
    return Counter((f["code"], f["offset"]) for f in report)


def via_info(capsys, path: Path, opts: list[str]) -> dict:
    return json.loads(_out(capsys, ["info", str(path), "--format", "json", *opts]))


def via_convert(capsys, path: Path, opts: list[str], out: Path) -> tuple[Counter, dict]:
    """The findings on the MCAP's diagnostics channel, and the statistics in its metadata."""
    _out(capsys, ["convert", str(path), "-o", str(out), "--force", *opts])
    found = Counter()
    with open(out, "rb") as f:
        reader = make_reader(f)
        for _, channel, msg in reader.iter_messages(topics=[DIAGNOSTICS_TOPIC]):
            found[(json.loads(msg.data)["name"].split()[0], json.loads(msg.data)["line"])] += 1
        stats = {m.name: m.metadata for m in reader.iter_metadata()}[STATS_METADATA_NAME]["stats"]
    return found, json.loads(stats)


def via_monitor(path: Path, opts: list[str]) -> Store:
    """The monitor as the command builds it (source, settings, linter), run headless into its store."""
    args = build_parser().parse_args(["monitor", str(path), *opts])
    source, decode_options, config = monitor_command.prepare(args)
    store = Store(config.get("history", 10_000_000), baud=decode_options.baud)
    done = threading.Event()

    def post(b):
        store.add(b.records, b.findings, b.servos, b.bytes_in, b.stats)
        if b.done:
            assert b.error is None, b.error
            done.set()

    Feeder(source, decode_options, post, linter=config["linter_factory"]()).run()
    assert done.is_set()
    return store


def check_agreement(capsys, path: Path, opts: list[str], tmp_path: Path) -> Counter:
    decoded = via_decode(capsys, path, opts)
    linted = via_lint(capsys, path, opts)
    info = via_info(capsys, path, opts)
    converted, mcap_stats = via_convert(capsys, path, opts, tmp_path / "out.mcap")
    store = via_monitor(path, opts)
    monitored = Counter((f.code, f.offset) for f in store.findings)
    assert decoded == linted, "decode vs lint"
    assert converted == linted, "convert's /rs30x/diagnostics vs lint"
    assert monitored == linted, "monitor vs lint"
    by_rule = Counter()
    for (code, _), n in linted.items():
        by_rule[code] += n
    assert {k.split()[0]: v for k, v in info["findings_by_rule"].items()} == dict(by_rule), "info vs lint"
    # The monitor's figures and the MCAP metadata's are info's: one definition of the statistics.
    figures = {k: v for k, v in info.items() if k not in ("input", "linted", "settings")}
    assert mcap_stats == figures
    stats = store.capture_stats
    assert stats["bus_load"] == info["bus_load"] and stats["latency_s"] == info["latency_s"]
    assert {k: v["poll_rate_hz"] for k, v in stats["servos"].items()} == \
        {k: v["poll_rate_hz"] for k, v in info["servos"].items()}
    return linted


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """Each scenario at 9600 and 115200 baud, as timestamped hex and as the MCAP `simulate` writes."""
    d = tmp_path_factory.mktemp("sim")
    made = {}
    for name in SCENARIOS:
        for baud in (9600, 115200):
            for ext in ("thex", "mcap"):
                path = d / f"{name}-{baud}.{ext}"
                assert main(["simulate", "--scenario", name, "--baud", str(baud), "--duration", "1.5", "--seed", "1",
                             "-o", str(path)]) == 0
                made[(name, baud, ext)] = path
    return made


@pytest.mark.parametrize("path", BUNDLED, ids=lambda p: p.name)
def test_bundled_captures_agree(capsys, tmp_path, path):
    found = check_agreement(capsys, path, ["--isolated"], tmp_path)
    assert found, "the bundled captures hold findings: an empty agreement proves nothing"
    # And the MCAP made from it agrees with it.
    mcap = tmp_path / "again.mcap"
    main(["convert", str(path), "-o", str(mcap), "--isolated"])
    capsys.readouterr()
    assert check_agreement(capsys, mcap, ["--isolated"], tmp_path) == found


@pytest.mark.parametrize("baud", (9600, 115200))
@pytest.mark.parametrize("name", SCENARIOS)
def test_simulated_scenarios_agree(capsys, tmp_path, simulated, name, baud):
    thex = simulated[(name, baud, "thex")]
    mcap = simulated[(name, baud, "mcap")]
    from_text = check_agreement(capsys, thex, ["--isolated", "--baud", str(baud)], tmp_path)
    # The MCAP records its baud: no --baud needed, and the answer is the same.
    from_mcap = check_agreement(capsys, mcap, ["--isolated"], tmp_path)
    assert from_mcap == from_text


def test_a_loggers_arrival_stamped_capture_agrees_everywhere(capsys, tmp_path, simulated):
    """Stamped at arrival (as serial loggers stamp reads): every command, the monitor included, lays the
    times back to the first byte the same way, so findings and latencies agree."""
    from rs30x_sniff.sources.captures import read_capture, write_capture
    from rs30x_sniff.protocol.wire import byte_time

    bt = byte_time(9600)
    chunks = [(d, t + len(d) * bt) for d, t in read_capture(str(simulated[("setup", 9600, "thex")]))]
    path = tmp_path / "logger.thex"
    write_capture(path, chunks, "timestamped")
    check_agreement(capsys, path, ["--isolated"], tmp_path)
    assert via_info(capsys, path, ["--isolated"])["settings"]["time_ref"] == "arrival"


def test_a_9600_log_lints_at_its_own_baud(capsys, simulated):
    """The issue's case: `lint` of a 9600-baud MCAP used to decode at 115200 and report B006 on every reply."""
    mcap = simulated[("hexapod", 9600, "mcap")]
    assert not [k for k in via_lint(capsys, mcap, ["--isolated"]) if k[0] == "B006"]
    assert via_info(capsys, mcap, ["--isolated"])["baud"] == 9600


def test_config_file_and_command_line_give_the_same_answer(capsys, tmp_path, simulated, monkeypatch):
    thex = simulated[("setup", 9600, "thex")]
    by_options = check_agreement(capsys, thex, ["--isolated", "--baud", "9600", "--model", "RS304MD",
                                                "--model", "2=RS303MR"], tmp_path)
    (tmp_path / "rs30x-sniff.toml").write_text('baud = 9600\nmodel = "RS304MD"\n[models]\n2 = "RS303MR"\n')
    monkeypatch.chdir(tmp_path)
    by_file = check_agreement(capsys, thex, [], tmp_path)
    assert by_file == by_options
    info = via_info(capsys, thex, [])
    assert info["settings"]["origin"]["baud"].endswith("rs30x-sniff.toml")
    assert info["settings"]["models"] == {"2": "RS303MR"} and info["settings"]["default_model"] == "RS304MD"
    # The command line wins over the file.
    assert via_info(capsys, thex, ["--baud", "115200"])["baud"] == 115200


@pytest.mark.parametrize("argv, needle", [
    (["--baud", "12345"], "--baud 12345: not a rate the servos run at"),
    (["--reply-timeout", "nan"], "--reply-timeout nan: expected a duration"),
    (["--reply-timeout", "-1"], "--reply-timeout -1: must be a finite, positive duration"),
    (["--gap-bytes", "-1"], "--gap-bytes -1.0: must be 0 or more"),
    (["--model", "300=RS304MD"], "--model 300=RS304MD: servo IDs run from 1 to 127"),
    (["--model", "0=RS304MD"], "--model 0=RS304MD: servo IDs run from 1 to 127"),
])
@pytest.mark.parametrize("command", ["decode", "lint", "info", "monitor"])
def test_bad_values_fail_the_same_way_in_every_command(capsys, command, argv, needle):
    assert main([command, str(BUNDLED[0]), "--isolated", *argv]) == 2
    err = capsys.readouterr().err
    assert needle in err and err.count("\n") == 1, err


@pytest.mark.parametrize("body, needle", [
    ("baud = 12345\n", "baud = 12345: not a rate the servos run at"),
    ("reply-timeout = nan\n", "reply-timeout = nan: must be a finite number"),
    ("baudd = 9600\n", "unknown key 'baudd'"),
    ("[models]\n300 = \"RS304MD\"\n", "models.300 = 'RS304MD': servo IDs run from 1 to 127"),
])
@pytest.mark.parametrize("command", ["decode", "lint", "info", "monitor"])
def test_bad_config_values_fail_the_same_way_in_every_command(capsys, tmp_path, monkeypatch, command, body, needle):
    (tmp_path / "rs30x-sniff.toml").write_text(body)
    monkeypatch.chdir(tmp_path)
    assert main([command, str(BUNDLED[0])]) == 2
    err = capsys.readouterr().err
    assert needle in err and err.count("\n") == 1, err


def test_gap_bytes_zero_turns_gap_detection_off_in_a_config_file(capsys, tmp_path, monkeypatch):
    (tmp_path / "rs30x-sniff.toml").write_text("gap-bytes = 0\n")
    monkeypatch.chdir(tmp_path)
    info = via_info(capsys, BUNDLED[1], [])
    assert info["settings"]["gap_bytes"] is None
