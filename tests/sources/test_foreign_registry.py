"""The registry of other tools' formats: what --channel means where a capture has one stream of bytes."""

from pathlib import Path

from rs30x_sniff.cli import main
from rs30x_sniff.sources import foreign

CAPTURES = Path(__file__).resolve().parents[2] / "captures"


def test_only_multi_signal_formats_take_a_channel():
    assert {name for name, f in foreign.formats().items() if f.channels} == {"sigrok", "sigrok-uart"}


def test_a_channel_given_for_a_single_stream_capture_is_said_to_be_ignored(capsys):
    assert main(["decode", str(CAPTURES / "manual-examples.hex"), "--channel", "D0"]) == 0
    assert "--channel is ignored: a hex capture holds one stream of bytes" in capsys.readouterr().err
    assert main(["decode", str(CAPTURES / "foreign" / "spy.log"), "--channel", "1"]) == 0
    assert "--channel is ignored: a spy capture" in capsys.readouterr().err


def test_a_channel_for_a_sigrok_session_is_used_without_a_warning(capsys):
    assert main(["decode", str(CAPTURES / "foreign" / "sigrok-hexapod.sr"), "--channel", "D0"]) == 0
    assert "ignored" not in capsys.readouterr().err
