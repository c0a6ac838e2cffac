"""sigrok captures: ``.sr`` session files (the UART decoded from the samples here) and sigrok-cli's UART annotations.

``.sr`` (``sigrok``): a zip holding ``version``, an INI ``metadata`` (``[device 1]`` with ``samplerate``,
``unitsize``, ``total probes`` and ``probeN`` channel names) and the samples in ``logic-1-1``,
``logic-1-2``... (little-endian units of ``unitsize`` bytes; bit k is probe k+1). One channel is read:
``--channel`` by name (``D0``, ``RX``) or by index from 0 (probe N is index N-1); without it the only
channel, else the first channel that toggles (and a warning says which, when several do). The bytes are
decoded as 8N1 (rs30x_sniff.sources.uart) at ``--baud``, or at the rate the samples show (found from the
pulse widths and scored by the RS30x frames each nearby rate decodes). Each chunk's time is its start
bit's first low sample over the sample rate.

sigrok-cli's annotations (``sigrok-uart``): what ``sigrok-cli -i CAPTURE -P uart:rx=D0:baudrate=BPS -A
uart=rx-data --protocol-decoder-samplenum`` prints, ``SS-ES uart-1: FA`` per byte (``-l 4`` and up
print ``SS-ES uart-1: rx-data: "FA"``; ``tx-data`` rows are read as well, and ``--channel rx|tx`` keeps
one of the two). ``Frame error`` / ``Parity error`` rows (``-A uart=rx-data:rx-warnings:rx-parity-err``)
mark the byte they follow; start, stop and data-bit rows are skipped. The text has sample numbers but
no sample rate: a byte's annotation spans its 8 data bits, so the mean span gives the samples per bit,
and the rate given to sigrok-cli's decoder (``--baud``, which the user passes again to us) turns that
into seconds. Without ``--baud`` the decoder's default 115200 is assumed and a warning says so: the
bytes and their order are right either way, only the time scale depends on it. Without
``--protocol-decoder-samplenum`` the bytes carry no times at all.
"""

from __future__ import annotations

import io
import itertools
import re
import zlib
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, BinaryIO
from collections.abc import Iterator

from ..protocol.chunks import FRAMING_ERROR, PARITY_ERROR, Marked
from .timebase import FIRST
from ..protocol.wire import BITS_PER_BYTE, DEFAULT_BAUD
from .captures import CaptureError
from .foreign import ForeignFormat, ReadContext, register

if TYPE_CHECKING:
    import zipfile

ZIP_MAGIC = b"PK\x03\x04"
VERSIONS = ("1", "2")
ESTIMATE_SAMPLES = 1 << 24   # samples the rate is estimated from, at most (4 s at 4 MHz)
LOW_WARNING = 0.9            # share of low samples that says the line is inverted (or not the bus)
ESTIMATE_EDGES = 40000       # ... or fewer once they hold this many level changes (some thousands of bytes)
_RATE = re.compile(r"^\s*([0-9]+(?:\.[0-9]+)?)\s*([kMG]?)\s*(?:Hz)?\s*$", re.I)
_PREFIX = {"": 1, "k": 1e3, "m": 1e6, "g": 1e9}


def _numpy(path: str) -> Any:
    try:
        import numpy as np
    except ModuleNotFoundError:
        raise CaptureError(f"{path}: decoding logic samples needs numpy (pip install numpy)") from None
    return np


# ---- .sr session files ----------------------------------------------------------------------------
@dataclass
class Session:
    """What a .sr file's metadata says, and the names of its sample chunks in order."""

    path: str
    zf: zipfile.ZipFile
    samplerate: float
    unitsize: int
    channels: dict[int, str]   # bit index -> name, for the channels the capture holds
    members: list[str]

    def describe_channels(self) -> str:
        return ", ".join(f"{name} (index {i})" for i, name in sorted(self.channels.items())) or "none"


def parse_samplerate(text: str) -> float | None:
    """Hz from sigrok's spelling: ``1 MHz``, ``500 kHz``, ``4000000``; None if it is none of those."""
    m = _RATE.match(text)
    if not m:
        return None
    rate = float(m.group(1)) * _PREFIX[m.group(2).lower()]
    return rate if rate > 0 else None


def open_session(stream: BinaryIO, path: str) -> Session:
    """Read a .sr file's version and metadata (a one-line CaptureError when it is not a session)."""
    import zipfile  # a sigrok session only: not a cost of every command's start-up

    try:
        zf = zipfile.ZipFile(stream)
    except (zipfile.BadZipFile, OSError, EOFError, ValueError) as e:
        raise CaptureError(f"{path}: not a readable sigrok session (a damaged or truncated zip: {e})") from None
    names = set(zf.namelist())
    for need in ("version", "metadata"):
        if need not in names:
            raise CaptureError(f"{path}: not a sigrok session: the zip has no {need!r} file")
    version = _member(zf, path, "version").decode("ascii", "replace").strip()
    if version not in VERSIONS:
        raise CaptureError(f"{path}: sigrok session version {version!r} is not one this reader knows "
                           f"({', '.join(VERSIONS)})")
    import configparser  # a sigrok session only: not a cost of every command's start-up

    meta = configparser.ConfigParser(interpolation=None, strict=False)
    try:
        meta.read_string(_member(zf, path, "metadata").decode("utf-8", "replace"))
    except configparser.Error as e:
        raise CaptureError(f"{path}: its metadata is not an INI file: {str(e).splitlines()[0]}") from None
    devices = [s for s in meta.sections() if s.startswith("device ") and meta.has_option(s, "capturefile")]
    if not devices:
        raise CaptureError(f"{path}: its metadata has no [device N] section with a capturefile")
    dev = meta[devices[0]]
    rate_text = dev.get("samplerate")
    if rate_text is None:
        raise CaptureError(f"{path}: its metadata gives no samplerate")
    samplerate = parse_samplerate(rate_text)
    if samplerate is None:
        raise CaptureError(f"{path}: samplerate {rate_text!r} is not a rate (1 MHz, 500 kHz, 4000000)")
    try:
        unitsize = int(dev.get("unitsize", "1"))
        total = int(dev.get("total probes", "0"))
    except ValueError:
        raise CaptureError(f"{path}: unitsize and total probes must be whole numbers") from None
    if not 1 <= unitsize <= 8:
        raise CaptureError(f"{path}: unitsize {unitsize} is not 1 to 8 bytes")
    channels: dict[int, str] = {}
    for key, value in dev.items():
        m = re.fullmatch(r"probe(\d+)", key)
        if m:
            index = int(m.group(1)) - 1
            if not 0 <= index < unitsize * 8:
                raise CaptureError(f"{path}: {key} is beyond the {unitsize * 8} bits of a sample")
            channels[index] = value.strip()
    if not channels and total:
        channels = {i: str(i) for i in range(min(total, unitsize * 8))}  # unnamed: call them by index
    base = dev["capturefile"].strip()
    numbered = sorted((int(n[len(base) + 1:]), n) for n in names
                      if n.startswith(base + "-") and n[len(base) + 1:].isdigit())
    members = [n for _, n in numbered] or ([base] if base in names else [])
    return Session(path, zf, samplerate, unitsize, channels, members)


def _member(zf: zipfile.ZipFile, path: str, name: str) -> bytes:
    import zipfile

    try:
        return zf.read(name)
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, ValueError) as e:
        raise CaptureError(f"{path}: {name} in the sigrok session cannot be read "
                           f"(damaged or truncated: {e})") from None


def _bits(raw: bytes, unitsize: int, index: int, np: Any) -> Any:
    """One channel's levels (bool) from a chunk of little-endian sample units."""
    usable = len(raw) - len(raw) % unitsize
    units = np.frombuffer(raw, np.uint8, count=usable)
    if unitsize > 1:
        units = units[index // 8::unitsize]  # the byte of each unit that holds this bit
    return (units & np.uint8(1 << (index % 8))) != 0


def _toggles(session: Session, np: Any) -> list[int]:
    """Indexes of the channels that change level in the first chunk where any does (lowest first)."""
    mask = sum(1 << i for i in session.channels)
    for name in session.members:
        raw = _member(session.zf, session.path, name)
        usable = len(raw) - len(raw) % session.unitsize
        if usable < 2 * session.unitsize:
            continue
        units = np.frombuffer(raw, np.uint8, count=usable).reshape(-1, session.unitsize)
        changed = np.bitwise_or.reduce(units[1:] ^ units[:-1], axis=0)
        word = int.from_bytes(changed.tobytes(), "little") & mask
        if word:
            return [i for i in sorted(session.channels) if word >> i & 1]
    return []


def pick_channel(session: Session, choice: Any, warn: Any, np: Any) -> tuple[int, str]:
    """The channel to decode: ``choice`` by name, else by index; else the only one, else the first that toggles."""
    chans = session.channels
    if not chans:
        raise CaptureError(f"{session.path}: the sigrok session lists no logic channels")
    if choice is not None and str(choice).strip() != "":
        text = str(choice).strip()
        for i, name in sorted(chans.items()):
            if name == text:
                return i, name
        for i, name in sorted(chans.items()):
            if name.lower() == text.lower():
                return i, name
        if text.isdigit() and int(text) in chans:
            return int(text), chans[int(text)]
        raise CaptureError(f"{session.path}: no channel {text!r} (the capture has {session.describe_channels()})")
    if len(chans) == 1:
        [(i, name)] = chans.items()
        return i, name
    active = _toggles(session, np)
    if not active:
        i = min(chans)
        if warn:
            warn(f"{session.path}: no channel changes level; reading {chans[i]} (--channel to pick another)")
        return i, chans[i]
    i = active[0]
    if len(active) > 1 and warn:
        names = ", ".join(chans[k] for k in active)
        warn(f"{session.path}: channels {names} all carry signals; decoding {chans[i]} "
             f"(--channel NAME|INDEX to pick another)")
    return i, chans[i]


def _blocks(session: Session, index: int, np: Any) -> Iterator[Any]:
    for name in session.members:
        yield _bits(_member(session.zf, session.path, name), session.unitsize, index, np)


def _window(blocks: Iterator[Any], np: Any) -> Any:
    """Enough samples to tell the rate by: from the first level change on, ESTIMATE_SAMPLES samples or
    ESTIMATE_EDGES changes (an idle stretch before the traffic is not kept)."""
    kept: list[Any] = []
    held = edges = 0
    for block in blocks:
        if len(block) < 2:
            continue
        changed = np.flatnonzero(block[1:] != block[:-1])
        if not kept:
            if not len(changed):
                continue
            block, changed = block[changed[0]:], changed - changed[0]
        kept.append(block)
        held += len(block)
        edges += len(changed)
        if edges >= ESTIMATE_EDGES or held >= ESTIMATE_SAMPLES:
            break
    if not kept:
        return np.zeros(0, bool)
    return (np.concatenate(kept) if len(kept) > 1 else kept[0])[:ESTIMATE_SAMPLES]


def _find_baud(session: Session, index: int, np: Any) -> Any:
    """The rate the channel's samples show (a pass over the first chunks of its own)."""
    from .uart import estimate_baud

    return estimate_baud(_window(_blocks(session, index, np), np), session.samplerate)


def _note(guess: Any, channel: str) -> str:
    return f"found from the samples of channel {channel}: {guess.evidence}"


def read_sr(stream: BinaryIO, ctx: ReadContext) -> Iterator[Any]:
    """The chunks of a .sr session: the chosen channel decoded as 8N1."""
    np = _numpy(ctx.path)
    from .uart import UartDecoder, chunks

    session = open_session(stream, ctx.path)
    index, name = pick_channel(session, ctx.options.get("channel"), ctx.warn, np)
    baud = ctx.options.get("baud")
    if not baud:
        guess = _find_baud(session, index, np)
        if guess:
            baud = guess.baud
            ctx.found["baud"] = baud
            ctx.found["baud_note"] = _note(guess, name)
        else:
            baud = DEFAULT_BAUD
            if ctx.warn and guess.bit_samples is not None:
                ctx.warn(f"{ctx.path}: the samples of channel {name} show no bit rate ({guess.evidence}); "
                         f"decoding at {baud} bit/s (--baud to say otherwise)")
    ctx.found["channel"] = name
    try:
        dec = UartDecoder(session.samplerate, baud)
    except ValueError as e:
        raise CaptureError(f"{ctx.path}: {e}") from None
    rate = session.samplerate
    for block in _blocks(session, index, np):
        yield from chunks(dec.feed(block), rate, baud)
    yield from chunks(dec.close(), rate, baud)
    # Even a bus busy with 00 bytes is high one bit in ten: a line low nearly all the time is no UART idling high.
    if ctx.warn and dec.samples and dec.low_samples > LOW_WARNING * dec.samples:
        ctx.warn(f"{ctx.path}: channel {name} is low {dec.low_samples / dec.samples:.0%} of the time, but a UART "
                 "line idles high: is the signal inverted, or is this not the bus wire?")


def probe_sr(path: str, options: dict[str, Any]) -> dict[str, Any]:
    """The rate the samples show (before the file is read): ``{"baud": ..., "baud_note": ...}``, or {}."""
    if options.get("baud"):
        return {}
    np = _numpy(path)
    with open(path, "rb") as f:
        session = open_session(f, path)
        index, name = pick_channel(session, options.get("channel"), None, np)
        guess = _find_baud(session, index, np)
    if not guess:
        return {}
    return {"baud": guess.baud, "baud_note": _note(guess, name), "channel": name}


def sniff_sr(head: bytes) -> bool:
    # sigrok writes "version" as the zip's first file: a local header's name starts at byte 30.
    return head.startswith(ZIP_MAGIC) and head[30:37] == b"version"


# ---- sigrok-cli's UART annotations ----------------------------------------------------------------
# "109-179 uart-1: FA", "uart-1: FA", "109-179 uart-1: rx-data: \"FA\"" (the class and every text
# variant, quoted, at log level 4 and up).
_LINE = re.compile(r'^(?:(\d+)-(\d+)\s+)?([A-Za-z][\w.]*-\d+):\s*(?:([a-z]+(?:-[a-z]+)+):\s*)?(.*?)\s*$')
_QUOTED = re.compile(r'"([^"]*)"')
_HEX_BYTE = re.compile(r"^[0-9A-Fa-f]{2}$")
_ERRORS = {"frame error": FRAMING_ERROR, "parity error": PARITY_ERROR}
_SKIPPED_TEXT = re.compile(r"^(?:[01]|start bit|stop bit|parity bit|break condition)$", re.I)
_SKIPPED_CLASSES = ("start", "stop", "parity-ok", "data-bits", "break", "packet")
WIDTH_SAMPLE = 512   # data rows whose spans are averaged for the samples per bit before the first chunk
_FLUSH = 4096        # untimed bytes per chunk


@dataclass
class _Row:
    kind: str          # "data" or an error reason
    value: int
    ss: int | None
    es: int | None
    line: int
    direction: str     # "rx", "tx" or "" (not said)


def _parse_line(text: str, lineno: int, path: str) -> _Row | None:
    m = _LINE.match(text)
    if not m:
        raise CaptureError(f"{path}:{lineno}: not a sigrok-cli uart annotation (expected e.g. "
                           f"'109-179 uart-1: FA'): {text[:40]!r}", line=lineno)
    ss, es, decoder, cls, rest = m.groups()
    if not decoder.lower().startswith("uart"):
        raise CaptureError(f"{path}:{lineno}: an annotation of decoder {decoder!r}, not uart", line=lineno)
    if ss is not None and int(es) < int(ss):
        raise CaptureError(f"{path}:{lineno}: sample range {ss}-{es} ends before it starts", line=lineno)
    if cls is not None:
        quoted = _QUOTED.findall(rest)
        if not quoted:
            raise CaptureError(f"{path}:{lineno}: expected the annotation text in quotes after {cls}:", line=lineno)
        body = quoted[0]
        direction, _, what = cls.partition("-")
        if direction not in ("rx", "tx"):
            raise CaptureError(f"{path}:{lineno}: {cls!r} is not a uart annotation class", line=lineno)
        if what in _SKIPPED_CLASSES:
            return None
        if what not in ("data", "warnings", "parity-err"):
            raise CaptureError(f"{path}:{lineno}: {cls!r} is not a uart annotation class", line=lineno)
        if what == "data" and not _HEX_BYTE.match(body):
            raise CaptureError(f"{path}:{lineno}: {body[:20]!r} is not a hex byte (run the uart decoder with its "
                               "default format=hex)", line=lineno)
    else:
        body, direction = rest, ""
    a, b = (int(ss), int(es)) if ss is not None else (None, None)
    if _HEX_BYTE.match(body):
        return _Row("data", int(body, 16), a, b, lineno, direction)
    reason = _ERRORS.get(body.lower())
    if reason is not None:
        return _Row(reason, 0, a, b, lineno, direction)
    if _SKIPPED_TEXT.match(body) or body.lower() in ("frame err", "fe", "parity err", "pe"):
        return None
    raise CaptureError(f"{path}:{lineno}: {body[:20]!r} is neither a hex byte nor a uart annotation this reader "
                       "knows (run the uart decoder with its default format=hex)", line=lineno)


def _rows(stream: BinaryIO, path: str, direction: str | None) -> Iterator[_Row]:
    text = io.TextIOWrapper(stream, encoding="utf-8", errors="replace", newline=None)
    timed: bool | None = None
    for lineno, line in enumerate(text, 1):
        if lineno == 1 and line.startswith("\ufeff"):
            line = line[1:]
        if not line.strip():
            continue
        row = _parse_line(line.strip(), lineno, path)
        if row is None:
            continue
        if timed is None:
            timed = row.ss is not None
        elif timed != (row.ss is not None):
            raise CaptureError(f"{path}:{lineno}: some lines have sample numbers and some do not "
                               "(run sigrok-cli with --protocol-decoder-samplenum throughout)", line=lineno)
        if direction and row.direction and row.direction != direction:
            continue
        yield row


def read_annotations(stream: BinaryIO, ctx: ReadContext) -> Iterator[Any]:
    """The chunks of sigrok-cli's uart annotation text (see the module's docstring for the time scale)."""
    channel = ctx.options.get("channel")
    direction = None
    if channel is not None and str(channel).strip():
        direction = str(channel).strip().lower()
        if direction not in ("rx", "tx"):
            raise CaptureError(f"{ctx.path}: --channel {channel}: annotation text has rows rx and tx only")
    rows = _rows(stream, ctx.path, direction)
    # Read ahead the first data rows: their spans (8 data bits each) give the samples per bit.
    head: list[_Row] = []
    for row in rows:
        head.append(row)
        if sum(r.kind == "data" for r in head) >= WIDTH_SAMPLE:
            break
    bit = _samples_per_bit([r for r in head if r.kind == "data" and r.ss is not None])
    samplerate = ctx.options.get("samplerate")
    baud = ctx.options.get("baud")
    if bit is not None and not samplerate:
        if not baud:
            baud = DEFAULT_BAUD
            if ctx.warn:
                ctx.warn(f"{ctx.path}: sigrok-cli's annotations give sample numbers but no sample rate: times "
                         f"assume the uart decoder ran at {baud} bit/s (give its baudrate with --baud)")
        samplerate = bit * baud
        ctx.found["samplerate"] = samplerate
    yield from _annotation_chunks(itertools.chain(head, rows), samplerate, bit)


def _samples_per_bit(rows: list[_Row]) -> float | None:
    """Samples per bit from data rows: a row spans its 8 data bits, but sigrok rounds the span's ends
    outwards (up to a sample too long); back-to-back bytes start exactly 10 bits apart, and their
    spacings, each off by under a sample either way, average to the true bit time."""
    if not rows:
        return None
    # The caller passes rows whose sample ends are read (ss not None; _parse_line reads ss and es together).
    rough = sum(r.es - r.ss for r in rows) / (8 * len(rows))  # type: ignore[operator, misc]  # see above
    steps = [b.ss - a.ss for a, b in zip(rows, rows[1:])]   # type: ignore[operator]  # see above
    # 5 % apart: a byte after one idle bit (11 bits) is not taken for back to back.
    close = [d for d in steps if abs(d - BITS_PER_BYTE * rough) <= 0.05 * BITS_PER_BYTE * rough]
    if len(close) >= 8:
        return sum(close) / (BITS_PER_BYTE * len(close))
    return rough


def _annotation_chunks(rows: Iterator[_Row], samplerate: float | None, bit: float | None) -> Iterator[Any]:
    """Bytes from rows: runs of back-to-back bytes in one chunk, flagged bytes on their own."""
    pending: _Row | None = None   # the last data row, until the next row says whether an error marks it
    flag: str | None = None
    run = bytearray()
    run_t: float | None = None
    run_ss = 0.0
    per_byte = (bit or 0.0) * BITS_PER_BYTE

    def start_of(r: _Row) -> float:
        # The data span begins one bit after the start bit; a row without sample numbers has no start (and no t).
        return r.ss - bit if bit is not None and r.ss is not None else 0.0

    def emit(r: _Row, error: str | None) -> Iterator[Any]:
        nonlocal run, run_t, run_ss
        t = None if samplerate is None or r.ss is None else start_of(r) / samplerate
        if error is not None:
            if run:
                yield bytes(run), run_t
                run = bytearray()
            yield Marked(bytes([r.value]), t, error=error)
            return
        s = start_of(r)
        if run and (t is None and len(run) < _FLUSH or
                    t is not None and abs(s - run_ss - len(run) * per_byte) <= (bit or 0) / 2):
            run.append(r.value)
            return
        if run:
            yield bytes(run), run_t
        run, run_t, run_ss = bytearray([r.value]), t, s

    for row in rows:
        if row.kind == "data":
            if pending is not None:
                yield from emit(pending, flag)
            pending, flag = row, None
        elif pending is not None and flag is None and \
                (row.ss is None or pending.es is None or row.ss <= pending.es + 2 * (bit or 0)):
            flag = row.kind  # the stop (or parity) bit of the byte just read
        # else: an error away from any byte (a start bit high again at its centre): no byte to mark
    if pending is not None:
        yield from emit(pending, flag)
    if run:
        yield bytes(run), run_t


def sniff_annotations(head: bytes) -> bool:
    """The first line of the head is a uart annotation, so are most of the others, and one is a byte.

    Strict where it matters (no other capture starts with ``109-179 uart-1: FA``), yet a file with a
    bad line further on is still taken for annotations, so that the reader names that line.
    """
    try:
        text = head.decode("ascii")
    except UnicodeDecodeError:
        return False  # sigrok-cli's uart annotations in hex are ASCII
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    if len(head) >= 4096 and lines and not text.endswith(("\n", "\r")):
        lines = lines[:-1]  # cut by the window
    rows, bad = [], 0
    for n, line in enumerate(lines, 1):
        try:
            rows.append(_parse_line(line, n, ""))
        except CaptureError:
            if n == 1:
                return False
            bad += 1
    return bool(rows) and 2 * bad < len(lines) and any(r is not None and r.kind == "data" for r in rows)


SIGROK = register(ForeignFormat(
    name="sigrok",
    description="sigrok session (.sr): logic samples, the UART decoded here",
    sniff=sniff_sr,
    read=read_sr,
    time_ref=FIRST,
    extensions=(".sr",),
    needs_seek=True,
    channels=True,
    probe=probe_sr,
))

SIGROK_UART = register(ForeignFormat(
    name="sigrok-uart",
    description="sigrok-cli uart annotations (-A uart=rx-data --protocol-decoder-samplenum)",
    sniff=sniff_annotations,
    read=read_annotations,
    time_ref=FIRST,
    channels=True,
))
