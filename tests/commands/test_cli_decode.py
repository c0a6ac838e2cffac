"""`rs30x-sniff decode` end to end: text and JSON lines, filters, errors as one line with exit code 2."""

import json
import subprocess
import sys
from pathlib import Path

from rs30x_sniff.cli import main
from tests.conftest import CAPTURES

EXAMPLES = str(CAPTURES / "manual-examples.hex")


def test_text_lines(capsys):
    assert main(["decode", EXAMPLES]) == 0
    out = capsys.readouterr().out.splitlines()
    # 24 events, then the lint findings only the end of input reveals (issue 3).
    assert len([line for line in out if " lint  " not in line]) == 24
    assert any(" lint  Q002 id-change-not-persisted" in line for line in out[24:])
    assert "host  WRITE id=1 goal_position=90.0deg goal_time=5.00s" in "\n".join(out)
    assert any("servo RETURN id=1 present_position=90.0deg" in line and "reply_to=@219" in line for line in out)


def test_jsonl_has_the_documented_keys(capsys):
    assert main(["decode", EXAMPLES, "--format", "jsonl"]) == 0
    objs = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    late = [o for o in objs if o["type"] == "diagnostic"]  # end-of-input lint findings come last (issue 3)
    assert [o["code"] for o in late] == ["Q002"] and objs[-1] is late[-1]
    objs = [o for o in objs if o["type"] != "diagnostic"]
    keys = {"type", "offset", "t", "raw", "checksum_ok", "id", "flag", "address", "length", "count", "fields",
            "flags", "reply_to", "latency_s", "diagnostics"}
    assert all(keys <= set(o) for o in objs)
    long = next(o for o in objs if o["type"] == "long")
    assert [(f["id"], f["name"], f["value"], f["unit"]) for f in long["fields"]] == [
        (1, "goal_position", 10.0, "deg"), (2, "goal_position", 10.0, "deg"), (5, "goal_position", 50.0, "deg")]
    ret = next(o for o in objs if o["type"] == "return")
    assert ret["reply_to"] == 219 and ret["fields"][0]["raw"] == "8403"


def test_id_filter_and_output_file(tmp_path, capsys):
    out = tmp_path / "out.txt"
    assert main(["decode", EXAMPLES, "--id", "5", "-o", str(out)]) == 0
    lines = out.read_text().splitlines()
    assert len(lines) == 1 and "LONG" in lines[0]


def test_verbose_field_tree(capsys):
    assert main(["decode", EXAMPLES, "-v", "--id", "5"]) == 0
    out = capsys.readouterr().out
    assert "[5] goal_position" in out and "F4 01" in out


def test_stdin_raw_bytes():
    data = bytes.fromhex("FAAF0100 1E020184 039B".replace(" ", ""))
    p = subprocess.run([sys.executable, "-m", "rs30x_sniff", "decode", "-"], input=data, capture_output=True)
    assert p.returncode == 0 and "goal_position=90.0deg" in p.stdout.decode()


def test_errors_are_one_line_and_exit_2(tmp_path):
    bad = tmp_path / "bad.hex"
    bad.write_text("FA AF QQ\n")
    for args in (["decode", str(tmp_path / "missing.hex")], ["decode", str(bad)],
                 ["decode", EXAMPLES, "--model", "RS999"]):
        p = subprocess.run([sys.executable, "-m", "rs30x_sniff", *args], capture_output=True, text=True)
        assert p.returncode == 2, args
        assert p.stderr.count("\n") == 1 and "Traceback" not in p.stderr, p.stderr
        assert p.stderr.startswith("rs30x-sniff: error: ")


def test_decode_id_shows_only_that_servos_part_of_a_long_packet(capsys):
    from rs30x_sniff.cli import main

    path = str(Path(__file__).resolve().parents[2] / "captures" / "manual-examples.hex")
    assert main(["decode", path, "--id", "5", "--no-lint"]) == 0
    assert capsys.readouterr().out.split("host  ")[1].strip() == "LONG 5:goal_position=50.0deg"
    assert main(["decode", path, "--id", "5", "--no-lint", "--format", "jsonl"]) == 0
    obj = json.loads(capsys.readouterr().out.splitlines()[0])
    assert obj["type"] == "long" and {f["id"] for f in obj["fields"]} == {5} and obj["vids"] == [1, 2, 5]
