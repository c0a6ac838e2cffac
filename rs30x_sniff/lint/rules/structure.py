"""Packet structure rules (P): header fields the packet formats of chapter 4 do not allow."""

from __future__ import annotations

from ...protocol.memmap import behaviour_of
from ...protocol.wire import (
    BROADCAST_ID, COMMAND_ADDRESS, COMMAND_BITS, FLAG_INITIALIZE, FLAG_REBOOT, FLAG_RESERVED, FLAG_WRITE_FLASH,
    MAX_READ_ADDRESS, RETURN_FLASH_WRITE_ERROR, RETURN_MODES, RETURN_SPECIFIED, encode_long,
    encode_read, encode_return, encode_short)
from ..params import Measured, said
from ..registry import example, frame, models_where, rule

_G90, _P10, _P50 = bytes.fromhex("8403"), bytes.fromhex("6400"), bytes.fromhex("F401")  # 90.0 deg, 10.0 deg, 50.0 deg
_RET = bytes.fromhex("FDDF")
_FLASH_REBOOT = FLAG_WRITE_FLASH | FLAG_REBOOT  # table 4.2: the manual wants these in separate packets

# Messages are made by said() (lint.params): the header fields a rule names (flag, Length, Count, Address,
# IDs, return mode) are what the host sent, the same in every recording of the same host, so they stay in
# the finding's key; only P013's whole return-flags byte, whose status bits follow the servo's state, is
# Measured.


def _cmds(ev) -> str:
    return "+".join(ev.commands)


@rule("P001", "reserved-flag-bit", "error", "A short packet sets flag bit 7, which is reserved.", f"""
## What it does
Flags a short packet whose flag has bit 7 set. Table 4.2 reserves that bit and says to keep it 0.

## Why it matters
Firmware is free to give a reserved bit a meaning later, or to reject the packet; either way the
servo may not do what the host meant. A set bit 7 is often a sign the host built the flag from the
wrong variable.

## Example
{example(encode_short(1, 0x80, 0x1E, _G90))}
""", kinds=("short",), column="header")
def reserved_flag_bit(lint, rec, ev):
    if ev.flag & FLAG_RESERVED:
        lint.emit("P001", rec, said("flag 0x{flag:02X} sets reserved bit 7", {"flag": ev.flag}))


@rule("P002", "long-packet-flags", "error", "A long packet whose flag is not 0.", f"""
## What it does
Flags a long packet (ID 0) whose flag byte is not 0: the long packet format says to set it to 0 always.

## Why it matters
A long packet cannot ask for returns (all servos would answer at once) nor flash or reboot; flag bits
there are at best ignored and at worst make some servos act on them.

## Example
{example(frame(0, 0x40, 0x1E, 3, 2, 1, 0x64, 0, 2, 0x64, 0), note="a long packet with the flash bit set:")}
""", kinds=("long",), column="header")
def long_packet_flags(lint, rec, ev):
    if ev.flag:
        lint.emit("P002", rec, said("long packet with flag 0x{flag:02X} (must be 0)", {"flag": ev.flag}))


@rule("P003", "long-packet-length", "error", "A long packet with Length below 2 or Count 0.", f"""
## What it does
Flags a long packet whose Length is below 2 (each record is a VID plus at least one data byte) or whose
Count is 0 (no servo at all). A Length that does not match the frame's size cannot reach the linter as
a packet: the decoder sizes frames by Length x Count, so such bytes come out as F001 or F003.

## Why it matters
Such a packet writes nothing. The host meant to move servos and did not, usually because it computed
Length without the VID byte or sent an empty batch.

## Example
{example(frame(0, 0, 0x1E, 1, 0), note="Length 1, Count 0:")}
""", kinds=("long",), column="header")
def long_packet_length(lint, rec, ev):
    if ev.length < 2 or ev.count == 0:
        lint.emit("P003", rec, said("long packet with Length {length} and Count {count} writes nothing",
                                    {"length": ev.length, "count": ev.count}))


@rule("P004", "duplicate-vid", "warning", "A long packet addresses the same servo twice.", f"""
## What it does
Flags a long packet in which the same VID appears in more than one record.

## Why it matters
The servo takes one of the two values (which one is up to the firmware), so one of the host's
commands is silently lost; usually a copy-paste slip in the host's servo table.

## Example
{example(encode_long(0x1E, [(1, _P10), (1, _P50)]))}
""", kinds=("long",), column="header")
def duplicate_vid(lint, rec, ev):
    vids = [r[0] for r in ev.records]
    if len(set(vids)) != len(vids):
        dup = sorted({v for v in vids if vids.count(v) > 1})
        lint.emit("P004", rec, said("VID {vids} appears more than once", {"vids": ", ".join(map(str, dup))}))


@rule("P005", "invalid-id", "error", "An ID outside 1-127 (and not 255 for a short packet).", f"""
## What it does
Flags a short packet to ID 128-254, a long-packet record with VID 0 or above 127, and a return from an
ID outside 1-127. Servo IDs are 1-127 (table 4.6, No. 4); 255 addresses every servo; 0 marks a long
packet.

## Why it matters
No servo can have such an ID, so the command reaches nobody, and a return claiming one is corrupt
or comes from something that is not an RS30x servo.

## Example
{example(encode_short(200, 0, 0x1E, _G90))}
""", kinds=("short", "long", "return"), column="header")
def invalid_id(lint, rec, ev):
    kind = ev.kind
    if kind == "long":
        bad = [r[0] for r in ev.records if not 1 <= r[0] <= 127]
        if bad:
            lint.emit("P005", rec, said("VID {vids} outside 1-127", {"vids": ", ".join(map(str, bad))}), sid=bad[0])
    elif kind == "short":
        if 128 <= ev.id <= 254:
            lint.emit("P005", rec, said("ID {id} outside 1-127 (255 is broadcast)", {"id": ev.id}))
    elif not 1 <= ev.id <= 127:
        lint.emit("P005", rec, said("return from ID {id}, outside 1-127", {"id": ev.id}))


@rule("P006", "bad-count", "error", "Count is not 1 on a short write, or not 0 on a flag-0F read.", f"""
## What it does
Flags a short packet that carries data (Length above 0) with a Count other than 1, and a flag-0F read
with a Count other than 0. Command packets (flash, reboot, initialize) are P008's business.

## Why it matters
The frame's size is Length x Count, so a wrong Count makes the servo read the wrong number of bytes:
it either takes the next packet's bytes as data or writes garbage past the intended registers.

## Example
{example(frame(1, 0, 0x1E, 1, 2, 0x84, 0x03), frame(1, 0x0F, 0x2A, 2, 1, 0, 0), note="a 1-byte write with Count 2, and a read with Count 1:")}
""", kinds=("short",), column="header")
def bad_count(lint, rec, ev):
    if ev.flag & COMMAND_BITS:
        return
    if ev.return_mode == RETURN_SPECIFIED:
        if ev.count != 0:
            lint.emit("P006", rec, said("flag-0F read with Count {count} (must be 0)", {"count": ev.count}))
    elif ev.length and ev.count != 1:
        lint.emit("P006", rec, said("short write with Length {length} and Count {count} (Count must be 1)",
                                    {"length": ev.length, "count": ev.count}))


@rule("P007", "undefined-return-mode", "error", "Flag bits 3-0 are not a return mode of table 4.3.", f"""
## What it does
Flags a short packet whose return-mode bits (flag bits 3-0) are none of 0000, 0001, 0011, 0101, 0111,
1001, 1011 or 1111 (table 4.3), unless its servo's model defines that mode (its map's return_areas:
1101, a return of addresses 60-127, on {models_where(lambda m: 0x0D in m.behaviour.return_areas)}).

## Why it matters
The host cannot know whether the servo will answer, and with what; the linter cannot pair the
request with a reply either, so a stray return may follow and collide with the next command.

## Example
{example(encode_short(1, 0x02, 0x1E, _G90))}
""", kinds=("short",), column="header")
def undefined_return_mode(lint, rec, ev):
    mode = ev.return_mode
    if mode not in RETURN_MODES and mode not in rec.return_areas:  # a mode the servo's model defines is a read
        lint.emit("P007", rec, said("return mode {mode:04b} is not in table 4.3", {"mode": mode}))


@rule("P008", "command-packet-format", "error", "A flash / reboot / initialize packet not sent as Address FF, Length 0, Count 0.", f"""
## What it does
Flags a packet with the flash, reboot or initialize bit whose Address is not FF, whose Count is not 0,
whose Length is not 0, or that carries data. Initialize is accepted with Length 00 or FF: the manual's
text asks for Length 00 but its example sends FF.

## Why it matters
The manual defines these commands only in that exact form. Mixing a command with a memory write (as
the manual's own return-delay example does) leaves it to the firmware whether the write lands before
the flash or the reboot, or at all.

## Example
{example(frame(1, 0x40, 0x07, 1, 1, 0x12), note="a flash write that also carries return_delay 18:")}
""", kinds=("command",), column="silent")
def command_packet_format(lint, rec, ev):
    problems = []  # the template's pieces, one per field out of form
    if ev.address != COMMAND_ADDRESS:
        problems.append("Address {address:02X}")
    if ev.count != 0:
        problems.append("Count {count}")
    if ev.length != 0 and not (ev.flag & FLAG_INITIALIZE and ev.length == 0xFF):
        problems.append("Length {length}")
    if ev.data:
        problems.append("{data} data byte(s)")  # Length x Count, so the host's packet form, not a measurement
    if problems:
        lint.emit("P008", rec, said("{command} command with " + ", ".join(problems)
                                    + " (expected Address FF, Length 0, Count 0, no data)",
                                    {"command": _cmds(ev), "address": ev.address, "count": ev.count,
                                     "length": ev.length, "data": len(ev.data)}))


@rule("P009", "combined-flash-reboot", "error", "Flash write and reboot requested in one packet.", f"""
## What it does
Flags a packet that sets both the Write Flash ROM bit (6) and the Reboot bit (5), sent to a servo whose
manual asks for the two in separate packets: {models_where(lambda m: not m.behaviour.flash_and_reboot_together)}.
The RS301CR/RS302CD manual allows both in one packet (flag 0x60, p.12), so the rule is silent for
{models_where(lambda m: m.behaviour.flash_and_reboot_together)} (each model's `[behaviour]` in its memory map says
which).

## Why it matters
The manual asks for the two as separate packets, the reboot only after the flash write has finished.
Rebooting while flash is being written can lose the settings or corrupt the servo's stored
configuration (the manual warns not to cut power during a flash write).

## Example
{example(bytes.fromhex("FAAF01600701011274"), note="the manual's own return-delay example:")}
""", kinds=("command",), column="silent")
def combined_flash_reboot(lint, rec, ev):
    if ev.flag & _FLASH_REBOOT == _FLASH_REBOOT and not behaviour_of(rec.model).flash_and_reboot_together:
        lint.emit("P009", rec, said("flash write and reboot in one packet; send the reboot separately, "
                                    "after the flash write", {}))


@rule("P010", "broadcast-return-request", "error", "A packet to ID 255 asks for a reply.", f"""
## What it does
Flags a short packet to the broadcast ID 255 whose flag asks for an ACK/NACK or a return.

## Why it matters
Every servo on the bus would answer at the same moment; the replies collide on the half-duplex line
and the host gets garbage (and may conclude servos are missing).

## Example
{example(encode_read(255, 0x2A, 2))}
""", kinds=("short",), column="header")
def broadcast_return_request(lint, rec, ev):
    if ev.id == BROADCAST_ID and rec.expects is not None:
        lint.emit("P010", rec, said("broadcast packet asks every servo for {reply}",
                                    {"reply": "an ACK" if rec.expects == "ack" else "a return"}))


@rule("P011", "read-out-of-range", "error", "A flag-0F read of length 0 or past address 139.", f"""
## What it does
Flags a flag-0F (specified address) read whose Length is 0 or whose last address is beyond the model's
readable range (address 139, section "Direct specified address").

## Why it matters
The servo has nothing sensible to return; depending on firmware it answers with junk, with a short
return, or not at all, and the host waits for a reply that never fits.

## Example
{example(encode_read(1, 0x80, 16))}
""", kinds=("short",), column="header")
def read_out_of_range(lint, rec, ev):
    if ev.return_mode != RETURN_SPECIFIED:
        return
    top = rec.model.readable_to if rec.model is not None else MAX_READ_ADDRESS
    if ev.length == 0:
        lint.emit("P011", rec, said("read of length 0", {}))
    elif ev.address + ev.length - 1 > top:
        lint.emit("P011", rec, said("read of {first}-{last} goes past address {top}",
                                    {"first": ev.address, "last": ev.address + ev.length - 1, "top": top}))


@rule("P012", "return-count", "warning", "A return packet whose Count is not 1.", f"""
## What it does
Flags a return packet whose Count byte is not 1; table 4.4's notes say a return always carries Count 1.

## Why it matters
A servo never sends anything else, so such a frame was corrupted on the way (with a Sum that still
matched by chance) or comes from a device that only imitates the protocol.

## Example
{example(frame(1, 0, 0x2A, 2, 2, 0x84, 0x03, header=_RET))}
""", kinds=("return",), column="header")
def return_count(lint, rec, ev):
    if ev.count != 1:
        lint.emit("P012", rec, said("return with Count {count} (always 1)", {"count": ev.count}))


@rule("P013", "return-reserved-flag", "warning", "A return packet sets a reserved status bit.", f"""
## What it does
Flags a return whose flags set a bit its servo's model reserves (always 0): bit 6, 4, 2 or 0 in table
4.4, and bit 3 too on models without a flash-write-error bit
({models_where(lambda m: RETURN_FLASH_WRITE_ERROR not in m.behaviour.return_flags)}).

## Why it matters
Either the frame was corrupted in a way the Sum did not catch, or the servo runs firmware this tool
does not know; its other status bits are then not to be trusted either.

## Example
{example(encode_return(1, 0x2A, _G90, flags=0x40))}
""", kinds=("return",), when="flagged", column="silent")
def return_reserved_flag(lint, rec, ev):
    reserved = ev.flags & behaviour_of(rec.model).reserved_flags
    if reserved:
        # The whole flags byte also holds the status bits (table 4.4: temperature, flash, received error),
        # which come and go with the servo's state: measured. The reserved bits set are the behaviour.
        lint.emit("P013", rec, said("return flags 0x{flags:02X} set reserved bit(s) 0x{reserved:02X}",
                                    {"flags": Measured(ev.flags), "reserved": reserved}))
