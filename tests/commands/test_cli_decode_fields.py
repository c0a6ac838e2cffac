"""`rs30x-sniff decode --format fields`: chosen columns, tab-separated, each meaning what the JSON lines say."""

import csv
import io
import json
import subprocess
import sys

import pytest

from rs30x_sniff.cli import main
from rs30x_sniff.sim import run
from rs30x_sniff.sources.captures import write_capture
from tests.conftest import CAPTURES

KEYS = ["type", "offset", "t", "t_end", "raw", "checksum_ok", "id", "flag", "address", "length", "count", "op",
        "model", "reply_to", "reply", "latency_s", "status"]
REGISTERS = ["goal_position", "goal_time", "present_position", "present_temperature", "torque_enable"]


def _text(v):
    return "" if v is None else ("true" if v is True else "false" if v is False else str(v))


@pytest.fixture
def hexapod(tmp_path):
    """The simulator's hexapod: RS303MR and RS304MD servos on one bus, long packets to both models at once."""
    path = tmp_path / "hexapod.thex"
    write_capture(path, run("hexapod", baud=230400, duration=0.5), "timestamped")
    return str(path)


@pytest.mark.parametrize("capture", ["manual-examples.hex", "session-mixed.thex", "hexapod"])
def test_each_column_is_the_json_lines_value(capture, capsys, request):
    path = request.getfixturevalue("hexapod") if capture == "hexapod" else str(CAPTURES / capture)
    assert main(["decode", path, "--format", "jsonl"]) == 0
    objs = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    objs = [o for o in objs if o["type"] != "diagnostic"]
    assert main(["decode", path, "--fields", ",".join(KEYS + REGISTERS + ["diagnostics"])]) == 0
    lines = [line.split("\t") for line in capsys.readouterr().out.splitlines() if not line.startswith("#")]
    assert lines[0] == KEYS + REGISTERS + ["diagnostics"]
    rows = lines[1:]
    assert len(rows) == len(objs) > 10
    for row, obj in zip(rows, objs):
        assert row[:len(KEYS)] == [_text(obj[k]) for k in KEYS]
        for i, name in enumerate(REGISTERS, len(KEYS)):
            assert row[i] == " ".join(_text(f["value"]) for f in obj["fields"] if f["name"] == name)
        assert row[-1] == " ".join(d["code"] for d in obj["diagnostics"])
    assert any(" " in row[len(KEYS)] for row in rows) or capture == "session-mixed.thex"  # a long packet's values


@pytest.mark.parametrize("capture", ["manual-examples.hex", "session-mixed.thex"])
def test_the_packets_tables_columns_say_the_same(capture, capsys):
    # One language: a column both outputs have holds the same text (the packets table's findings were empty
    # until it ran the linter too).
    names = ["offset", "type", "direction", "id", "op", "flag", "address", "length", "count", "status", "reply_to",
             "latency_s", "findings"]
    path = str(CAPTURES / capture)
    assert main(["table", path, "--of", "packets", "-o", "-", "--format", "csv"]) == 0
    table = [[row[k] for k in names] for row in csv.DictReader(io.StringIO(capsys.readouterr().out))]
    assert main(["decode", path, "--fields", ",".join(names)]) == 0
    lines = [line.split("\t") for line in capsys.readouterr().out.splitlines() if not line.startswith("#")]
    assert lines[1:] == table
    assert any(row[-1] for row in table)


def test_a_long_packets_values_are_joined_and_id_keeps_its_servos(capsys):
    path = str(CAPTURES / "manual-examples.hex")
    assert main(["decode", path, "--fields", "kind,id,vids,goal_position"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "kind\tid\tvids\tgoal_position"
    assert "long\t0\t1 2 5\t10.0 10.0 50.0" in out
    assert main(["decode", path, "--fields", "kind,goal_position", "--id", "5"]) == 0
    assert capsys.readouterr().out.splitlines() == ["kind\tgoal_position", "long\t50.0"]


def test_a_finding_the_end_reveals_is_a_comment_line(capsys):
    assert main(["decode", str(CAPTURES / "manual-examples.hex"), "--fields", "offset"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[-1].startswith("# Q002 id-change-not-persisted @")


@pytest.mark.parametrize("args,said", [
    (["--fields", "present_postion"], "--fields: no column 'present_postion' (did you mean present_position?)"),
    (["--format", "fields"], "--format fields: name the columns with --fields"),
    (["--format", "jsonl", "--fields", "t"], "--fields: only with --format fields, not jsonl"),
    (["--fields", " , "], "--fields: no columns"),
])
def test_a_bad_column_is_one_line_before_the_input_opens(args, said):
    proc = subprocess.run([sys.executable, "-m", "rs30x_sniff", "decode", "/no/such/capture.hex", *args],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.count("\n") == 1 and said in proc.stderr, proc.stderr
