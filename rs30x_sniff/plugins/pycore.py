"""The RS30x decoding core the sigrok and Saleae plug-ins carry: bytes with positions in, frames with named fields out.

This file is copied verbatim into every generated plug-in, beside a literal ``MAPS = {...}`` (the memory maps as
plain data, made by rs30x_sniff.plugins.maps). So it imports nothing but the standard library and is plain Python
3.8 (libsigrokdecode embeds its own Python; Saleae Logic 2 ships 3.8). It is a port of rs30x-sniff's own decoder,
which the test tests/plugins/test_pycore.py holds it equal to:

- framing (rs30x_sniff/decode/framing.py): FA AF requests, FD DF returns, the XOR Sum over ID..data, ACK (07) and
  NACK (08) single bytes right after a request in return mode 0001 (manual table 4.3), resynchronization on bad
  bytes, frames cut at idle gaps, garbage handed out in pieces of 128 bytes;
- fields (rs30x_sniff/protocol/memmap.py): registers by address, 2-byte registers little-endian, scale, offset,
  enum labels and tables; one byte of a 2-byte register is a "low"/"high" part with its raw value;
- models (rs30x_sniff/decode/pairing.py): every servo is decoded as the default model until a return of its
  model number (addresses 0-1, table 4.5) names another map; a servo_id write moves what was learned. A map with
  no model number (RS405CB, RS406CB) is used only when the user names it;
- missing replies (rs30x_sniff/decode/pairing.py, BusTracker): a short request whose return mode asks for a
  reply (table 4.3) that gets none before the next request, before the reply timeout runs out or before the
  capture ends past it: ``Core.take_no_replies`` hands such requests out (``status`` "missing": decode's
  NO-REPLY).

Positions are whatever the host tool counts in (sample numbers, seconds): the core only compares them.
"""

from functools import reduce
from operator import xor

# A header claiming more data than this is noise, not a frame (the whole memory map is 140 bytes).
MAX_DATA = 1024
# A run of garbage is handed out in pieces of this many bytes, counted from the run's first byte.
GARBAGE_PIECE = 128
# The packet layout ("Format of Packets"): header(2) ID Flag Address Length Count, data, Sum.
AT_ID, AT_FLAG, AT_ADDRESS, AT_LENGTH, AT_COUNT = 2, 3, 4, 5, 6
HEADER_SIZE = 7
FRAME_OVERHEAD = 8  # header(2) + ID Flag Address Length Count + Sum
# Until the first frame, garbage is the tail of a frame cut by the start of the capture, unless it runs on
# for longer than any frame could.
LEAD_MAX = FRAME_OVERHEAD + MAX_DATA
# Where the model number lives (table 4.5) and where servo_id does (table 4.6 No. 4), and the IDs it may hold.
MODEL_NUMBER_ADDRESS, MODEL_NUMBER_SIZE = 0, 2
SERVO_ID_RANGE = (1, 127)

# Why bytes became garbage (the "reason" words of `rs30x-sniff decode --format jsonl`).
NOISE = "noise"
BAD_HEADER = "bad-header"
TRUNCATED = "truncated"
CAPTURE_START = "capture-start"
CAPTURE_END = "capture-end"
_CUT_BY_START = (NOISE, TRUNCATED, BAD_HEADER)

# Results of Framer._frame_end besides an end index.
_WAIT = -1      # more bytes are needed to decide
_NOT_SYNC = -2  # no frame header here
_BAD = -3       # a header whose length cannot be a real frame
_CUT = -4       # _CUT - k: the frame is cut short at buffer index k


class Frame(object):
    """One decoded piece of the bus: a packet, an ACK/NACK byte, or a run of garbage."""

    def __init__(self, kind, offset, raw, byte_positions):
        self.kind = kind                      # "short", "long", "return", "ack", "nack", "garbage"
        self.offset = offset                  # index of its first byte in the whole input
        self.raw = raw                        # its bytes
        self.byte_positions = byte_positions  # (start, end) of each byte
        self.start = byte_positions[0][0]
        self.end = byte_positions[-1][1]
        self.direction = None                 # "host" (FA AF), "servo" (FD DF, ACK, NACK), None (garbage)
        self.checksum_ok = kind in ("ack", "nack")
        self.id = None
        self.flag = None
        self.address = None
        self.length = None
        self.count = None
        self.reason = None                    # garbage: why
        self.model = None                     # the memory map its fields were decoded with
        self.fields = []                      # dicts: id, address, name, label, raw, value, unit, start, end
        self.flags = []                       # the flag byte's meanings by name
        self.warnings = []                    # short words: "bad checksum", "truncated", ...
        self.status = None                    # a request that asked for a reply: "waiting", "answered",
                                              # "missing" (NO-REPLY) or "unknown" (the capture ended first)

    def as_dict(self):
        d = dict(self.__dict__)
        d["raw"] = self.raw.hex()
        d["fields"] = [dict(f) for f in self.fields]
        d["byte_positions"] = [list(p) for p in self.byte_positions]
        return d

    def __repr__(self):
        return "Frame(%s @%d %s)" % (self.kind, self.offset, self.raw.hex())


# ---- memory maps ------------------------------------------------------------------------------------
def convert(reg, raw_value):
    """The engineering value of a whole register's raw value (memmap.Register.convert): an enum's label (the
    raw value when it has none), a table's number (None when it has none), or offset + raw x scale."""
    if reg["enum"] is not None:
        return reg["enum"].get(raw_value, raw_value)
    if reg["table"] is not None:
        return reg["table"].get(raw_value)
    scale = reg["scale"]
    if scale == 1:
        value = raw_value
    elif scale < 1 and abs(1 / scale - round(1 / scale)) < 1e-9:
        value = raw_value / round(1 / scale)  # 900 / 10, not 900 * 0.1: the same float as ours
    else:
        value = raw_value * scale
    return value + reg["offset"] if reg["offset"] else value


class MemoryMap(object):
    """One model's registers by address, and how a packet's data splits into fields."""

    def __init__(self, model):
        self.name = model["name"]
        self.model_number = model["model_number"]
        self.by_address = {}
        for reg in model["registers"]:
            for a in range(reg["address"], reg["address"] + reg["size"]):
                self.by_address[a] = reg
        self.by_name = dict((reg["name"], reg) for reg in model["registers"] if reg["name"])

    def register_at(self, address):
        """The register covering ``address``; an unnamed byte past the documented map."""
        reg = self.by_address.get(address)
        if reg is None:
            reg = {"name": None, "label": "addr_%d" % address, "address": address, "size": 1, "signed": False,
                   "scale": 1, "offset": 0, "unit": None, "access": "read", "enum": None, "table": None,
                   "format": None, "description": ""}
        return reg

    def fields(self, address, data, servo_id, positions):
        """The fields of ``data`` written to or read from memory ``address`` (memmap.Layout)."""
        out = []
        a, end, k = address, address + len(data), 0
        while a < end:
            reg = self.register_at(a)
            if a == reg["address"] and a + reg["size"] <= end:
                size, partial = reg["size"], None
            else:
                size, partial = 1, "low" if a == reg["address"] else "high"
            raw = bytes(data[k:k + size])
            if partial:
                raw_value = value = raw[0]
            else:
                raw_value = int.from_bytes(raw, "little", signed=reg["signed"])
                value = raw_value if reg["name"] is None else convert(reg, raw_value)
            field = {"id": servo_id, "address": a, "name": reg["name"], "label": reg["label"], "raw": raw.hex(),
                     "raw_value": raw_value, "value": value, "unit": None if partial else reg["unit"],
                     "partial": partial, "text": value_text(reg, raw_value, value, partial),
                     "start": positions[k][0], "end": positions[k + size - 1][1]}
            out.append(field)
            a += size
            k += size
        return out


def value_text(reg, raw_value, value, partial):
    """A field's value as short text with its unit (render.records.format_value): 90.0deg, on, 0x3030."""
    if partial:
        return "0x%02X(%s)" % (raw_value, partial)
    if reg["name"] is None:
        return "0x%02X" % raw_value
    if reg["format"] == "hex":
        return "0x%0*X" % (2 * reg["size"], raw_value)
    if value is None:
        return "?%d" % raw_value
    if isinstance(value, str):
        return value
    decimals = 0
    if reg["scale"] < 1 and not reg["enum"] and not reg["table"]:
        decimals = max(0, len(("%.10f" % reg["scale"]).rstrip("0").split(".")[1]))
    if decimals:
        text = "%.*f" % (decimals, value)
    elif isinstance(value, float):
        text = "%g" % value
    else:
        text = str(value)
    return text + reg["unit"] if reg["unit"] else text


# ---- framing ----------------------------------------------------------------------------------------
class Framer(object):
    """The resynchronizing frame decoder (rs30x_sniff.decode.framing.FrameDecoder, fed one byte at a time).

    ``put`` returns raw events ``(kind, offset, raw, positions, detail)``: kind "frame" (detail: the Sum
    matches), "ack", "nack" or "garbage" (detail: the reason). Every byte ends up in exactly one event.
    """

    def __init__(self, protocol, gap=None, seam=None, seam_back=None):
        self.request = bytes(protocol["request_header"])
        self.answer = bytes(protocol["return_header"])
        self.ack, self.nack = protocol["ack"], protocol["nack"]
        self.mode_mask = protocol["return_mode_mask"]
        self.gap, self.seam, self.seam_back = gap, seam, seam_back
        self.buf = bytearray()
        self.pos = []             # (start, end) of each byte of buf
        self.base = 0             # input offset of buf[0]
        self.scan = 0             # where scanning resumes; buf[:scan] is pending garbage
        self.start = 0            # buffer index of the first byte not yet in an event
        self.reason = NOISE       # the reason the pending garbage will get
        self.ack_pending = False  # the next byte may be an ACK/NACK
        self.breaks = []          # input offsets preceded by an idle gap, ascending
        self.lead = True          # no frame yet: garbage is the tail of one cut by the capture's start
        self.seg_start = 0        # input offset where the current capture segment began
        self.last_start = None    # the previous byte's start and end
        self.last_end = None
        self.final = False        # nothing more comes (the end of input, or flagged bytes next)
        self.hard = False         # the line has gone idle after the last byte (idle())
        self.seams = []           # (offset of a new segment's first byte, end of the last byte before it)

    @property
    def offset(self):
        """Input offset of the next byte."""
        return self.base + len(self.buf)

    def _note_gap(self, start):
        if self.gap is not None and self.last_end is not None and start - self.last_end > self.gap:
            if not self.breaks or self.breaks[-1] != self.offset:
                self.breaks.append(self.offset)

    def _seam(self, start):
        """Events ended by a seam before a byte starting at ``start``: the capture resumed after a long silence
        (or its clock went back): what is pending ends as at the end of input, and a new segment begins."""
        if self.last_start is None:
            return []
        if not ((self.seam is not None and start - self.last_start > self.seam)
                or (self.seam_back is not None and start < self.last_start - self.seam_back)):
            return []
        out = self._parse(final=True, ended=True)
        self.seams.append((self.offset, self.last_end))
        self.last_start = self.last_end = None
        self.lead = True
        self.seg_start = self.offset
        return out

    def put(self, byte, start, end):
        out = self._seam(start)
        self._note_gap(start)
        self._add(byte, start, end)
        return out + self._parse(final=False)

    def put_flagged(self, byte, start, end, reason):
        """A byte the capturing UART flagged (framing error): what is pending ends, the byte is garbage."""
        out = self._parse(final=True)
        out += self._seam(start)
        self._note_gap(start)
        self._add(byte, start, end)
        self.start = 0
        self.reason = reason
        self._emit_garbage(out, 1)
        del self.buf[:]
        del self.pos[:]
        self.base += 1
        self.scan = 0
        return out

    def _add(self, byte, start, end):
        self.buf.append(byte)
        self.pos.append((start, end))
        self.hard = False
        if start is not None:
            self.last_start = start if self.last_start is None else max(self.last_start, start)
        if end is not None:
            self.last_end = end if self.last_end is None else max(self.last_end, end)

    def idle(self, at):
        """The line has been quiet until ``at``: past the gap, a pending frame is cut (the next byte will
        come after an idle gap whatever it is) and pending garbage ends."""
        if self.gap is None or self.last_end is None or at - self.last_end <= self.gap:
            return []
        if not self.breaks or self.breaks[-1] != self.offset:
            self.breaks.append(self.offset)
        self.hard = True
        return self._parse(final=False)

    def close(self):
        return self._parse(final=True, ended=True)

    def _next_break(self, after, before):
        """The first break b with after < b < before, or None."""
        for b in self.breaks:
            if b > after:
                return b if b < before else None
        return None

    def _frame_end(self, i):
        """Classify a candidate frame at buffer index i: the index past it, or _WAIT, _NOT_SYNC, _BAD, _CUT - k."""
        buf, n, cut_at_end = self.buf, len(self.buf), self.final or self.hard
        if i + 1 >= n:
            # After an idle gap the next byte still decides: a header cut, or noise (as our decoder sees it).
            return _CUT - n if self.final else _WAIT
        first = buf[i]
        if bytes(buf[i:i + 2]) not in (self.request, self.answer):
            return _NOT_SYNC
        base = self.base
        cut = self._next_break(base + i, base + min(i + HEADER_SIZE, n))
        if cut is not None:
            return _CUT - (cut - base)  # an idle gap inside the header
        if i + HEADER_SIZE > n:
            return _CUT - n if cut_at_end else _WAIT
        length = buf[i + AT_LENGTH]
        # Data bytes = Length x Count for requests, Length for returns ("Format of Packets").
        data_len = length * buf[i + AT_COUNT] if first == self.request[0] else length
        if data_len > MAX_DATA:
            return _BAD
        end = i + FRAME_OVERHEAD + data_len
        cut = self._next_break(base + i, base + min(end, n))
        if cut is not None:
            return _CUT - (cut - base)
        if end > n:
            return _CUT - n if cut_at_end else _WAIT
        return end

    def _intact(self, i):
        if self.hard and i + 1 >= len(self.buf):
            return _NOT_SYNC  # its second byte comes after an idle gap: no intact frame
        end = self._frame_end(i)
        if end < 0:
            return _WAIT if end == _WAIT else _NOT_SYNC
        return end if reduce(xor, self.buf[i + AT_ID:end - 1], 0) == self.buf[end - 1] else _NOT_SYNC

    def _find_intact_inside(self, i, end):
        """Index of the first intact frame starting in (i, end); _NOT_SYNC if none; _WAIT if undecidable."""
        buf = self.buf
        j = i + 1
        while True:
            a = buf.find(self.request, j, end + 1)
            b = buf.find(self.answer, j, end + 1)
            a = -1 if a >= end else a
            b = -1 if b >= end else b
            if a < 0 and b < 0:
                if (end == len(buf) and not (self.final or self.hard)
                        and buf[end - 1] in (self.request[0], self.answer[0])):
                    return _WAIT  # a sync byte in the last place may start a frame still to come
                return _NOT_SYNC
            q = a if b < 0 or 0 <= a < b else b
            r = self._intact(q)
            if r == _WAIT:
                return _WAIT
            if r >= 0:
                return q
            j = q + 1

    def _leading(self, i):
        if self.base + i - self.seg_start < LEAD_MAX:
            return True
        self.lead = False  # longer than any frame: no tail of one
        return False

    def _parse(self, final, ended=False):
        out = []
        buf = self.buf
        n = len(buf)
        self.start = 0
        self.final = final
        hard = self.hard and not final
        sync = (self.request[0], self.answer[0])
        i = self.scan
        while i < n:
            while i - self.start >= GARBAGE_PIECE and not (self.lead and self._leading(i)):
                self._emit_garbage(out, self.start + GARBAGE_PIECE)
            start, base, br = self.start, self.base, self.breaks
            while br and br[0] <= base + start:
                br.pop(0)
            if i > start and br and br[0] == base + i:
                self._emit_garbage(out, i)  # garbage runs end at idle gaps
                continue
            c = buf[i]
            if self.ack_pending:
                # ACK/NACK bytes have no header: only the byte right after a request asking for one.
                self.ack_pending = False
                if i == start and (c == self.ack or c == self.nack):
                    self._emit(out, "ack" if c == self.ack else "nack", i + 1, True)
                    i += 1
                    continue
            if c in sync:
                end = self._frame_end(i)
                if end == _WAIT:
                    break
                if end == _NOT_SYNC or end == _BAD:
                    if end == _BAD:
                        self.reason = BAD_HEADER
                    i += 1
                    continue
                ok = end >= 0 and reduce(xor, buf[i + AT_ID:end - 1], 0) == buf[end - 1]
                if not ok:
                    stop = end if end >= 0 else _CUT - end
                    q = self._find_intact_inside(i, stop)
                    if q == _WAIT:
                        break
                    if q >= 0 or end < 0:
                        # Cut short, or corrupt with an intact frame inside: the head is garbage.
                        if i > start:
                            self._emit_garbage(out, i)
                        self.reason = CAPTURE_END if ended and q < 0 and stop == n else TRUNCATED
                        i = q if q >= 0 else stop
                        self._emit_garbage(out, i)
                        continue
                if i > start:
                    self._emit_garbage(out, i)
                self._emit(out, "frame", end, ok)
                self.ack_pending = self._wants_ack(out[-1][2])
                i = end
                continue
            # Not a sync byte: skip ahead to the next possible one (or the next idle gap).
            nxt = n
            for s in sync:
                k = buf.find(s, i + 1)
                if 0 <= k < nxt:
                    nxt = k
            gap = self._next_break(base + i, base + nxt)
            i = nxt if gap is None else gap - base
        while i - self.start >= GARBAGE_PIECE and not (self.lead and self._leading(i)):
            self._emit_garbage(out, self.start + GARBAGE_PIECE)
        if final and n > self.start:
            self._emit_garbage(out, n)
            i = n
        elif hard and i == n and n > self.start:
            self._emit_garbage(out, n)  # the garbage run ends at the idle gap
        start = self.start
        if start:
            del buf[:start]
            del self.pos[:start]
            self.base += start
            i -= start
        self.scan = i
        return out

    def _wants_ack(self, raw):
        """A short request in return mode 0001 (table 4.3): the next byte may be its ACK/NACK."""
        return raw[0] == self.request[0] and raw[AT_ID] != 0 and raw[AT_FLAG] & self.mode_mask == 1

    def _emit(self, out, kind, end, detail):
        self.lead = False
        start = self.start
        out.append((kind, self.base + start, bytes(self.buf[start:end]), self.pos[start:end], detail))
        self.start = end

    def _emit_garbage(self, out, end):
        reason = self.reason
        start = self.start
        if self.lead and reason in _CUT_BY_START:
            if self.base + start == self.seg_start and bytes(self.buf[start:start + 2]) in (self.request, self.answer):
                self.lead = False  # the segment starts with a header: no frame was cut by its start
            elif not (self.final and end == len(self.buf)):
                reason = CAPTURE_START
        out.append(("garbage", self.base + start, bytes(self.buf[start:end]), self.pos[start:end], reason))
        self.start = end
        self.reason = NOISE
        self.ack_pending = False


# ---- the core ---------------------------------------------------------------------------------------
class Core(object):
    """Feed bytes with their positions; get Frames with direction, header, named and scaled fields.

    ``maps``: the plug-in's MAPS; ``model``: the model to decode servos as until their model number is seen
    (default: the maps' default); ``gap``: idle time (in the units of the positions) that cuts a frame short,
    None for never; ``seam``: a longer silence after which the capture counts as resumed (nothing pending
    carries over), and ``seam_back`` how far positions may go back before the same; ``reply_timeout``: how long
    after its request an ACK/NACK still answers it (None: always).
    """

    def __init__(self, maps, model=None, gap=None, seam=None, seam_back=None, reply_timeout=None):
        self.protocol = maps["protocol"]
        self.maps = {}
        for m in maps["models"]:
            self.maps.setdefault(m["name"].upper(), MemoryMap(m))
        for m in maps["models"]:  # another name of a map, unless a model of that name has a map of its own
            for name in m.get("also_named") or ():
                self.maps.setdefault(name.upper(), self.maps[m["name"].upper()])
        self.by_number = {}
        for m in maps["models"]:  # the first map of a model number wins (as in our registry)
            if m["model_number"] is not None:  # a model without one is known only by its name
                self.by_number.setdefault(m["model_number"], self.maps[m["name"].upper()])
        name = (model or maps["default_model"]).upper()
        if name not in self.maps:
            raise ValueError("unknown model %r (known: %s)" % (model, ", ".join(sorted(self.maps))))
        self.default = self.maps[name]
        self.reply_timeout = reply_timeout
        self.framer = Framer(self.protocol, gap, seam, seam_back)
        self.learned = {}   # servo ID -> MemoryMap told by its model number
        self.servos = {}    # servo ID -> MemoryMap, for every servo a checksum-valid packet named
        self.request = None  # the last request, while an ACK/NACK may answer it
        self.waiting = None  # the request whose reply is due (pairing.BusTracker's pending request)
        self.no_replies = []  # requests found missing their reply, not yet taken
        self.last_end = None  # the end of the last frame's last byte
        wanting = [mode for mode, row in self.protocol["return_modes"].items() if row["expect"] != "none"]
        self.wants_reply = set(int(mode) for mode in wanting)  # return modes that ask for a reply (table 4.3)
        self._id_address = self.default.by_name["servo_id"]["address"] if "servo_id" in self.default.by_name else 4

    # ---- input ----
    def feed(self, byte, start=None, end=None):
        """One byte and its start/end positions: the frames it completes."""
        return self._frames(self.framer.put(byte, start, end))

    def feed_flagged(self, byte, start=None, end=None, reason="framing-error"):
        """A byte the capturing UART flagged (framing or parity error): it becomes garbage of its own."""
        return self._frames(self.framer.put_flagged(byte, start, end, reason))

    def idle(self, at):
        """The line has been idle until ``at``: frames the gap ends (and a reply that is now overdue is
        missing: see take_no_replies)."""
        frames = self._frames(self.framer.idle(at))
        self.idle_until(at)
        return frames

    def flush(self):
        """End of input: whatever is pending."""
        frames = self._frames(self.framer.close())
        self._end_segment(self.framer.last_end if self.framer.last_end is not None else self.last_end)
        return frames

    def take_no_replies(self):
        """The requests found missing their reply since the last call (decode's NO-REPLY), oldest first."""
        out, self.no_replies = self.no_replies, []
        return out

    # ---- frames ----
    def model_of(self, servo_id):
        return self.learned.get(servo_id, self.default)

    def _servo(self, servo_id):
        if servo_id not in self.servos:
            self.servos[servo_id] = self.model_of(servo_id)

    def _frames(self, events):
        frames = []
        for ev in events:
            f = self._frame(*ev)
            self._pair(f)
            frames.append(f)
        return frames

    def idle_until(self, at):
        """The line has been quiet until ``at``: a reply due longer ago than the reply timeout is missing."""
        w = self.waiting
        if (w is not None and self.reply_timeout is not None and at is not None and w.end is not None
                and at - w.end > self.reply_timeout):
            self._missing(w)

    # ---- replies (rs30x_sniff.decode.pairing.BusTracker.feed_into) ----
    def _pair(self, f):
        seams = self.framer.seams
        while seams and seams[0][0] <= f.offset:
            self._end_segment(seams.pop(0)[1])  # nothing is paired across a seam of the clock
        w = self.waiting
        if (w is not None and self.reply_timeout is not None and f.start is not None and w.end is not None
                and f.start - w.end > self.reply_timeout):
            self._missing(w)
            w = None
        if f.kind in ("return", "ack", "nack"):
            if w is not None:
                w.status = "answered"
                self.waiting = None
        elif f.kind in ("short", "long"):
            if w is not None:
                self._missing(w)  # another request: the servo will not answer this one
            if f.kind == "short" and f.flag & self.protocol["return_mode_mask"] in self.wants_reply:
                f.status = "waiting"
                self.waiting = f
        if f.end is not None:
            self.last_end = f.end

    def _missing(self, request):
        request.status = "missing"
        self.no_replies.append(request)
        self.waiting = None

    def _end_segment(self, end):
        """The capture (or a time segment) ended at ``end``: a reply still due is missing if the reply timeout
        ran out before then, else unknown (it may have come after the capture)."""
        w = self.waiting
        if w is None:
            return
        timeout = self.reply_timeout
        if timeout is not None and end is not None and w.end is not None and end - w.end > timeout:
            self._missing(w)
        else:
            w.status = "unknown"
            self.waiting = None

    def _frame(self, kind, offset, raw, positions, detail):
        p = self.protocol
        if kind == "garbage":
            f = Frame("garbage", offset, raw, positions)
            f.reason = detail
            f.warnings = [detail]
            self.request = None
            return f
        if kind in ("ack", "nack"):
            f = Frame(kind, offset, raw, positions)
            f.direction = "servo"
            req, self.request = self.request, None
            if req is not None and (self.reply_timeout is None or f.start is None or req.end is None
                                    or f.start - req.end <= self.reply_timeout):
                f.id = req.id
                f.model = req.model
            else:
                f.warnings = ["unsolicited"]
            return f
        first = raw[0]
        sid, flag, address, length, count = raw[AT_ID], raw[AT_FLAG], raw[AT_ADDRESS], raw[AT_LENGTH], raw[AT_COUNT]
        data, data_pos = raw[HEADER_SIZE:-1], positions[HEADER_SIZE:-1]
        if first == p["return_header"][0]:
            f = Frame("return", offset, raw, positions)
            f.direction = "servo"
        else:
            f = Frame("long" if sid == p["long_packet_id"] else "short", offset, raw, positions)
            f.direction = "host"
        f.checksum_ok = detail
        f.id, f.flag, f.address, f.length, f.count = sid, flag, address, length, count
        if not detail:
            f.warnings.append("bad checksum")
        self.request = None
        if f.kind == "return":
            f.flags = [name for bit, name in p["return_flag_bits"].items() if flag & bit]
            f.warnings += f.flags
            model = self.model_of(sid)
            if detail:
                self._servo(sid)
                if address == MODEL_NUMBER_ADDRESS and len(data) >= MODEL_NUMBER_SIZE:
                    learned = self.by_number.get(int.from_bytes(data[:MODEL_NUMBER_SIZE], "little"))
                    if learned is not None and learned is not self.servos[sid]:
                        self.learned[sid] = self.servos[sid] = learned
                model = self.servos[sid]
            f.model = model.name
            f.fields = model.fields(address, data, sid, data_pos) if data else []
        elif f.kind == "short":
            f.flags = self._request_flag_names(flag)
            model = self.model_of(sid)
            f.model = model.name
            f.fields = model.fields(address, data, sid, data_pos) if data else []
            if flag & p["return_mode_mask"] == 1:
                self.request = f
            if detail and sid != p["broadcast_id"]:
                self._servo(sid)
                if data and address <= self._id_address < address + len(data):
                    self._renumber([(sid, data[self._id_address - address])])
        else:
            f.flags = ["reserved_bit7"] if flag & p["flag_reserved"] else []
            f.model = self.default.name
            size = length - 1  # each record: its VID, then this many data bytes ("Long Packet")
            records = [(k, data[k], data[k + 1:k + length]) for k in range(0, len(data), length)] if length else []
            uniform = all(m is self.default for m in self.learned.values())
            for k, vid, rec in records:
                model = self.default if uniform else self.model_of(vid)
                f.fields += model.fields(address, rec, vid, data_pos[k + 1:k + length]) if rec else []
            if detail and size > 0:
                for _, vid, _ in records:
                    self._servo(vid)
                if address <= self._id_address < address + size:
                    k = self._id_address - address
                    self._renumber([(vid, rec[k]) for _, vid, rec in records if len(rec) > k])
        return f

    def _request_flag_names(self, flag):
        """What a short request's flag says (tables 4.2-4.3): its commands, reserved_bit7, its return mode."""
        p = self.protocol
        names = [name for bit, name in p["commands"] if flag & bit]
        if flag & p["flag_reserved"]:
            names.append("reserved_bit7")
        mode = flag & p["return_mode_mask"]
        row = p["return_modes"].get(mode)
        if row is None:
            names.append("return_mode_{:04b}".format(mode))
        elif row["name"] is not None:
            names.append(row["name"])
        return names

    def _renumber(self, moves):
        """Servos whose servo_id was written answer to the new ID at once (table 4.6 No. 4): what was
        learned of their model moves with them."""
        lo, hi = SERVO_ID_RANGE
        moves = [(old, new) for old, new in moves if old != new and lo <= new <= hi]
        if not moves:
            return
        taken = [(new, self.servos.pop(old, None)) for old, new in moves]
        for old, _ in moves:
            self.learned.pop(old, None)
        for new, model in taken:
            if model is None:
                continue
            if model is self.default:
                self.learned.pop(new, None)
            else:
                self.learned[new] = model
            self.servos[new] = model
