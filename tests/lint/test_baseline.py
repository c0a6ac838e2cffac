"""`lint --write-baseline` / `--baseline` (issue 24): fingerprints that survive a new recording of the same bus,
new findings only toward the exit code, absorbed and stale counts in every report, and bad baselines refused."""

from __future__ import annotations

import json
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import jsonschema
import pytest
from hypothesis import given
from hypothesis import strategies as st

from rs30x_sniff.cli import main
from rs30x_sniff.lint import Finding
from rs30x_sniff.lint.params import DURATION, TIME, Measured, said
from rs30x_sniff.lint.baseline import BASELINE_KIND, BASELINE_VERSION, Baseline, fingerprint, stable_message
from rs30x_sniff.protocol.wire import RETURN_FIRST, encode_short
from rs30x_sniff.sim import SimBus, run as sim_run
from rs30x_sniff.sim.scenarios import get as get_scenario
from rs30x_sniff.sources.captures import TIMESTAMPED, write_capture

from .test_cli import SARIF_SUBSET

# Scenarios with findings of several shapes: missing replies, bad sums, status flags, duplicate replies,
# early requests with their latencies, noise bursts of varying length.
SCENARIOS = ("silent-servo", "bad-checksum", "overheat", "duplicate-id", "request-before-return", "noise")


@pytest.fixture(autouse=True)
def _no_config(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no pyproject.toml / rs30x-sniff.toml above unless a test writes one


def lint(capsys, *argv) -> tuple[int, str, str]:
    code = main(["lint", *map(str, argv)])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def simulate(capsys, tmp_path: Path, scenario: str, seed: int, duration: float | None = None) -> Path:
    out = tmp_path / f"{scenario}-{seed}.thex"
    more = ["--duration", str(duration)] if duration else []
    assert main(["simulate", "--scenario", scenario, "--seed", str(seed), "-o", str(out), *more]) == 0
    capsys.readouterr()
    return out


def findings_json(capsys, *argv) -> list[dict]:
    code, out, err = lint(capsys, *argv, "--format", "json", "--fail-on", "never")
    assert code == 0, err
    return json.loads(out)


def finding(code="B002", message="ID 4 did not answer", id=4, offset=10, t=1.0) -> Finding:
    return Finding(code, "x", "error", message, offset, t, id)


# ---- fingerprints -----------------------------------------------------------------------------------
@pytest.mark.parametrize("code, a, b", [
    ("B001", "sent 0.101 ms after request @2306 to ID 5, whose reply was still due",
             "sent right after request @629 to ID 5, whose reply was still due"),
    ("B003", "return from ID 5 that no request asked for; 2.102 ms after request @3983, past the reply timeout",
             "return from ID 5 that no request asked for; 2.109 ms after request @629, past the reply timeout"),
    ("B009", "another reply to request @10084 to ID 2", "another reply to request @1090 to ID 2"),
    ("F001", "Sum is 0x1C but the bytes from ID on XOR to 0x46", "Sum is 0x19 but the bytes from ID on XOR to 0x43"),
    ("F002", "2 byte(s) with no frame header", "9 byte(s) with no frame header"),
    ("B006", "reply 9.906 ms after the request; return_delay 0 (assumed) means 0.100 ms",
             "reply 7.500 ms after the request; return_delay 0 (assumed) means 0.100 ms"),
    ("M003", "goal_position=-2000 (raw) on ID 3 outside -1500-1500 (-200.0deg)",
             "goal_position=1700 (raw) on ID 3 outside -1500-1500 (170.0deg)"),
    ("Q004", "goal_position 12.5deg to ID 3, whose torque is off", "goal_position -3.0deg to ID 3, whose torque is off"),
    ("F005", "the capture's clock goes backwards once: first here, stamped 1.000000 s, 2.000 ms before",
             "the capture's clock goes backwards 4 times: first here, stamped 7.250000 s, 0.300 ms before"),
    ("U001", "ID 3 at 61.5", "ID 3 at 64"),                      # a user's rule: its numbers are measurements
])
def test_what_varies_between_recordings_is_left_out(code, a, b):
    assert stable_message(code, a) == stable_message(code, b)
    assert "@" not in stable_message(code, a) or "@*" in stable_message(code, a)


@pytest.mark.parametrize("code, a, b", [
    ("B002", "ID 4 did not answer; the request asked for a return of model_number",
             "ID 4 did not answer; the request asked for a return of addresses 42-59 (present_position to present_voltage)"),
    ("M003", "goal_position=-2000 (raw) on ID 3 outside -1500-1500", "max_torque=120 (raw) on ID 3 outside 0-100"),
    ("M001", "writes read-only model_number of ID 1", "writes read-only firmware_version of ID 1"),
    ("P001", "flag 0x80 sets reserved bit 7", "flag 0xC0 sets reserved bit 7"),       # the flag is the packet's shape
    ("B009", "another reply to request @10 to ID 2", "another reply to request @10 to ID 3"),
    ("F006", "2 chunks stamped before the bytes ahead could have crossed the wire at 115200 bit/s",
             "2 chunks stamped before the bytes ahead could have crossed the wire at 57600 bit/s"),
    ("S002", "ID 2 is within 10 degC of its temperature limit", "ID 3 is within 10 degC of its temperature limit"),
    ("U001", "ID 3 at 61.5", "ID 4 at 61.5"),                    # a user's rule keeps its servo IDs
])
def test_what_names_the_behaviour_is_kept(code, a, b):
    assert stable_message(code, a) != stable_message(code, b)


def test_fingerprint_is_code_servo_and_stable_message():
    assert fingerprint(finding()) == "B002:4:ID 4 did not answer"
    assert fingerprint(finding(id=None, message="x")) == "B002:-:x"
    # Offsets and times are not in it; the servo is, even where the message does not name it.
    assert fingerprint(finding(offset=1, t=None)) == fingerprint(finding(offset=99, t=5.0))
    assert fingerprint(finding(code="B009", message="m", id=2)) != fingerprint(finding(code="B009", message="m", id=3))


def test_the_file_is_sorted_stable_and_counts_what_it_saw():
    fs = [finding("S004", "ID 2 received a packet it could not accept", 2),
          finding("B002", "ID 4 did not answer", 4, offset=5),
          finding("B002", "ID 4 did not answer", 4, offset=50),
          finding("B002", "ID 1 did not answer", 1)]
    import io
    a, b = io.StringIO(), io.StringIO()
    Baseline.of(fs).dump(a)
    Baseline.of(list(reversed(fs))).dump(b)
    assert a.getvalue() == b.getvalue() and a.getvalue().endswith("}\n")
    data = json.loads(a.getvalue())
    assert data["kind"] == BASELINE_KIND and data["version"] == BASELINE_VERSION == 2
    assert [(e["code"], e["id"], e["count"]) for e in data["entries"]] == [("B002", 1, 1), ("B002", 4, 2),
                                                                          ("S004", 2, 1)]
    assert data["entries"][1] == {"fingerprint": "B002:4:ID 4 did not answer", "code": "B002", "id": 4,
                                  "message": "ID 4 did not answer", "count": 2}


# ---- the acceptance: another seed of the same scenario is absorbed, an injected fault is the only new finding
@pytest.mark.parametrize("scenario", SCENARIOS)
def test_baseline_of_one_seed_absorbs_another_seed(capsys, tmp_path, scenario):
    # The second recording is longer too: other offsets, other times, other counts of the same behaviour
    # (not bad-checksum's: it corrupts a write to the next servo every half second, so a longer run is
    # another behaviour, the fault on servos it never reached before).
    longer = None if scenario == "bad-checksum" else get_scenario(scenario).duration * 1.5
    first, second = simulate(capsys, tmp_path, scenario, 1), simulate(capsys, tmp_path, scenario, 2, longer)
    base = tmp_path / "baseline.json"
    code, out, err = lint(capsys, first, "--write-baseline", base)
    assert code == 0 and out == "" and f"to {base}" in err
    expected = findings_json(capsys, second)
    assert expected, f"{scenario} seed 2 has no findings: the test would prove nothing"
    assert lint(capsys, second)[0] == 1 or scenario == "noise"  # without the baseline it fails (noise: warnings)
    code, out, err = lint(capsys, second, "--baseline", base, "--fail-on", "warning")
    assert code == 0, out
    assert "\n0 findings in 1 file.\n" in out
    assert f"{len(expected)} finding{'s' if len(expected) != 1 else ''} absorbed by the baseline {base}" in out
    report = json.loads(lint(capsys, second, "--baseline", base, "--format", "json")[1])
    assert report["findings"] == [] and report["baseline"]["absorbed"] == len(expected)


def _write(path: Path, chunks) -> Path:
    write_capture(path, chunks, TIMESTAMPED)
    return path


class LosesOneReply(SimBus):
    """A bus on which one reply of servo ``sid`` after ``after`` seconds never reaches the wire."""

    def __init__(self, sid: int, after: float) -> None:
        super().__init__()
        self.sid, self.after, self.lost = sid, after, False

    def attach(self, servo):
        if servo.id == self.sid:
            receive = servo.receive

            def lossy(ev, t):
                reply = receive(ev, t)
                if reply is not None and not self.lost and t >= self.after and reply[0][0] == RETURN_FIRST:
                    self.lost = True
                    return None
                return reply
            servo.receive = lossy
        return super().attach(servo)


def _new_findings(capsys, capture: Path, base: Path) -> list[dict]:
    code, out, err = lint(capsys, capture, "--baseline", base, "--format", "json")
    report = json.loads(out)
    assert code == (1 if report["findings"] else 0), err
    return report["findings"]


@pytest.mark.parametrize("scenario", ["silent-servo", "overheat"])
def test_a_missing_reply_is_the_only_new_finding(capsys, tmp_path, scenario):
    base = tmp_path / "baseline.json"
    assert lint(capsys, simulate(capsys, tmp_path, scenario, 1), "--write-baseline", base)[0] == 0
    bus = LosesOneReply(sid=1, after=1.5)
    faulty = _write(tmp_path / "lost.thex", sim_run(scenario, seed=2, bus=bus))
    assert bus.lost
    new = _new_findings(capsys, faulty, base)
    assert [(f["code"], f["id"]) for f in new] == [("B002", 1)], new
    assert new[0]["message"].startswith("ID 1 did not answer")


@pytest.mark.parametrize("scenario", ["bad-checksum", "duplicate-id"])
def test_an_out_of_range_write_is_the_only_new_finding(capsys, tmp_path, scenario):
    base = tmp_path / "baseline.json"
    assert lint(capsys, simulate(capsys, tmp_path, scenario, 1), "--write-baseline", base)[0] == 0
    chunks = list(sim_run(scenario, seed=2))
    t_end = chunks[-1][1] + 0.05
    chunks.append((encode_short(3, 0, 0x23, bytes((120,))), t_end))  # max_torque 120 %: above 100
    faulty = _write(tmp_path / "bad-write.thex", chunks)
    new = _new_findings(capsys, faulty, base)
    assert [(f["code"], f["id"]) for f in new] == [("M003", 3)], new
    # The same capture without the baseline: the fault among every other finding.
    assert len(findings_json(capsys, faulty)) > 1


def test_a_new_servo_with_the_same_fault_is_new(capsys, tmp_path):
    # silent-servo: ID 4 never answers; a baseline of it must not absorb ID 1 going silent too.
    base = tmp_path / "baseline.json"
    assert lint(capsys, simulate(capsys, tmp_path, "silent-servo", 1), "--write-baseline", base)[0] == 0
    entries = json.loads(base.read_text())["entries"]
    assert {e["id"] for e in entries} == {4}
    assert Baseline.load(str(base)).split([finding(message="ID 1 did not answer; the request asked for a "
                                                           "return of model_number", id=1)])[0]


# ---- stale entries and the report formats --------------------------------------------------------------
@pytest.fixture
def mixed(capsys, tmp_path):
    """A baseline of silent-servo and bad-checksum, and a capture of silent-servo plus an out-of-range write:
    B002 of ID 4 absorbed, the F001/S004 entries stale, one new M003."""
    base = tmp_path / "baseline.json"
    firsts = [simulate(capsys, tmp_path, s, 1) for s in ("silent-servo", "bad-checksum")]
    assert lint(capsys, *firsts, "--write-baseline", base)[0] == 0
    chunks = list(sim_run("silent-servo", seed=2))
    chunks.append((encode_short(3, 0, 0x23, bytes((120,))), chunks[-1][1] + 0.05))
    capture = _write(tmp_path / "mixed.thex", chunks)
    absorbed = [f for f in findings_json(capsys, capture) if f["code"] == "B002"]
    return base, capture, len(absorbed)


def test_text_report_counts_absorbed_and_lists_stale(capsys, mixed):
    base, capture, absorbed = mixed
    code, out, err = lint(capsys, capture, "--baseline", base)
    assert code == 1 and err == ""
    assert " M003 value-out-of-range: max_torque=120 (raw) on ID 3 outside 0-100" in out
    assert " B002 " not in out  # absorbed: not listed
    assert "\n1 finding (1 error) in 1 file.\n" in out
    assert f"{absorbed} findings absorbed by the baseline {base}" in out
    assert "8 baseline entries no longer seen (stale" in out
    assert "    F001 ID 1: Sum is 0x1C but the bytes from ID on XOR to 0x46 (1 before)\n" in out
    assert "    S004 ID 4: ID 4 received a packet it could not accept (1 before)\n" in out


def test_only_new_findings_count_toward_the_exit_code(capsys, tmp_path, mixed):
    base, capture, _ = mixed
    assert lint(capsys, capture, "--baseline", base, "--fail-on", "error")[0] == 1
    # Every finding of the capture in the baseline: exit 0, whatever --fail-on says.
    full = tmp_path / "full.json"
    assert lint(capsys, capture, "--write-baseline", full)[0] == 0
    for fmt in ("text", "json", "junit", "sarif", "github"):
        assert lint(capsys, capture, "--baseline", full, "--fail-on", "info", "--format", fmt)[0] == 0, fmt


def test_json_report_holds_new_findings_absorbed_count_and_stale(capsys, mixed):
    base, capture, absorbed = mixed
    code, out, _ = lint(capsys, capture, "--baseline", base, "--format", "json")
    report = json.loads(out)
    assert code == 1
    assert [f["code"] for f in report["findings"]] == ["M003"]
    assert report["baseline"]["file"] == str(base) and report["baseline"]["absorbed"] == absorbed
    stale = report["baseline"]["stale"]
    assert sorted({(e["code"], e["id"]) for e in stale}) == [(c, i) for c in ("F001", "S004") for i in (1, 2, 3, 4)]
    assert all(e["count"] == 1 and e["fingerprint"].startswith(e["code"] + ":") for e in stale)
    # Without --baseline the json report is the plain list it always was.
    assert isinstance(json.loads(lint(capsys, capture, "--format", "json")[1]), list)


def test_sarif_marks_new_and_unchanged(capsys, mixed):
    base, capture, absorbed = mixed
    code, out, _ = lint(capsys, capture, "--baseline", base, "--format", "sarif")
    log = json.loads(out)
    jsonschema.validate(log, SARIF_SUBSET)
    results = log["runs"][0]["results"]
    states = {(r["ruleId"], r["baselineState"]) for r in results}
    assert states == {("M003", "new"), ("B002", "unchanged")}
    assert sum(r["baselineState"] == "unchanged" for r in results) == absorbed
    assert log["runs"][0]["properties"]["baseline"]["absorbed"] == absorbed
    assert len(log["runs"][0]["properties"]["baseline"]["stale"]) == 8
    # Without a baseline no result carries a baselineState (SARIF: only against a baseline).
    plain = json.loads(lint(capsys, capture, "--format", "sarif")[1])
    assert all("baselineState" not in r for r in plain["runs"][0]["results"])
    assert "properties" not in plain["runs"][0]


def test_junit_and_github_report_only_new_findings(capsys, mixed):
    base, capture, _ = mixed
    code, out, _ = lint(capsys, capture, "--baseline", base, "--format", "junit")
    suites = ET.fromstring(out)
    failed = [c.get("name") for c in suites.iter("testcase") if c.find("failure") is not None]
    assert code == 1 and failed == ["M003 value-out-of-range"]
    code, out, _ = lint(capsys, capture, "--baseline", base, "--format", "github")
    assert code == 1
    assert [line.split("title=")[1].split("::")[0] for line in out.splitlines()] == ["M003 value-out-of-range"]


# ---- writing, and bad baselines ----------------------------------------------------------------------
def test_write_baseline_to_stdout_and_never_over_a_file_unasked(capsys, tmp_path):
    capture = simulate(capsys, tmp_path, "silent-servo", 1)
    code, out, err = lint(capsys, capture, "--write-baseline", "-")
    assert code == 0 and json.loads(out)["kind"] == BASELINE_KIND
    assert "2 entries (20 findings) to stdout" in err
    base = tmp_path / "b.json"
    base.write_text("keep me")
    code, out, err = lint(capsys, capture, "--write-baseline", base)
    assert code == 2 and err.count("\n") == 1 and "already exists (use --force" in err
    assert base.read_text() == "keep me"
    assert lint(capsys, capture, "--write-baseline", base, "--force")[0] == 0
    assert json.loads(base.read_text())["entries"]


def test_write_baseline_leaves_nothing_when_an_input_cannot_be_read(capsys, tmp_path):
    capture = simulate(capsys, tmp_path, "silent-servo", 1)
    base = tmp_path / "b.json"
    code, out, err = lint(capsys, capture, tmp_path / "missing.thex", "--write-baseline", base)
    assert code == 2 and out == "" and "missing.thex" in err and "baseline not written" in err
    assert not base.exists() and list(tmp_path.glob(".b.json*")) == []


@pytest.mark.parametrize("text, says", [
    (None, "cannot read the baseline"),
    ("{", "invalid JSON at line 1 column 2"),
    ("[]", "not a baseline"),
    (json.dumps({"kind": BASELINE_KIND, "version": 9, "entries": []}), "baseline version 9"),
    (json.dumps({"kind": BASELINE_KIND, "version": 1, "entries": {}}), "\"entries\" must be a list"),
    (json.dumps({"kind": BASELINE_KIND, "version": 1, "entries": [{"code": "B002"}]}), "entry 1: \"fingerprint\""),
    (json.dumps({"kind": BASELINE_KIND, "version": 1, "entries": [
        {"fingerprint": "B002:4:x", "code": "B002", "id": "four"}]}), "entry 1: \"id\""),
    (json.dumps({"kind": BASELINE_KIND, "version": 1, "entries": [
        {"fingerprint": "B002:4:x", "code": "B002", "id": 4}] * 2}), "entry 2: fingerprint 'B002:4:x' is there twice"),
])
def test_a_bad_baseline_is_one_line_and_exit_2(capsys, tmp_path, text, says):
    capture = simulate(capsys, tmp_path, "silent-servo", 1)
    base = tmp_path / "b.json"
    if text is not None:
        base.write_text(text)
    code, out, err = lint(capsys, capture, "--baseline", base)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and str(base) in err and says in err, err
    assert "Traceback" not in err


def test_baseline_options_that_cannot_go_together(capsys, tmp_path):
    capture = simulate(capsys, tmp_path, "silent-servo", 1)
    base = tmp_path / "b.json"
    code, _, err = lint(capsys, capture, "--baseline", base, "--write-baseline", tmp_path / "c.json")
    assert code == 2 and "--baseline and --write-baseline" in err
    code, _, err = lint(capsys, capture, "--write-baseline", base, "-o", tmp_path / "r.txt")
    assert code == 2 and "-o and --write-baseline" in err
    assert not base.exists() and not (tmp_path / "r.txt").exists()


# ---- typed parameters (issue 32): the fingerprint is the message's key, not a reading of its text ----------
SLOW = ('[[rule]]\ncode = "U001"\nname = "slow-reply"\nwhen = "kind:return latency>0.01ms"\n'
        'message = "ID {id} replied {latency} after its request, at {t}"\n')


def _shift_replies(src: Path, dst: Path, by: float) -> Path:
    """The capture with every return packet stamped ``by`` seconds later: each latency moves by ``by``."""
    lines = []
    for line in src.read_text().splitlines():
        t, _, rest = line.partition(" ")
        if rest.startswith("FD DF"):
            line = f"{float(t) + by:.6f} {rest}"
        lines.append(line)
    dst.write_text("\n".join(lines) + "\n")
    return dst


@pytest.mark.parametrize("by", [10e-6, -10e-6, 1e-6])
def test_a_user_rules_latency_moving_never_makes_its_finding_new(capsys, tmp_path, by):
    (tmp_path / "rs30x-sniff.toml").write_text(SLOW)
    first = simulate(capsys, tmp_path, "overheat", 1, 1.0)
    found = findings_json(capsys, first, "--select", "U001")
    assert found and all(" ms after its request, at " in f["message"] for f in found)
    assert not any("e-0" in f["message"] for f in found)  # units, never float noise (7.955555555555548e-05)
    base = tmp_path / "baseline.json"
    assert lint(capsys, first, "--select", "U001", "--write-baseline", base)[0] == 0
    entries = json.loads(base.read_text())["entries"]
    assert entries and all(e["fingerprint"] == f"U001:{e['id']}:ID {e['id']} replied * after its request, at *"
                           for e in entries)
    moved = _shift_replies(first, tmp_path / "moved.thex", by)
    assert findings_json(capsys, moved, "--select", "U001") != found  # the messages did change
    code, out, _ = lint(capsys, moved, "--select", "U001", "--baseline", base)
    assert code == 0 and "\n0 findings in 1 file.\n" in out


@given(st.floats(min_value=1e-6, max_value=0.05), st.floats(min_value=-20e-6, max_value=20e-6),
       st.floats(min_value=0, max_value=1e6), st.floats(min_value=-50, max_value=150))
def test_a_measured_value_is_written_with_its_unit_and_left_out_of_the_key(latency, moved, t, temperature):
    template = "ID {id} at {present_temperature}, {latency} after its request, at {t}"
    a = said(template, {"id": 3, "latency": Measured(latency, DURATION), "t": Measured(t, TIME),
                        "present_temperature": Measured(temperature, "degC")})
    b = said(template, {"id": 3, "latency": Measured(latency + moved, DURATION), "t": Measured(t + 1, TIME),
                        "present_temperature": Measured(temperature + 1.5, "degC")})
    assert a.key == b.key == "ID 3 at *, * after its request, at *"
    assert re.fullmatch(r"ID 3 at -?[\d.]+ degC, -?\d+\.\d{3} ms after its request, at \d+\.\d{6} s", a), a
    f, g = finding("U001", a, 3), finding("U001", b, 3)
    assert fingerprint(f) == fingerprint(g)
    assert fingerprint(finding("U001", a, 4)) != fingerprint(f)  # the servo stays in it


def test_a_unit_the_message_writes_itself_is_not_written_twice():
    m = said("ID {id} at {present_temperature} degC, {latency} ms", {"id": 2, "present_temperature": Measured(61, "degC"),
                                                                      "latency": Measured(8e-05, DURATION)})
    assert m == "ID 2 at 61 degC, 0.080 ms" and m.key == "ID 2 at * degC, * ms"
    assert said("{x}", {"x": Measured(12.300000000000001, "deg")}) == "12.3 deg"


def test_a_version_1_baseline_is_still_read_with_its_own_fingerprints(capsys, tmp_path):
    capture = simulate(capsys, tmp_path, "silent-servo", 1)
    base = tmp_path / "v2.json"
    assert lint(capsys, capture, "--write-baseline", base)[0] == 0
    data = json.loads(base.read_text())
    assert data["version"] == 2
    # What version 1 wrote: the same entries, fingerprinted by the text (built-in messages are plain text).
    old = Baseline({k: v for k, v in Baseline.load(str(base)).entries.items()}, version=1)
    v1 = tmp_path / "v1.json"
    with open(v1, "w") as fh:
        old.dump(fh)
    assert json.loads(v1.read_text())["version"] == 1
    code, out, _ = lint(capsys, capture, "--baseline", v1)
    assert code == 0 and "\n0 findings in 1 file.\n" in out
    # A typed message in a version 1 baseline matches by its text, as version 1 did.
    f = finding("U001", said("ID {id} at {v}", {"id": 3, "v": Measured(61, "degC")}), 3)
    assert fingerprint(f, 1) == "U001:3:ID 3 at * degC" and fingerprint(f) == "U001:3:ID 3 at *"
    assert Baseline({fingerprint(f, 1): None}, version=1).split([f]) == ([], [f])


def test_findings_carry_their_typed_parameters_across_processes():
    import pickle
    m = said("ID {id} {latency}", {"id": 3, "latency": Measured(8e-05, DURATION)})
    f = pickle.loads(pickle.dumps(finding("U001", m, 3)))
    assert f.message == "ID 3 0.080 ms" and fingerprint(f) == "U001:3:ID 3 *"
    assert f.params == {"id": 3, "latency": Measured(8e-05, DURATION)}
    assert finding().params == {}
