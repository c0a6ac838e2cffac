"""The CI gate never passes or fails for the wrong reason (issue 32 §4): a configuration that clashes is one
line and exit 2, every command checks [regress], diff --fail-on-regress with nothing checkable fails, and
options that contradict each other are refused, never silently resolved."""

from __future__ import annotations

from pathlib import Path

import pytest

from rs30x_sniff.cli import main
from rs30x_sniff.lint.registry import RULES

CAPTURES = Path(__file__).resolve().parents[2] / "captures"
TIMED = str(CAPTURES / "session-mixed.thex")
UNTIMED = str(CAPTURES / "manual-examples.hex")

RULE = '[[rule]]\ncode = "U001"\nname = "servo-too-hot"\nwhen = "kind:return present_temperature>60"\n'


def expect(code: str = "U001", name: str = "legs-polled") -> str:
    return f'\n[[expect]]\ncode = "{code}"\nname = "{name}"\ncheck = "poll_hz >= 5"\nfor = "each"\n'


@pytest.fixture(autouse=True)
def _clean(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no configuration above
    yield
    assert not RULES.user()  # a command's user rules stay in its own rule set


def run(capsys, *argv) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def one_line(err: str, *words: str) -> None:
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, err


# ---- configuration errors ----------------------------------------------------------------------------
@pytest.mark.parametrize("body, words", [
    (RULE + expect("U001", "legs-polled"), ["[[expect]] #1 (U001): code = 'U001'", "[[rule]] U001"]),
    (RULE + expect("U002", "servo-too-hot"), ["[[expect]] #1 (U002): name = 'servo-too-hot'", "[[rule]] U001"]),
    (expect("U002", "missing-return"), ["name = 'missing-return'", "built-in rule B002"]),
])
@pytest.mark.parametrize("command", ["lint", "info", "decode", "rules"])
def test_a_rule_and_a_check_under_one_code_or_name_is_one_line_and_exit_2(capsys, tmp_path, body, words, command):
    conf = tmp_path / "rs30x-sniff.toml"
    conf.write_text(body)
    argv = [command] if command == "rules" else [command, TIMED]
    code, out, err = run(capsys, *argv, "--config", conf)
    assert code == 2 and out == ""
    one_line(err, str(conf), *words)


@pytest.mark.parametrize("command", ["lint", "info", "decode", "convert", "diff"])
def test_every_command_that_reads_the_configuration_checks_regress(capsys, tmp_path, command):
    conf = tmp_path / "rs30x-sniff.toml"
    conf.write_text('[regress]\nlatency_p96 = "+20%"\n')
    argv = {"convert": ["convert", TIMED, "-o", tmp_path / "x.mcap"], "diff": ["diff", TIMED, TIMED]}.get(
        command, [command, TIMED])
    code, out, err = run(capsys, *argv, "--config", conf)
    assert code == 2 and out == ""
    one_line(err, str(conf), "regress.latency_p96: unknown figure; did you mean latency_p95?")
    assert not (tmp_path / "x.mcap").exists()


# ---- diff --fail-on-regress with nothing checkable -----------------------------------------------------
def test_fail_on_regress_with_nothing_checkable_fails(capsys, tmp_path):
    conf = tmp_path / "rs30x-sniff.toml"
    conf.write_text('[regress]\nlatency_p95 = "+20%"\nbus_load = "+10%"\n')
    # Untimed captures give no latency and no load: every threshold is "not checked".
    code, out, err = run(capsys, "diff", UNTIMED, UNTIMED, "--config", conf, "--fail-on-regress")
    assert code == 1
    assert "none checkable" in out and "none crossed" not in out
    lines = [x for x in err.splitlines() if "not checkable" in x]
    assert len(lines) == 2 and all(x.startswith("rs30x-sniff: error: not checkable: ") for x in lines), err
    code, _, err = run(capsys, "diff", UNTIMED, UNTIMED, "--config", conf, "--fail-on-regress", "--allow-unchecked")
    assert code == 0 and "warning: not checkable: latency_p95" in err
    # Without --fail-on-regress the report is only a report.
    assert run(capsys, "diff", UNTIMED, UNTIMED, "--config", conf)[0] == 0


def test_fail_on_regress_with_no_threshold_fails(capsys):
    code, _, err = run(capsys, "diff", TIMED, TIMED, "--isolated", "--fail-on-regress")
    assert code == 1 and "error: --fail-on-regress: not checkable: no thresholds" in err
    code, _, err = run(capsys, "diff", TIMED, TIMED, "--isolated", "--fail-on-regress", "--allow-unchecked")
    assert code == 0 and "warning: --fail-on-regress: not checkable" in err


def test_a_checked_threshold_still_passes_and_the_annotations_say_what_was_not(capsys, tmp_path):
    code, out, err = run(capsys, "diff", TIMED, TIMED, "--isolated", "--fail-on-regress",
                         "--threshold", "latency_p95=+20%", "--format", "github")
    assert code == 0 and "none crossed" in out and "not checkable" not in err
    code, out, _ = run(capsys, "diff", UNTIMED, UNTIMED, "--isolated", "--fail-on-regress",
                       "--threshold", "latency_p95=+20%", "--format", "github")
    assert code == 1 and "title=rs30x-sniff diff%3A latency_p95 not checkable::latency_p95 (bus)" in out
    assert f"::error file={UNTIMED},title=" in out


def test_allow_unchecked_needs_fail_on_regress(capsys):
    code, out, err = run(capsys, "diff", TIMED, TIMED, "--isolated", "--allow-unchecked")
    assert code == 2 and out == ""
    one_line(err, "--allow-unchecked: only with --fail-on-regress")


# ---- options that contradict each other --------------------------------------------------------------
@pytest.mark.parametrize("options, words", [
    (["--model", "3=RS303MR", "--model", "3=RS304MD"], "--model 3=RS303MR and --model 3=RS304MD: two models for ID 3"),
    (["--model", "3=RS303MR", "--model", "0x3=RS304MD"], "ID 3 is given two models (RS303MR and RS304MD)"),
    (["--model", "RS303MR", "--model", "RS304MD"], "two models for every ID"),
    (["--select", "B002", "--ignore", "B002"], "B002 is both selected and ignored"),
    (["--select", "missing-return", "--ignore", "B"], "B002 is both selected and ignored"),
    (["--time-unit", "ms"], "is an untimed hex capture: --time-unit is for timestamped hex captures"),
])
@pytest.mark.parametrize("command", ["lint", "info", "decode"])
def test_conflicting_options_are_refused(capsys, options, words, command):
    capture = UNTIMED if "--time-unit" in options else TIMED
    code, out, err = run(capsys, command, capture, "--isolated", *options)
    assert code == 2 and out == ""
    one_line(err, words)


@pytest.mark.parametrize("options, words", [
    (["--severity", "B002=info", "--severity", "B002=error"], "--severity B002=info and --severity B002=error"),
    (["--severity", "B002=info", "--severity", "missing-return=error"], "two levels for B002"),
])
def test_two_severities_for_one_rule_are_refused(capsys, options, words):
    code, out, err = run(capsys, "lint", TIMED, "--isolated", *options)
    assert code == 2 and out == ""
    one_line(err, words)


@pytest.mark.parametrize("options", [
    ["--model", "3=RS303MR", "--model", "3=rs303mr"],            # the same, said twice
    ["--severity", "B002=info", "--severity", "B002=info"],
    ["--severity", "B=info", "--severity", "B002=error"],         # a rule named on its own refines its family
    ["--select", "B", "--ignore", "B002"],                        # every B rule but one
    ["--time-unit", "s"],                                         # a timestamped capture reads it
])
def test_options_that_agree_or_refine_are_taken(capsys, options):
    code, _, err = run(capsys, "lint", TIMED, "--isolated", "--fail-on", "never", *options)
    assert code == 0, err


def test_a_config_files_select_and_ignore_that_contradict_are_one_line(capsys, tmp_path):
    conf = tmp_path / "rs30x-sniff.toml"
    conf.write_text('select = ["B002"]\nignore = ["B002"]\n')
    code, _, err = run(capsys, "lint", TIMED, "--config", conf)
    assert code == 2
    one_line(err, str(conf), "select names B002 and ignore drops it")
    # Across layers the command line wins: the file's select, the command line's ignore.
    conf.write_text('select = ["B"]\n')
    assert run(capsys, "lint", TIMED, "--config", conf, "--ignore", "B002", "--fail-on", "never")[0] == 0


def test_time_unit_on_a_binary_or_mcap_capture_is_refused(capsys, tmp_path):
    mcap, binary = tmp_path / "x.mcap", tmp_path / "x.bin"
    assert run(capsys, "convert", TIMED, "--isolated", "-o", mcap)[0] == 0
    assert run(capsys, "simulate", "--scenario", "overheat", "--duration", "0.5", "-o", binary)[0] == 0
    for path, what in ((binary, "a binary capture"), (mcap, "an MCAP capture")):
        code, out, err = run(capsys, "info", path, "--isolated", "--time-unit", "ms")
        assert code == 2 and out == ""
        one_line(err, f"{path} is {what}")


def test_a_rate_past_table_4_7_needs_baud_any_on_files_and_ports(capsys, tmp_path):
    """921600 is no servo's rate (table 4.7 stops at 230400, code 0x0A of some models is 460800): refused as the docs
    say, taken with --baud-any; 460800 is taken as it is."""
    code, _, err = run(capsys, "info", TIMED, "--isolated", "--baud", "921600")
    assert code == 2
    one_line(err, "--baud 921600: not a rate the servos run at", "--baud-any")
    code, _, err = run(capsys, "record", "/dev/ttyUSB-not-there", "--isolated", "--baud", "921600", "-o",
                       tmp_path / "x.mcap", "--duration", "1")
    assert code == 2 and "--baud 921600: not a rate the servos run at" in err
    assert run(capsys, "info", TIMED, "--isolated", "--baud", "921600", "--baud-any")[0] == 0
    assert run(capsys, "info", TIMED, "--isolated", "--baud", "460800")[0] == 0
    text = (Path(__file__).resolve().parents[2] / "docs" / "live-capture.md").read_text()
    assert "or 460800." not in text and "`--baud-any`" in text


# ---- convert writes what the output's name says ---------------------------------------------------------
@pytest.mark.parametrize("name, options, words", [
    ("x.bin", [], "-o {out}: convert writes mcap or pcapng, not .bin: name the output .mcap or .pcapng"),
    ("x.thex", [], "not .thex"),
    ("x.mcap", ["--to", "pcapng"], "-o {out} and --format pcapng: the name says mcap"),
    ("x.pcapng", ["--to", "mcap"], "the name says pcapng"),
])
def test_convert_refuses_a_name_of_a_format_it_does_not_write(capsys, tmp_path, name, options, words):
    out = tmp_path / name
    code, stdout, err = run(capsys, "convert", TIMED, "--isolated", "-o", out, *options)
    assert code == 2 and stdout == ""
    one_line(err, words.format(out=out))
    assert list(tmp_path.iterdir()) == []  # nothing written, not even a temporary file


@pytest.mark.parametrize("name, options, magic", [
    ("x.mcap", [], b"\x89MCAP"), ("x.PCAPNG", [], b"\x0a\x0d\x0d\x0a"), ("x", ["--to", "pcapng"], b"\x0a\x0d\x0d\x0a"),
    ("x", [], b"\x89MCAP"), ("x.mcap", ["--to", "mcap"], b"\x89MCAP"),
])
def test_convert_writes_the_format_its_name_or_to_says(capsys, tmp_path, name, options, magic):
    out = tmp_path / name
    assert run(capsys, "convert", TIMED, "--isolated", "-o", out, *options)[0] == 0
    assert out.read_bytes().startswith(magic)
