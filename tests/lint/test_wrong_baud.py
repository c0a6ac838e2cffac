"""F007 wrong-baud-rate: said for a bus read at the wrong rate, never for a healthy capture or scenario."""

from __future__ import annotations

import pytest

from rs30x_sniff.lint import LintConfig, Linter
from rs30x_sniff.decode.decoder import Decoder, DecodeOptions
from rs30x_sniff.sim import SCENARIOS, run
from rs30x_sniff.sim.wire import retime

from .helpers import CAPTURES, lint_chunks, parse


def _lint(chunks, baud):
    linter = Linter(LintConfig(baud=baud))
    dec = Decoder(DecodeOptions(baud=baud), linter)
    during = []
    for d, t in chunks:
        during += [f for f in dec.feed(d, t).findings if f.code == "F007"]
    dec.close()
    return [f for f in linter.findings if f.code == "F007"], during


@pytest.mark.parametrize("baud", [9600, 28800, 115200, 230400])
@pytest.mark.parametrize("name", list(SCENARIOS))
def test_no_scenario_at_its_rate_looks_like_a_wrong_rate(name, baud):
    found, _ = _lint(run(name, baud=baud, duration=2.0), baud)
    assert not found, found[0].message


@pytest.mark.parametrize("path", sorted(CAPTURES.glob("*.*hex")) + sorted((CAPTURES / "lint").glob("*.*hex")),
                         ids=lambda p: p.name)
def test_no_healthy_capture_looks_like_a_wrong_rate(path):
    if path.name.startswith("F007-"):
        pytest.skip("the rule's own capture")
    chunks, _ = parse(path.read_text())
    assert not [f for f in lint_chunks(chunks).findings if f.code == "F007"]


def test_115200_read_at_57600_is_a_wrong_rate_untimed():
    chunks = list(retime(run("hexapod", baud=115200, duration=2.5), 115200, 57600))
    found, _ = _lint([(b"".join(d for d, _ in chunks), None)], 57600)
    assert len(found) == 1  # once per stretch, not per byte
    msg = found[0].message
    assert msg.startswith("no valid frame in ") and "--baud auto" in msg and "table 4.7" in msg
    assert found[0].severity == "error"


def test_115200_read_at_57600_is_said_while_feeding_timed_chunks():
    chunks = list(retime(run("hexapod", baud=115200, duration=2.5), 115200, 57600))
    found, during = _lint(chunks, 57600)
    assert during and found == during


def test_a_valid_frame_ends_the_stretch_and_a_new_one_is_said_again():
    bad = b"".join(d for d, _ in retime(run("hexapod", baud=115200, duration=1.6), 115200, 57600))
    from rs30x_sniff.protocol.wire import encode_short
    good = encode_short(1, 0, 0x1E, b"\x84\x03")
    found, _ = _lint([(bad + good + bad, None)], 57600)
    assert len(found) == 2


def test_a_busy_bus_at_the_wrong_rate_is_flagged_within_a_second_live():
    """A live tap at 57600 on a 115200 bus: no frames and no idle gaps end the garbage, yet the finding
    comes during the feed (the decoder hands long garbage runs out in pieces), within a second."""
    chunks = list(retime(run("hexapod", baud=115200, duration=3.0), 115200, 57600))
    t0 = chunks[0][1]
    linter = Linter(LintConfig(baud=57600))
    dec = Decoder(DecodeOptions(baud=57600), linter)
    first = None
    for d, t in chunks:
        for piece in range(0, len(d), 16):  # small reads, as a serial port returns them
            step = dec.feed(d[piece:piece + 16], t + piece * 10 / 57600)
            if first is None and any(f.code == "F007" for f in step.findings):
                first = t - t0
    assert first is not None and first < 1.5, first  # the issue: "within a second or two"
    # And the garbage is still said once per run by F002, not once per piece.
    dec.close()
    assert sum(1 for f in linter.findings if f.code == "F002") <= sum(1 for f in linter.findings if f.code == "F007") + 1
