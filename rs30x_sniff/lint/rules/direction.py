"""Direction rules (F): packets whose sender, as the capture records it, is not who sends such packets."""

from __future__ import annotations

from ...protocol.chunks import HOST, SERVO
from ...protocol.events import OFFSET, T_START
from ..params import Measured, said
from ..registry import rule

_EXPECTED = {"short": HOST, "long": HOST, "return": SERVO, "ack": SERVO, "nack": SERVO}
_WHAT = {"short": "a request (FA AF)", "long": "a long packet (FA AF)", "return": "a return (FD DF)",
         "ack": "an ACK (07)", "nack": "a NACK (08)"}


class _Tally:
    """F009's memory: packets checked against the capture's senders, and the first that disagreed."""

    __slots__ = ("senders", "checked", "wrong", "first")

    def __init__(self) -> None:
        self.senders = False  # the decoder's SenderMap, once the first packet shows whether it has one
        self.checked = 0
        self.wrong = 0
        self.first: tuple | None = None  # (offset, t, id, kind, sender) of the first disagreement


def _sender_mismatch_columns(st, view) -> bool:
    """F009 on a Block: silent unless the capture says who sent what (then each packet is checked)."""
    senders = decide(st, view.lint) if st.senders is False else st.senders
    return senders is None


@rule("F009", "sender-mismatch", "warning",
      "A packet the capture says the other side sent: a request from a servo, or a reply from the host.", """
## What it does
Compares the decoder's reading of each packet with who the capture says sent its first byte, where
the capture says so (a serial logger's TX/RX or `>`/`<`, a logic analyzer's channel): requests and
long packets (FA AF) come from the host, returns (FD DF), ACKs (07) and NACKs (08) from the servos.
Said once per capture, at the first packet that disagrees, with how many of the packets checked
did; when every one of them does, the capture's directions are the wrong way round. Captures that do
not say who sent what (raw bytes, hex, our own timestamped hex) are not checked.

## Why it matters
A packet from the wrong side means the capture is not what it seems: the logger sat on the servo's
port rather than the host's, an analyzer's RX and TX channels were swapped, a servo emulator was
logged as the host, or an echo the adapter read back was logged as the servo's. Latencies, pairing
and every per-direction figure read from such a capture are wrong until the logger is set up the
other way round.

## Example
A pyserial `spy://` log (hex text cannot say who sent a byte) whose TX and RX are swapped: the read
of present_position of ID 1 is logged as received (RX), the servo's return of 90.0 deg as sent (TX).

```
000000.001 RX   0000  FA AF 01 0F 2A 02 00 26                           ....*..&
000000.002 TX   0000  FD DF 01 00 2A 02 01 84  03 AF                    ....*.....
```
""", kinds=("request", "reply", "close"), state=_Tally, column=_sender_mismatch_columns)
def sender_mismatch(st, lint, rec, ev):
    senders = st.senders
    if senders is False:
        senders = decide(st, lint)
    if senders is None:
        return
    offset = ev[OFFSET]
    sent = senders.at(offset)
    if sent is None:
        return
    st.checked += 1
    kind = ev.kind
    if sent != _EXPECTED[kind]:
        st.wrong += 1
        if st.first is None:
            st.first = (offset, ev[T_START], rec.id, kind, sent)


def decide(st, lint):
    """Whether the capture says who sent what, decided at the first packet (by then the first chunks, and
    their senders, have been fed): the SenderMap, or None."""
    senders = st.senders = lint.senders or None  # the Decoder's SenderMap: None, or empty, when none was said
    if senders is None:
        _stop_calling(st, lint)
    return senders


def _stop_calling(st, lint) -> None:
    # A capture that does not say who sent what (most do not) must not pay for this rule: its checks
    # leave the linter's per-kind dispatch, which is built once per run.
    lint.stop_calling(st, _EXPECTED)


@sender_mismatch.on("close")
def _sender_mismatch_report(st, lint):
    if st.first is None:
        return
    offset, t, sid, kind, sent = st.first
    n, of = st.wrong, st.checked
    # The counts are this capture's (measured); whether every packet disagreed is what the finding says.
    how = _F009_ALL if n == of else _F009_SOME
    hint = (": the capture's directions are the wrong way round (was the logger on the servo's side, or "
            "RX and TX swapped?)" if n == of and n > 1 else "")
    params = {"wrong": Measured(n), "checked": Measured(of), "what": _WHAT[kind], "sent": sent, "hint": hint}
    lint.emit_at("F009", offset, t, said(how + _F009_FIRST, params), sid)


_F009_ALL = "every packet checked disagrees"
_F009_SOME = "{wrong} of {checked} packets checked disagree"
_F009_FIRST = " with the capture about who sent it; first here, {what} the capture says the {sent} sent{hint}"
