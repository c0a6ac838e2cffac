"""F009 sender-mismatch: a packet the capture says the other side sent, said once with a count; free without senders."""

from __future__ import annotations

import io

import pytest

from rs30x_sniff.protocol.chunks import HOST, SERVO, Marked
from rs30x_sniff.sources import foreign
from rs30x_sniff.lint import RULES, LintConfig, Linter
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.sinks.pipeline import drive
from rs30x_sniff.protocol.wire import ACK, encode_read, encode_return, encode_short

from ..sources import serial_log_writers as w

READ = encode_read(1, 0x2A, 2)
RET = encode_return(1, 0x2A, b"\x84\x03")
ACK_ME = encode_short(1, 0x01, 0x1E, b"\x84\x03")  # return mode 0001: answer with an ACK


def lint(chunks, config: LintConfig | None = None) -> tuple[Linter, Decoder]:
    linter = Linter(config)
    dec = drive(chunks, Decoder(DecodeOptions(), linter))
    return linter, dec


def f009(linter: Linter) -> list:
    return [f for f in linter.findings if f.code == "F009"]


def test_declared():
    r = RULES["F009"]
    assert (r.name, r.severity) == ("sender-mismatch", "warning")
    assert RULES.get("sender-mismatch") is r and r.state is not None


def test_agreeing_senders_say_nothing():
    linter, _ = lint([Marked(READ, 0.0, sender=HOST), Marked(RET, 0.001, sender=SERVO)] * 3)
    assert not f009(linter) and linter.state_of("F009").checked == 6


def test_a_whole_capture_the_wrong_way_round_is_one_finding():
    linter, _ = lint([Marked(READ, 0.0, sender=SERVO), Marked(RET, 0.001, sender=HOST)] * 5)
    (f,) = f009(linter)
    assert f.offset == 0 and f.t == 0.0 and f.id == 1 and f.severity == "warning"
    assert f.message.startswith("every packet checked disagrees with the capture about who sent it;")
    assert "a request (FA AF) the capture says the servo sent" in f.message and "wrong way round" in f.message


def test_one_packet_from_the_wrong_side_is_counted_and_placed():
    chunks = [Marked(READ, 0.0, sender=HOST), Marked(RET, 0.001, sender=SERVO),
              Marked(READ, 0.01, sender=HOST), Marked(RET, 0.011, sender=HOST),  # the host "sent" a return
              Marked(READ, 0.02, sender=HOST), Marked(RET, 0.021, sender=SERVO)]
    linter, _ = lint(chunks)
    (f,) = f009(linter)
    assert f.offset == 2 * len(READ) + len(RET) and f.t == 0.011
    assert f.message.startswith("1 of 6 packets checked") and "a return (FD DF) the capture says the host sent" in f.message
    assert "wrong way round" not in f.message


def test_an_ack_from_the_host_is_a_mismatch():
    linter, _ = lint([Marked(ACK_ME, 0.0, sender=HOST), Marked(bytes((ACK,)), 0.001, sender=HOST)])
    (f,) = f009(linter)
    assert "an ACK (07) the capture says the host sent" in f.message and f.message.startswith("1 of 2")


def test_bytes_the_capture_does_not_attribute_are_not_checked():
    chunks = [Marked(READ, 0.0, sender=HOST), (RET, 0.001), Marked(READ, 0.01, sender=SERVO), (RET, 0.011)]
    linter, _ = lint(chunks)
    assert linter.state_of("F009").checked == 2 and f009(linter)[0].message.startswith("1 of 2")


def test_without_senders_the_rule_leaves_the_dispatch():
    linter, dec = lint([(READ + RET, None)] * 200)
    st = linter.state_of("F009")
    assert not dec.senders and st.checked == 0 and not f009(linter)
    # Its checks are gone from every packet kind's list after the first packet: no call per packet.
    assert not any(getattr(fn, "__self__", None) is st
                   for kind in ("short", "long", "return", "ack", "nack") for fn in linter._on[kind])


def test_a_linter_without_a_decoder_is_fine():
    from rs30x_sniff.sinks.pipeline import decode_records

    linter = Linter()
    for rec in decode_records([(READ + RET, None)]):
        linter.feed(rec)
    linter.close()
    assert not f009(linter)


def test_ignored():
    linter, _ = lint([Marked(READ, 0.0, sender=SERVO)], LintConfig(ignore=["F009"]))
    assert not f009(linter)


@pytest.mark.parametrize("fmt,write", [
    ("spy", lambda sent: w.spy_log(sent, 115200).encode()),
    ("interceptty", lambda sent: w.interceptty_log(sent, 115200)),
    ("slsnif", lambda sent: w.slsnif_log(sent, 115200)),
])
def test_a_log_attached_on_the_servos_side_gives_f009(fmt, write):
    """Formats whose words say host and servo: a log made from the servos' side is all mismatches."""
    sent = w.simulated("hexapod", baud=115200, seconds=0.05)
    for swapped, expect in ((False, 0), (True, 1)):
        text = write(w.swapped(sent) if swapped else sent)
        chunks = foreign.get(fmt).read(io.BytesIO(text), foreign.ReadContext(fmt, {"baud": 115200}))
        found = f009(lint(chunks)[0])
        assert len(found) == expect
        if expect:
            assert found[0].offset == 0 and found[0].message.startswith("every packet checked")


def test_the_documented_example_fires_read_as_its_format():
    text = RULES["F009"].example.encode()
    fmt = foreign.sniff(text)
    assert fmt is not None and fmt.name == "spy"
    (f,) = f009(lint(fmt.read(io.BytesIO(text), foreign.ReadContext("example")))[0])
    assert f.offset == 0
