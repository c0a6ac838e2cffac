"""The convert, export and info commands: real files, exit codes, one-line errors, lint findings in the log."""

from __future__ import annotations

import json

import jsonschema
from mcap.reader import make_reader

from rs30x_sniff.cli import main
from rs30x_sniff.lint import Linter
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.schemas import schema

from .conftest import ROOT, chunks_of, hexapod_frames

MANUAL = ROOT / "captures" / "manual-examples.hex"


def one_line_error(capsys, text):
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("rs30x-sniff: error:") and "Traceback" not in err, err
    assert text in err, err


def test_convert_writes_lint_findings_as_foxglove_logs(tmp_path, capsys):
    out = tmp_path / "m.mcap"
    assert main(["convert", str(MANUAL), "-o", str(out)]) == 0
    lint = Linter()
    dec = Decoder(DecodeOptions(), linter=lint)
    for data, t in chunks_of(MANUAL):
        dec.feed(data, t)
    dec.close()
    expected = sorted((f.offset, f"{f.code} {f.name}") for f in lint.findings)
    assert expected  # the manual's examples break some of its own rules
    validator = jsonschema.Draft202012Validator(schema("foxglove.Log"))
    with open(out, "rb") as f:
        logs = [json.loads(m.data) for _, _, m in make_reader(f).iter_messages(topics=["/rs30x/diagnostics"])]
    for log in logs:
        validator.validate(log)
        assert log["file"] == str(MANUAL)
    assert sorted((x["line"], x["name"]) for x in logs) == expected
    # The packets channel carries each finding on its record too, as decode --format jsonl does.
    with open(out, "rb") as f:
        packets = [json.loads(m.data) for _, _, m in make_reader(f).iter_messages(topics=["/rs30x/packets"])]
    on_packets = [(d["offset"], f"{d['code']} {d['name']}") for p in packets for d in p["diagnostics"]]
    assert on_packets and set(on_packets) <= set(expected)


def test_select_and_ignore_choose_the_rules(tmp_path):
    out = tmp_path / "m.mcap"
    # A family selected and one of its rules ignored: a refinement (one rule both selected and ignored is refused).
    assert main(["convert", str(MANUAL), "-o", str(out), "--select", "Q004,P", "--ignore", "P009"]) == 0
    with open(out, "rb") as f:
        names = {json.loads(m.data)["name"] for _, _, m in make_reader(f).iter_messages(topics=["/rs30x/diagnostics"])}
    assert names == {"Q004 goal-while-torque-off", "P008 command-packet-format"}


def test_convert_refuses_to_overwrite_without_force(tmp_path, capsys):
    out = tmp_path / "m.mcap"
    out.write_bytes(b"precious")
    assert main(["convert", str(MANUAL), "-o", str(out)]) == 2
    one_line_error(capsys, "already exists (use --force")
    assert out.read_bytes() == b"precious"
    assert main(["convert", str(MANUAL), "-o", str(out), "--force", "--no-lint"]) == 0
    assert out.read_bytes().startswith(b"\x89MCAP0\r\n")
    assert "47 messages" in capsys.readouterr().err
    # Never over its own input, even with --force.
    assert main(["convert", str(out), "-o", str(out), "--force"]) == 2
    one_line_error(capsys, "is the input file")


def test_bad_inputs_are_one_line_errors(tmp_path, capsys):
    assert main(["convert", str(tmp_path / "nope.hex"), "-o", str(tmp_path / "o.mcap")]) == 2
    one_line_error(capsys, "no such file")
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"\x00\x01\x02 not mcap")
    for cmd in (["info", str(junk)], ["export", str(junk), "-o", str(tmp_path / "x.bin")],
                ["convert", str(junk), "-o", str(tmp_path / "y.mcap")]):
        assert main(cmd) == 2
        one_line_error(capsys, "not an MCAP file")
    assert main(["export", str(MANUAL), "-o", str(tmp_path / "x.bin")]) == 2
    one_line_error(capsys, "not an MCAP file")
    assert main(["info", str(MANUAL), "--select", "NO-SUCH-RULE"]) == 2
    one_line_error(capsys, "NO-SUCH-RULE")


def test_a_bad_line_mid_capture_leaves_no_file(tmp_path, capsys):
    """An input error is a failed run: no complete-looking MCAP is left behind (issue 10), and an
    existing file at OUT (with --force) is not touched either."""
    src = tmp_path / "bad.thex"
    lines = [f"{t:.6f} {d.hex(' ')}" for d, t in hexapod_frames(50)]
    src.write_text("\n".join(lines[:30] + ["0.700000 zz 12"] + lines[30:]) + "\n")
    out = tmp_path / "bad.mcap"
    assert main(["convert", str(src), "-o", str(out), "--no-lint"]) == 2
    one_line_error(capsys, ":31: not a hex byte")
    assert not out.exists() and [p.name for p in tmp_path.iterdir()] == ["bad.thex"]
    out.write_bytes(b"keep me")
    assert main(["convert", str(src), "-o", str(out), "--no-lint", "--force"]) == 2
    assert out.read_bytes() == b"keep me"


def test_info_text_and_json_agree_across_formats(tmp_path, hexapod_thex, capsys):
    mcap = tmp_path / "h.mcap"
    assert main(["convert", str(hexapod_thex), "-o", str(mcap), "--no-lint"]) == 0
    capsys.readouterr()
    assert main(["info", str(hexapod_thex), "--format", "json"]) == 0
    a = json.loads(capsys.readouterr().out)
    assert main(["info", str(mcap), "--format", "json"]) == 0
    b = json.loads(capsys.readouterr().out)
    a.pop("input"), b.pop("input")
    # The settings agree; only where the baud came from differs: the MCAP records the rate it was made at.
    sa, sb = a.pop("settings"), b.pop("settings")
    assert sa["origin"]["baud"].startswith("capture (its timestamps") and sb["origin"]["baud"].startswith("capture (the MCAP")
    assert {k: v for k, v in sa.items() if k != "origin"} == {k: v for k, v in sb.items() if k != "origin"}
    assert a == b
    assert a["timed"] and a["by_type"] == {"long": 100, "return": 300, "short": 300}
    assert a["latency_s"]["count"] == 300 and 0.0001 <= a["latency_s"]["p50"] <= a["latency_s"]["p95"] <= 0.0002
    assert set(a["servos"]) == {str(i) for i in range(1, 19)}
    s3 = a["servos"]["3"]
    assert s3["reads"] == s3["returns"] and s3["long_writes"] == 100 and s3["missing"] == 0
    # 3 polls per 20 ms cycle over 18 servos: each servo is read 50/6 times a second.
    assert abs(s3["poll_rate_hz"] - 50 / 6) < 0.3
    assert 0.3 < a["bus_load"] < 1.0
    assert main(["info", str(mcap)]) == 0
    text = capsys.readouterr().out
    assert "latency" in text and "bus load" in text and "poll rate" in text and "Hz" in text


def test_export_to_stdout_and_timestamped_from_untimed(tmp_path, capsysbinary):
    mcap = tmp_path / "m.mcap"
    assert main(["convert", str(MANUAL), "-o", str(mcap), "--no-lint"]) == 0
    capsysbinary.readouterr()
    assert main(["export", str(mcap), "-o", "-", "--format", "bin"]) == 0
    assert capsysbinary.readouterr().out == b"".join(d for d, _ in chunks_of(MANUAL))
    out = tmp_path / "t.thex"
    assert main(["export", str(mcap), "-o", str(out)]) == 0
    # An untimed capture exported with times gets the synthetic ones the log was written with.
    assert out.read_text().startswith("0.000000 FA AF 01")
    assert main(["export", str(mcap), "-o", str(out)]) == 2  # exists, no --force
