"""A sink writing the decoded capture as pcapng for Wireshark: one packet per frame or garbage run, in order."""

from __future__ import annotations

import struct
from array import array
from bisect import bisect_right
from typing import IO, Any
from collections.abc import Iterable

from ..decode.decoder import Step
from ..decode.pairing import Record
from ..protocol.wire import byte_time
from ..version import __version__
from .pipeline import Sink

# pcapng (draft-ietf-opsawg-pcapng): block types and the options written here.
SHB, IDB, ISB, EPB = 0x0A0D0D0A, 0x00000001, 0x00000005, 0x00000006
BYTE_ORDER_MAGIC = 0x1A2B3C4D
OPT_ENDOFOPT, OPT_COMMENT = 0, 1
SHB_HARDWARE, SHB_OS, SHB_USERAPPL = 2, 3, 4
IF_NAME, IF_DESCRIPTION, IF_TSRESOL = 2, 3, 9
EPB_FLAGS = 2
ISB_STARTTIME, ISB_ENDTIME, ISB_IFRECV = 2, 3, 4
TSRESOL_NS = 9  # if_tsresol: 10^-9 s, timestamps in nanoseconds

# LINKTYPE_WIRESHARK_UPPER_PDU: each packet starts with exported-PDU tags (big-endian tag, length, value) that
# name the dissector to hand the rest to. Chosen over a user DLT (147-162) because the file then says which
# dissector it is for (tshark without the plug-in shows "Dissector name: rs30x"), and it takes no DLT_USER
# slot a user may already have given to another protocol (Wireshark's epan/exported_pdu.h).
LINKTYPE_WIRESHARK_UPPER_PDU = 252
EXP_PDU_TAG_END_OF_OPT = 0
EXP_PDU_TAG_DISSECTOR_NAME = 12
DISSECTOR_NAME = b"rs30x"

# epb_flags bits 0-1: the direction (pcapng: 0 not available, 1 inbound, 2 outbound).
DIRECTION_UNKNOWN, DIRECTION_INBOUND, DIRECTION_OUTBOUND = 0, 1, 2

# The rs30x packet header, between the exported-PDU tags and the wire's bytes: what our decoder decided
# of the bytes, which the bytes alone cannot tell the Lua dissector (an 07 byte that is garbage and not an
# ACK; why a run was skipped; which request a reply answers; the servo's model).
#   u8 version (1), u8 kind (KIND_CODES), u8 direction (as epb_flags), u8 reason length,
#   u32 big-endian frame number of the request a reply answers (1-based as Wireshark counts; 0: none),
#   u8 model length, then the reason text (garbage: noise, truncated, ...), the model name, the wire's bytes.
HEADER_VERSION = 1
KIND_CODES = {"short": 1, "long": 2, "return": 3, "ack": 4, "nack": 5, "garbage": 6}
RS30X_HEADER = struct.Struct(">BBBBIB")

DIRECTION_OF_KIND = {"short": DIRECTION_OUTBOUND, "long": DIRECTION_OUTBOUND, "return": DIRECTION_INBOUND,
                     "ack": DIRECTION_INBOUND, "nack": DIRECTION_INBOUND, "garbage": DIRECTION_UNKNOWN}


def _pad4(n: int) -> int:
    return (4 - n % 4) % 4


def option(code: int, value: bytes) -> bytes:
    """One pcapng option: code, length, value padded to 32 bits."""
    return struct.pack("<HH", code, len(value)) + value + b"\0" * _pad4(len(value))


def options(opts: Iterable[tuple[int, bytes]]) -> bytes:
    body = b"".join(option(c, v) for c, v in opts)
    return body + struct.pack("<HH", OPT_ENDOFOPT, 0) if body else b""


def block(kind: int, body: bytes) -> bytes:
    """A pcapng block: type, total length, body (padded), total length again."""
    body += b"\0" * _pad4(len(body))
    total = len(body) + 12
    return struct.pack("<II", kind, total) + body + struct.pack("<I", total)


def exported_pdu_tags() -> bytes:
    """The tags before every packet's payload: the dissector's name, then the end of the tags."""
    name = DISSECTOR_NAME + b"\0" * _pad4(len(DISSECTOR_NAME))
    return (struct.pack(">HH", EXP_PDU_TAG_DISSECTOR_NAME, len(name)) + name
            + struct.pack(">HH", EXP_PDU_TAG_END_OF_OPT, 0))


def rs30x_header(kind: str, request_frame: int, reason: str, model: str) -> bytes:
    r = reason.encode("utf-8")[:255]
    m = model.encode("utf-8")[:255]
    return RS30X_HEADER.pack(HEADER_VERSION, KIND_CODES[kind], DIRECTION_OF_KIND[kind], len(r),
                             request_frame, len(m)) + r + m


def finding_comment(f: Any) -> str:
    return f"{f.code} {f.name}: {f.message}"


class PcapngSink(Sink[Record]):
    """Writes pcapng: a section and one interface (the bus), then an Enhanced Packet Block per record.

    Times are in nanoseconds: the capture's own (plus ``start_time``, a wall-clock anchor, when given), or
    for a capture without times the moment each byte would reach the wire at ``baud`` (8N1), counted from
    ``start_time`` or 0. Findings on a record are comments on its packet; one on no record (F010 at a seam of
    the capture: a clock restart, a lost port) is a comment on the first packet at or past its place; the few
    only the end of input reveals concern packets already written, and go as comments on an Interface
    Statistics Block at the end, each naming its frame.
    """

    def __init__(self, out: IO[bytes], *, source: str, baud: int, timed: bool,
                 start_time: float | None = None) -> None:
        self.out = out
        self.baud = baud
        self.timed = timed
        self.origin_ns = round((start_time or 0.0) * 1e9)
        self.byte_time = byte_time(baud)
        self.offsets = array("q")  # each packet's stream offset, in order: frame number by bisect
        self.packets = 0
        self.bytes_written = 0
        self.late: list = []
        self.loose: list = []  # findings on no record, waiting for the first packet at or past their offset
        self.first_ns: int | None = None
        self.last_ns = 0
        self.tags = exported_pdu_tags()
        if timed:
            clock = ("capture times, anchored to the wall clock" if start_time is not None else
                     "capture times as the capture gave them")
        else:
            clock = (f"the capture has no times: each packet at the time its first byte would reach the wire "
                     f"at {baud} bit/s 8N1, counted from "
                     + ("the --start-time anchor" if start_time is not None else "0"))
        self.clock = clock
        shb = struct.pack("<IHHq", BYTE_ORDER_MAGIC, 1, 0, -1) + options([
            (OPT_COMMENT, f"RS30x bus decoded from {source}; times: {clock}".encode()),
            (SHB_USERAPPL, f"rs30x-sniff {__version__}".encode()),
        ])
        idb = struct.pack("<HHI", LINKTYPE_WIRESHARK_UPPER_PDU, 0, 0) + options([
            (IF_NAME, b"rs30x"),
            (IF_DESCRIPTION, f"RS30x bus, {baud} bit/s 8N1".encode()),
            (IF_TSRESOL, bytes([TSRESOL_NS])),
            (OPT_COMMENT, f"times: {clock}".encode()),
        ])
        self._write(block(SHB, shb) + block(IDB, idb))

    def _write(self, data: bytes) -> None:
        self.out.write(data)
        self.bytes_written += len(data)

    def time_ns(self, t: float | None, offset: int) -> int:
        # The anchor and the time since it are rounded apart: their sum in seconds (1.8e9 s) would keep
        # only a quarter of a microsecond in a double.
        return max(0, self.origin_ns + round((t if t is not None else offset * self.byte_time) * 1e9))

    def frame_of(self, offset: int) -> int:
        """The 1-based frame number of the packet holding stream ``offset`` (0: none written yet)."""
        return bisect_right(self.offsets, offset)

    def batch(self, step: Step) -> None:
        write = self._write
        tags = self.tags
        offsets = self.offsets
        if step.findings:
            self.loose += step.loose()
        loose = self.loose
        for rec in step:
            ev = rec.event
            kind = ev.kind
            req = rec.request if kind in ("return", "ack", "nack") else None
            request_frame = self.frame_of(req.event.offset) if req is not None else 0
            reason = ev.reason if kind == "garbage" else ""
            model = rec.model.name if rec.model is not None and kind != "garbage" else ""  # as decode's JSON
            payload = tags + rs30x_header(kind, request_frame, reason, model) + ev.raw
            ns = self.time_ns(ev.t_start, ev.offset)
            if self.first_ns is None:
                self.first_ns = ns
            self.last_ns = max(self.last_ns, ns)
            opts = [(OPT_COMMENT, finding_comment(f).encode("utf-8")) for f in rec.findings]
            if loose:
                here = [f for f in loose if f.offset <= ev.offset]
                opts += [(OPT_COMMENT, finding_comment(f).encode("utf-8")) for f in here]
                loose[:] = [f for f in loose if f.offset > ev.offset]
            opts.append((EPB_FLAGS, struct.pack("<I", DIRECTION_OF_KIND[kind])))
            n = len(payload)
            body = (struct.pack("<IIIII", 0, ns >> 32, ns & 0xFFFFFFFF, n, n) + payload + b"\0" * _pad4(n)
                    + options(opts))
            write(block(EPB, body))
            offsets.append(ev.offset)
            self.packets += 1
        if step.late:
            self.late += step.late

    def close(self) -> None:
        """The end: an Interface Statistics Block (packets, first and last times, late findings)."""
        first = self.first_ns or 0
        opts = [(OPT_COMMENT, f"frame {self.frame_of(f.offset)} (offset {f.offset}): {finding_comment(f)}"
                 .encode()) for f in self.late + self.loose]
        opts += [(ISB_STARTTIME, struct.pack("<II", first >> 32, first & 0xFFFFFFFF)),
                 (ISB_ENDTIME, struct.pack("<II", self.last_ns >> 32, self.last_ns & 0xFFFFFFFF)),
                 (ISB_IFRECV, struct.pack("<Q", self.packets))]
        body = struct.pack("<III", 0, self.last_ns >> 32, self.last_ns & 0xFFFFFFFF) + options(opts)
        self._write(block(ISB, body))
