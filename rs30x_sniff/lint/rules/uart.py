"""UART rules (F): bytes the capturing tool flagged with a framing or parity error."""

from __future__ import annotations

from ...protocol.chunks import FRAMING_ERROR, UART_ERRORS
from ...protocol.wire import byte_time, encode_short
from ..params import Measured, said
from ..registry import rule

_GOAL = encode_short(1, 0, 0x1E, b"\x84\x03")  # goal_position 90.0 deg on ID 1


def _saleae_table(data: bytes, flagged: dict[int, str], baud: int = 115200) -> str:
    """A Saleae Logic 2 Async Serial table of ``data`` sent back to back (the example capture).

    Hex text cannot say that a byte was received badly, so this rule's example is in the one format
    that can that a reader of this repository most likely has.
    """
    bt = byte_time(baud)
    duration = round(9.5 / baud, 9)  # the analyzer's frame: start bit to the middle of the stop bit
    lines = ["name,type,start_time,duration,data,error"]
    for k, b in enumerate(data):
        error = flagged.get(k, "").removesuffix("-error")  # framing-error -> framing, as Saleae writes it
        lines.append(f'"Async Serial","data",{round(k * bt, 9)!r},{duration!r},0x{b:02X},{error}')
    return "```\n" + "\n".join(lines) + "\n```"


@rule("F008", "uart-error", "error", "A byte the capturing tool's UART flagged with a framing or parity error.", f"""
## What it does
Flags bytes that the tool which captured them marked as received badly: a framing error (the stop bit
was sampled low) or a parity error, as logic analyzer exports record them (the `error` column of a
Saleae Logic 2 table, the error columns of a Logic 1.x export). Such a byte's value cannot be trusted,
so it never becomes part of a frame: the frame it falls in is cut short there (F003) and the byte is
garbage of its own. Said once per run of adjacent flagged bytes.

## Why it matters
The servos' own UARTs see the same bad byte and drop the packet it belongs to, so a command is lost
or a return never reaches the host. A framing error means the line was low where it must be high:
two talkers at once, a break, electrical noise, a slow edge sampled near its threshold, or an analyzer
set to another baud rate than the bus. A parity error cannot happen on this bus (8N1, no parity bit,
table 4.7): the analyzer is set to expect a parity bit.

## Example
A Saleae Logic 2 table of a goal_position write whose eighth byte the analyzer flagged:

{_saleae_table(_GOAL, {7: FRAMING_ERROR})}
""", kinds=("garbage",), column="silent")
def uart_error(lint, rec, ev):
    reason = ev.reason
    if reason not in UART_ERRORS:
        return
    prev = lint.prev
    if prev is not None:
        pe = prev.event
        if pe.kind == "garbage" and pe.end_offset == ev.offset and pe.reason in UART_ERRORS:
            return  # the same run of flagged bytes: said once, at its first byte
    if reason == FRAMING_ERROR:
        why = "a framing error (its stop bit was low)"
    else:
        why = "a parity error (the bus has no parity bit: is the analyzer set to 8N1?)"
    # The byte's value is what the tool read (measured); the kind of error names the finding.
    lint.emit("F008", rec, said("byte 0x{byte:02X} flagged by the capturing tool with {why}: its value cannot be "
                                "trusted, and a frame it falls in is lost", {"byte": Measured(ev.raw[0]), "why": why}),
              sid=None)
