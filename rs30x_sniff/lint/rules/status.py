"""Servo status rules (S): the error bits of return packets (table 4.4), said when they turn on."""

from __future__ import annotations

from ...protocol.wire import (
    RETURN_FLASH_WRITE_ERROR, RETURN_RECEIVED_ERROR, RETURN_TEMPERATURE_ALARM, RETURN_TEMPERATURE_LIMIT,
    encode_return)
from ...protocol.memmap import behaviour_of
from ..params import said
from ..registry import example, models_where, rule

_NOTE = """
A servo keeps a bit set in every return while the condition lasts, so the rule speaks once when the bit
turns on for a servo, and again only after a return with it clear.
"""


def _turned_on(lint, ev, bit: int) -> bool:
    if not ev.flags & bit:
        return False
    sh = lint.servos.get(ev.id)
    return sh is None or not sh.flags & bit




def _ret(flags: int) -> str:
    return example(encode_return(1, 0x2A, bytes.fromhex("8403"), flags=flags))


@rule("S001", "temperature-limit", "error", "A servo reports its temperature limit: torque cut.", f"""
## What it does
Flags a return with status bit 7 set: the servo's temperature passed its temperature limit (table 4.6,
No. 14) and it cut its torque (brake mode).
{_NOTE}
## Why it matters
The joint goes limp or stiff under load, mid-motion. The motor is then at 120-140 degC. What brings the
servo back is its model's: a reboot ({models_where(lambda m: not m.behaviour.recovers_by_torque_enable)};
torque on before that is Q009), or a torque_enable write
({models_where(lambda m: m.behaviour.recovers_by_torque_enable)}); the finding says which.

## Example
{_ret(RETURN_TEMPERATURE_LIMIT)}
""", kinds=("return",), when="flagged", column="silent")
def temperature_limit(lint, rec, ev):
    if _turned_on(lint, ev, RETURN_TEMPERATURE_LIMIT):
        lint.emit("S001", rec, said("ID {id} passed its temperature limit and cut torque ({way})",
                                    {"id": ev.id, "way": behaviour_of(rec.model).recovery}))


@rule("S002", "temperature-alarm", "warning", "A servo reports a temperature alarm.", f"""
## What it does
Flags a return with status bit 5 set: the servo is within 10 degC of its temperature limit.
{_NOTE}
## Why it matters
It is the last warning before the servo cuts its torque (S001). Reduce the load or duty cycle now.

## Example
{_ret(RETURN_TEMPERATURE_ALARM)}
""", kinds=("return",), when="flagged", column="silent")
def temperature_alarm(lint, rec, ev):
    if _turned_on(lint, ev, RETURN_TEMPERATURE_ALARM):
        lint.emit("S002", rec, said("ID {id} is within 10 degC of its temperature limit", {"id": ev.id}))


@rule("S003", "flash-write-error", "error", "A servo reports that writing its flash ROM failed.", f"""
## What it does
Flags a return with status bit 3 set: the last Write Flash ROM command failed. Models whose manual
reserves bit 3 have no such report
({models_where(lambda m: RETURN_FLASH_WRITE_ERROR not in m.behaviour.return_flags)}):
the rule is silent for them, and P013 names the reserved bit.
{_NOTE}
## Why it matters
Settings the host believes saved (ID, baud rate, limits) are not; after the next power cycle the servo
comes back with old values, maybe on another ID or baud rate.

## Example
{_ret(RETURN_FLASH_WRITE_ERROR)}
""", kinds=("return",), when="flagged", column="silent")
def flash_write_error(lint, rec, ev):
    if (_turned_on(lint, ev, RETURN_FLASH_WRITE_ERROR)
            and RETURN_FLASH_WRITE_ERROR in behaviour_of(rec.model).return_flags):
        lint.emit("S003", rec, said("ID {id} failed to write its flash ROM", {"id": ev.id}))


@rule("S004", "received-packet-error", "warning", "A servo reports it received a bad packet.", f"""
## What it does
Flags a return with status bit 1 set: the servo received a packet it could not accept (bad Sum, bad
length) since its last return.
{_NOTE}
## Why it matters
Some command to this servo was lost, maybe one the sniffer saw intact: the servo's view of the line
differs from the tap's (noise near the servo, a marginal baud rate).

## Example
{_ret(RETURN_RECEIVED_ERROR)}
""", kinds=("return",), when="flagged", column="silent")
def received_packet_error(lint, rec, ev):
    if _turned_on(lint, ev, RETURN_RECEIVED_ERROR):
        lint.emit("S004", rec, said("ID {id} received a packet it could not accept", {"id": ev.id}))
