"""Turn records into text lines (for people) and JSON objects (for pipes); shared by CLI, MCAP and TUI."""

from __future__ import annotations

import json
from typing import Any

from ..decode.pairing import Record
from ..protocol.events import Garbage, LongPacket, ReturnPacket, ShortPacket
from ..protocol.memmap import Field, Register
from ..protocol.wire import COMMAND_ADDRESS, FLAG_RESERVED, request_flag_names as _short_flag_names
from .layout_json import record_fields_json
from .times import time_text

_KIND_WORD = {"ack": "ACK", "nack": "NACK", "long": "LONG", "return": "RETURN", "garbage": "GARBAGE"}
_OP_WORD = {"write": "WRITE", "read": "READ", "write+read": "WRITE+READ", "write+ack": "WRITE+ACK",
            "ping": "PING", "empty": "NOP", "flash": "FLASH", "reboot": "REBOOT", "initialize": "INIT"}


def direction(rec: Record) -> str:
    """Who put the bytes on the wire: the host (requests), a servo (replies), or unknown (garbage)."""
    if rec.is_request:
        return "host"
    if rec.is_reply:
        return "servo"
    return "?"


def kind_word(rec: Record) -> str:
    """WRITE, READ, LONG, RETURN, ACK, ... as shown in text output and the TUI."""
    ev = rec.event
    op = rec.op  # a short request's, by its servo's model: a return mode it defines reads (RS204MD's 0x0D)
    if op is not None:
        return _OP_WORD.get(op) or op.upper().replace("INITIALIZE", "INIT")
    return _KIND_WORD.get(ev.kind, ev.kind.upper())


def _decimals(reg: Register) -> int:
    s = reg.scale
    if s >= 1 or reg.enum or reg.table:
        return 0
    return max(0, len(f"{s:.10f}".rstrip("0").split(".")[1]))


def format_value(f: Field, with_unit: bool = True) -> str:
    """A field's value as text: 90.0deg, 5.00s, on, 115200bit/s, 0x3030."""
    reg = f.register
    v = f.value
    if f.partial:
        return f"0x{f.raw_value:02X}({f.partial})"
    if reg.name is None:
        return f"0x{f.raw_value:02X}"
    if reg.format == "hex":
        return f"0x{f.raw_value:0{2 * reg.size}X}"
    if v is None:
        return f"?{f.raw_value}"
    if isinstance(v, str):
        return v
    d = _decimals(reg)
    text = f"{v:.{d}f}" if d else (f"{v:g}" if isinstance(v, float) else str(v))
    unit = reg.unit if with_unit else None
    return text + unit if unit else text


def is_shown(f: Field) -> bool:
    # Reserved and undocumented bytes are noise in a one-line summary unless they carry something.
    return f.register.name is not None or f.raw_value != 0


def field_text(f: Field) -> str:
    return f"{f.label}={format_value(f)}"


def bad_sum(rec: Record) -> bool:
    """A packet whose Sum does not match (garbage has no Sum to match)."""
    return not rec.event.checksum_ok and type(rec.event) is not Garbage


def packet_notes(rec: Record) -> list[str]:
    """What a line says of a packet beside its fields: the registers a request reads, a command packet's odd
    header, a return's status flags (table 4.4)."""
    ev = rec.event
    notes = []
    if type(ev) is ShortPacket:
        names = rec.read_names
        read = rec.read_range
        if names and read:
            a, n = read
            notes.append(f"read[{a}+{n}]" if len(names) > 3 else f"read[{','.join(names)}]")
        if ev.commands and not ev.data and (ev.address, ev.length, ev.count) != (COMMAND_ADDRESS, 0, 0):
            notes.append(f"addr={ev.address} len={ev.length} count={ev.count}")
    elif type(ev) is ReturnPacket and ev.flags:
        notes.append("flags=" + ",".join(ev.flag_names or (f"0x{ev.flags:02X}",)))
    return notes


def summary(rec: Record, *, bare: bool = False, keep: bool = True, only: set[int] | None = None) -> str:
    """A one-line description of the record without time, offset or direction.

    ``bare`` leaves out what a table shows in columns of its own (the kind word, the ID, the
    latency); ``keep=False`` decodes the fields without keeping them on the record; ``only`` keeps
    a long packet's fields for those servo IDs alone (``decode --id``).
    """
    ev = rec.event
    t = type(ev)
    fields = rec.fields if keep else rec.peek_fields()
    parts = []
    if not bare:
        parts.append(kind_word(rec) + ("(BAD-SUM)" if bad_sum(rec) else ""))
    if type(ev) is Garbage:
        shown = ev.raw[:16].hex(" ").upper() + (" ..." if len(ev.raw) > 16 else "")
        return " ".join(parts + [f"{len(ev.raw)}B {ev.reason}: {shown}"])
    if bare:
        pass
    elif type(ev) is ShortPacket or type(ev) is ReturnPacket:
        parts.append(f"id={ev.id}")
    elif rec.is_reply and rec.id is not None:  # ACK/NACK: the ID of the request they answer
        parts.append(f"id={rec.id}")
    if t is LongPacket:
        by_id: dict[int | None, list[str]] = {}  # a long packet's fields: each of one servo
        for f in fields:
            if not is_shown(f) or (only is not None and f.id not in only):
                continue
            by_id.setdefault(f.id, []).append(field_text(f))
        parts += [f"{vid}:{','.join(items)}" for vid, items in by_id.items()]
    else:
        parts += [field_text(f) for f in fields if is_shown(f)]
    parts += packet_notes(rec)
    if rec.is_reply:
        if rec.request is not None:
            parts.append(f"reply_to=@{rec.request.offset}")
        if rec.latency is not None and not bare:
            parts.append(f"latency={rec.latency * 1e3:.3f}ms")
        if rec.status and rec.status != "paired":
            parts.append(rec.status.upper())
    elif rec.status == "missing":
        parts.append("NO-REPLY")
    elif rec.status == "unknown":
        parts.append("CAPTURE-ENDED")  # its reply was still due when the capture (or a time segment) ended
    return " ".join(parts)


OWN_TIME = object()  # text_line's ``at`` by default: the record's own capture time


def text_line(rec: Record, only: set[int] | None = None, at: Any = OWN_TIME) -> str:
    """One greppable line: time, offset, direction, then the summary and any findings. ``at`` is the time
    to show (render.times: seconds, a text already made, or None), by default the record's own."""
    ts = time_text(rec.event.t_start if at is OWN_TIME else at)
    line = f"{ts} @{rec.offset:<8} {direction(rec):<5} {summary(rec, only=only)}"
    if rec.findings:
        line += "  [" + ", ".join(f"{d.code} {d.name}" for d in rec.findings) + "]"
    return line


def verbose_lines(rec: Record) -> list[str]:
    """The field tree: header fields, then each field's address, raw bytes, value and unit."""
    ev = rec.event
    out = [f"    raw: {ev.raw.hex(' ').upper()}"]
    if isinstance(ev, (ShortPacket, ReturnPacket, LongPacket)):
        flag = ev.flags if isinstance(ev, ReturnPacket) else ev.flag
        out.append(f"    header: id={getattr(ev, 'id', 0)} flag=0x{flag:02X} address={ev.address} "
                   f"length={ev.length} count={ev.count} sum=0x{ev.raw[-1]:02X}"
                   f"{'' if ev.checksum_ok else ' (checksum mismatch)'}")
    for f in rec.fields:
        unit = f.unit or ""
        who = f"[{f.id}] " if isinstance(ev, LongPacket) else ""
        out.append(f"    {who}{f.label:<22} @{f.address:<3} {f.raw.hex(' ').upper():<6} = "
                   f"{format_value(f, with_unit=False)} {unit}".rstrip())
    for d in rec.findings:
        out.append(f"    ! {d.code} {d.name}: {d.message}")
    return out


# ---- JSON ---------------------------------------------------------------------------------------
def json_value(f: Field) -> Any:
    v = f.value
    if isinstance(v, float):
        return round(v, 6)
    return v


def field_json(f: Field) -> dict[str, Any]:
    return {"id": f.id, "address": f.address, "name": f.name, "raw": f.raw.hex(), "value": json_value(f),
            "unit": f.unit, **({"partial": f.partial} if f.partial else {})}


def request_flag_names(ev: ShortPacket | LongPacket) -> list[str]:
    """The request flag's meanings by name (table 4.2-4.3); a long packet's flag has only bit 7 to name."""
    if isinstance(ev, ShortPacket):
        return _short_flag_names(ev.flag)
    return ["reserved_bit7"] if ev.flag & FLAG_RESERVED else []


NO_FIELDS = {False: '"fields": []', True: '"fields":[]'}
SPACED = json.JSONEncoder(check_circular=False).encode
COMPACT = json.JSONEncoder(separators=(",", ":"), check_circular=False).encode


def record_json_text(rec: Record, only: set[int] | None = None, compact: bool = False) -> str:
    """``json.dumps(record_json(rec, only))`` (``compact``: with "," and ":" separators), the same text
    made faster: the fields come from per-layout templates (layout_json.record_fields_json), not Field
    objects."""
    text = (COMPACT if compact else SPACED)(record_json(rec, only, fields=False))
    fields = record_fields_json(rec, only, compact)
    if fields:
        empty = NO_FIELDS[compact]
        # "fields" is the first list in the object and its key comes before any string that could hold
        # the same characters (hex, names and numbers only): the first match is the right one.
        text = text.replace(empty, empty[:-1] + fields + "]", 1)
    return text


def json_id(rec: Record) -> int | None:
    """The JSON object's ``id``: a packet's header ID (a long packet's is 0), an ACK/NACK's request's, else none."""
    ev = rec.event
    if isinstance(ev, (ReturnPacket, ShortPacket, LongPacket)):
        return ev.id
    return rec.id if rec.is_reply else None


def record_json(rec: Record, only: set[int] | None = None, *, fields: bool = True) -> dict[str, Any]:
    """The public JSON object of a record (``decode --format jsonl``, MCAP /rs30x/packets); ``only``
    keeps a long packet's fields for those servo IDs alone (``decode --id``); ``fields=False`` leaves
    the fields list empty (record_json_text fills it in)."""
    ev = rec.event
    t = type(ev)
    obj: dict[str, Any] = {
        "type": ev.kind,
        "offset": ev.offset,
        "t": ev.t_start,
        "t_end": ev.t_end,
        "raw": ev.raw.hex(),
        "checksum_ok": ev.checksum_ok,
        "id": None, "flag": None, "address": None, "length": None, "count": None,
        "op": None,
        "model": rec.model.name if rec.model is not None and t is not Garbage else None,
        "fields": [field_json(f) for f in rec.fields if only is None or f.id in only] if fields else [],
        "flags": [],
        "reply_to": rec.request.offset if rec.request is not None else None,
        "reply": rec.reply.offset if rec.reply is not None else None,
        "latency_s": rec.latency,
        "status": rec.status,
        "diagnostics": [d.as_json() for d in rec.findings],
    }
    obj["id"] = json_id(rec)
    if type(ev) is ReturnPacket:
        obj.update(address=ev.address, length=ev.length, count=ev.count)
        obj["flag"] = ev.flags
        obj["flags"] = list(ev.flag_names)
    elif type(ev) is ShortPacket or type(ev) is LongPacket:
        obj.update(address=ev.address, length=ev.length, count=ev.count)
        obj["flag"] = ev.flag
        obj["flags"] = request_flag_names(ev)
    if type(ev) is ShortPacket:
        obj["op"] = rec.op
        read = rec.read_range
        if read is not None:
            a, n = read
            obj["read"] = {"address": a, "length": n, "names": rec.read_names}
    elif type(ev) is LongPacket:
        obj["op"] = "write"
        obj["vids"] = [r.vid for r in ev.records]
    elif type(ev) is Garbage:
        obj["reason"] = ev.reason
    return obj
