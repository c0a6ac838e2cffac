"""The /rs30x/transactions body of a request that expects a reply (an MCAP file, the Foxglove server, tables)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, cast

from ...protocol.events import Packet, ShortPacket

if TYPE_CHECKING:  # names for the checker; no import at run time
    from ...decode.pairing import Record


def transaction_json(rec: Record) -> dict[str, Any]:
    """A request that expects a reply, with its reply and latency (the /rs30x/transactions object)."""
    ev = cast(Packet, rec.event)  # a request is a short or long packet
    reply = rec.reply
    rev = reply.event if reply is not None else None
    return {
        "id": ev.id, "op": rec.op if type(ev) is ShortPacket else "write", "expects": rec.expects,
        "status": rec.status or "missing", "request_offset": ev.offset, "t_request": ev.t_start,
        "request_raw": ev.raw.hex(), "read": rec.read_names,
        "reply_type": rev.kind if rev is not None else None,
        "reply_offset": rev.offset if rev is not None else None,
        "t_reply": rev.t_start if rev is not None else None,
        "reply_raw": rev.raw.hex() if rev is not None else None,
        "reply_checksum_ok": rev.checksum_ok if rev is not None else None,
        "latency_s": reply.latency if reply is not None else None,
    }
