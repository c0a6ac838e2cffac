"""protocol.baud.contradiction: when a capture's timestamps contradict the rate it is decoded at, and what they show."""

from __future__ import annotations

from rs30x_sniff.protocol.baud import contradiction, estimate_baud, rate_fit
from rs30x_sniff.protocol.wire import byte_time


def _back_to_back(baud: int, n: int = 200, size: int = 9) -> list[tuple[bytes, float]]:
    """Frames of ``size`` bytes sent one after another at ``baud`` (each stamped at its first byte)."""
    return [(bytes(size), k * size * byte_time(baud)) for k in range(n)]


def test_the_rate_they_were_sent_at_is_not_contradicted():
    chunks = _back_to_back(115200)
    assert contradiction(estimate_baud(chunks), rate_fit(chunks), 115200) is None


def test_a_slower_rate_is_ruled_out_by_overlaps_and_the_sent_rate_is_shown():
    chunks = _back_to_back(115200)
    shown, evidence = contradiction(estimate_baud(chunks), rate_fit(chunks), 38400)
    assert shown == 115200 and "would start before the previous one ended" in evidence and "38400" in evidence


def test_a_faster_rate_is_contradicted_by_the_back_to_back_spacing():
    chunks = _back_to_back(57600)
    estimate = estimate_baud(chunks)
    shown, evidence = contradiction(estimate, rate_fit(chunks), 230400)
    assert shown == 57600 and evidence == estimate.evidence


def test_without_timestamps_nothing_is_said():
    chunks = [(bytes(9), None)] * 50
    assert contradiction(estimate_baud(chunks), rate_fit(chunks), 115200) is None
    assert contradiction(None, None, 115200) is None
