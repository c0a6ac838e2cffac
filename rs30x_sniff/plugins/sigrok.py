"""The sigrok protocol decoder (sigrok-cli, PulseView): an 'rs30x' decoder stacked on sigrok's uart, made from the maps.

The decoder is a package of four files: ``pd.py`` (the Decoder class, a fixed text written here), ``core.py``
(rs30x_sniff/plugins/pycore.py verbatim: the standalone framing and field decoding), ``maps.py`` (the memory maps
and the wire's constants as one Python literal from :func:`~rs30x_sniff.plugins.maps.py_literal`) and
``__init__.py`` (the description ``sigrok-cli --show -P rs30x`` prints). Only ``maps.py`` and the README depend
on the maps: no name, unit or label of a map is ever written into code, so a hostile map can only be data.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .maps import py_literal

PACKAGE = "rs30x"  # the decoder's id and folder name: what `-P rs30x` names

HEADER = """\
##
## This file is part of rs30x-sniff, the protocol analyzer for the Futaba RS30x servo bus.
## Written by `rs30x-sniff plugin sigrok`: write it again rather than editing it.
##
## SPDX-License-Identifier: MIT
##
"""

INIT = HEADER + """
'''
This decoder stacks on top of the 'uart' PD and decodes the packets of the
Futaba command-type servos (RS30x and the family that shares its packets:
each model the 'model' option lists has a memory map): short and long
packets from the host, return packets, ACK and NACK, with the memory map's
register names, scaled values and units. A servo is decoded with the model
its model-number return names; a model without a known number (RS405CB,
RS406CB) only when the 'model' option names it.

The bus is one half-duplex wire at 115200 bit/s (8N1) unless the servos were
set to another rate (manual table 4.7): decode it as the uart's RX. When the
uart decodes both RX and TX, each line is framed on its own.

A frame ends when its length says so, or at an idle gap of 'gap' byte times
(a cut frame). libsigrokdecode 0.5 tells a stacked decoder nothing at the end
of the capture: a frame still open then needs the uart's IDLE (a line left
idle for 'gap' byte times after the last byte) to be shown.

Options:
  model: the memory map used to name the registers.
  gap: idle byte times that end a frame (default 20).
'''

from .pd import Decoder
"""

PD = HEADER + r"""
import json
import sigrokdecode as srd
from .core import Core
from .maps import MAPS

'''
OUTPUT_PYTHON format:

Packet:
<frame>

One dict per frame (the core's Frame.as_dict()), positions in samples:
 - 'kind': 'short', 'long', 'return', 'ack', 'nack' or 'garbage'.
 - 'start', 'end': the frame's first and last sample; 'byte_positions': the
   [start, end] of each byte; 'offset': the index of its first byte on the line.
 - 'raw': the frame's bytes (hex).
 - 'direction': 'host', 'servo' or None; 'line': 0 for the uart's RX, 1 for TX.
 - 'checksum_ok', 'id', 'flag', 'address', 'length', 'count': the header.
 - 'reason': why bytes are garbage ('noise', 'truncated', 'bad-header', ...).
 - 'model': the memory map the fields were named by.
 - 'fields': a list of dicts {'id', 'address', 'name', 'label', 'raw',
   'raw_value', 'value', 'unit', 'partial', 'text', 'start', 'end'}: the
   registers a packet carries, scaled by the memory map.
 - 'flags', 'warnings': lists of strings.

Binary output 'frames': the same dicts as JSON, one line each.
'''

# Every model a user may name: each map's own name, then the other names of a
# map (a model that shares another's registers), once each.
MODELS = tuple(model['name'] for model in MAPS['models'])
MODELS += tuple(sorted(set(name for model in MAPS['models']
    for name in model.get('also_named') or () if name not in MODELS)))
PROTOCOL = MAPS['protocol']

# The uart's two lines (its <rxtx>).
RX = 0
TX = 1

# As rs30x-sniff decodes: a line silent this long (s) is a capture resumed,
# and an ACK/NACK later than this (s) after its request answers none.
SEAM_S = 10.0
REPLY_TIMEOUT_S = 0.05

# PulseView (0.4.2 as Debian ships it) colours a class by its row and its
# index: hue = the decoder's hue + 20 x row + 55 x class index (degrees). The
# indices are chosen for what that gives (with the first decoder's hue, 120):
# packets: request green, return cyan, ACK blue, NACK purple; fields: header
# teal, register yellow, checksum green, a bad sum red; warnings: a note (the
# edge of the capture, a fact rather than a fault) blue, a missing reply
# magenta, an error red, a warning amber. Under another hue they stay as far
# apart: a bad sum 110 degrees from a good one, an error 55 from a warning.
class Ann:
    (REQUEST, RETURN, ACK, NACK, BAD_SUM, REGISTER, CHECKSUM, HEADER, NOTE,
     NO_REPLY, ERROR, WARNING) = range(12)

# Garbage whose reason is the edge of the capture, not a fault of the bus.
EDGE_REASONS = ('capture-start', 'capture-end')

PACKET_CLASS = {
    'short': Ann.REQUEST,
    'long': Ann.REQUEST,
    'return': Ann.RETURN,
    'ack': Ann.ACK,
    'nack': Ann.NACK,
}

class Decoder(srd.Decoder):
    api_version = 3
    id = 'rs30x'
    name = 'RS30x'
    longname = 'Futaba RS30x servo bus'
    desc = 'Futaba RS30x command-type servo packets, named by the memory maps.'
    license = 'mit'
    inputs = ['uart']
    outputs = ['rs30x']
    tags = ['Embedded/industrial']
    options = (
        {'id': 'model', 'desc': 'Servo model (memory map)',
            'default': MAPS['default_model'], 'values': MODELS},
        {'id': 'gap', 'desc': 'Idle byte times that end a frame',
            'default': 20.0},
    )
    annotations = (  # in the order of Ann
        ('request', 'Request'),
        ('return', 'Return'),
        ('ack', 'ACK'),
        ('nack', 'NACK'),
        ('bad-sum', 'Bad checksum'),
        ('register', 'Register'),
        ('checksum', 'Checksum'),
        ('header', 'Header field'),
        ('note', 'Note (the edge of the capture)'),
        ('no-reply', 'No reply'),
        ('error', 'Error'),
        ('warning', 'Warning'),
    )
    annotation_rows = (
        ('packets', 'Packets', (Ann.REQUEST, Ann.RETURN, Ann.ACK, Ann.NACK)),
        ('fields', 'Fields', (Ann.HEADER, Ann.REGISTER, Ann.CHECKSUM,
            Ann.BAD_SUM)),
        ('warnings', 'Warnings', (Ann.NOTE, Ann.WARNING, Ann.NO_REPLY,
            Ann.ERROR)),
    )
    binary = (
        ('frames', 'Frames (JSON lines)'),
    )

    def __init__(self):
        self.reset()

    def reset(self):
        # One core per uart line: bytes of RX and TX may overlap in time, and
        # one frame never spans two wires.
        self.samplerate = None
        self.cores = [None, None]
        self.data = [None, None]

    def start(self):
        self.out_ann = self.register(srd.OUTPUT_ANN)
        self.out_python = self.register(srd.OUTPUT_PYTHON)
        self.out_binary = self.register(srd.OUTPUT_BINARY)

    def metadata(self, key, value):
        if key == srd.SRD_CONF_SAMPLERATE:
            self.samplerate = value

    def core(self, rxtx, byte_samples):
        # Positions are sample numbers. The gap is counted in byte times, and
        # the byte time is what the uart's own frames span (the uart's baud
        # rate option is not visible to a stacked decoder).
        if self.cores[rxtx] is None:
            gap = self.options['gap']
            seam = reply = None
            if self.samplerate:
                seam = SEAM_S * self.samplerate
                reply = REPLY_TIMEOUT_S * self.samplerate
            self.cores[rxtx] = Core(MAPS, model=self.options['model'],
                gap=gap * byte_samples if gap > 0 else None, seam=seam,
                reply_timeout=reply)
        return self.cores[rxtx]

    def putann(self, ss, es, cls, texts):
        self.put(ss, es, self.out_ann, [cls, texts])

    def decode(self, ss, es, data):
        ptype, rxtx, pdata = data
        if ptype == 'DATA':
            self.data[rxtx] = pdata[0]
        elif ptype == 'FRAME':
            value, valid = pdata
            if self.data[rxtx] is None:
                return  # an invalid start bit: no byte came
            self.data[rxtx] = None
            core = self.core(rxtx, es - ss)
            if valid:
                self.show(rxtx, core.feed(value & 0xFF, ss, es))
            else:
                # A low stop bit: the byte is garbage of its own.
                self.show(rxtx, core.feed_flagged(value & 0xFF, ss, es, 'framing-error'))
        elif ptype == 'IDLE':
            core = self.cores[rxtx]
            if core is not None:
                self.show(rxtx, core.idle(es))

    def show(self, rxtx, frames):
        for frame in frames:
            self.show_frame(rxtx, frame)
        core = self.cores[rxtx]
        if core is not None:
            # Requests that asked for a reply and got none (decode's NO-REPLY):
            # the next request came first, or the line stayed silent past
            # the reply timeout.
            for request in core.take_no_replies():
                self.putann(request.start, request.end, Ann.NO_REPLY,
                    no_reply_texts(request))

    def show_frame(self, rxtx, frame):
        ss, es = frame.start, frame.end
        cls = PACKET_CLASS.get(frame.kind)
        if cls is not None:
            self.putann(ss, es, cls, packet_texts(frame))
            self.show_header(frame)
            for field in frame.fields:
                self.putann(field['start'], field['end'], Ann.REGISTER, field_texts(field))
            self.show_checksum(frame)
        else:
            cls = Ann.NOTE if frame.reason in EDGE_REASONS else Ann.ERROR
            self.putann(ss, es, cls, garbage_texts(frame))
        for warning in frame.warnings:
            if warning == 'bad checksum':
                self.putann(ss, es, Ann.ERROR, ['Bad checksum', 'Bad sum', '!'])
            elif frame.kind != 'garbage':
                self.putann(ss, es, Ann.WARNING, warning_texts(frame, warning))
        record = frame.as_dict()
        record['line'] = rxtx
        self.put(ss, es, self.out_python, record)
        line = json.dumps(record, default=str, sort_keys=False) + '\n'
        self.put(ss, es, self.out_binary, [0, line.encode('utf-8')])

    def show_checksum(self, frame):
        pos = frame.byte_positions
        if frame.kind in ('ack', 'nack') or len(pos) <= PROTOCOL['header_size']:
            return
        total = frame.raw[-1]
        if frame.checksum_ok:
            texts = ['Checksum: %02X' % total, 'Sum %02X' % total, 'S']
            self.putann(pos[-1][0], pos[-1][1], Ann.CHECKSUM, texts)
            return
        # The Sum is the XOR of ID..data ("Format of Packets").
        due = 0
        for b in frame.raw[2:-1]:
            due ^= b
        texts = ['Checksum: %02X (bad, should be %02X)' % (total, due),
                 'Sum %02X bad' % total, 'Bad', '!']
        self.putann(pos[-1][0], pos[-1][1], Ann.BAD_SUM, texts)

    def show_header(self, frame):
        # A packet's header bytes (manual, "Format of Packets"): header, ID,
        # flag, address, length, count; a long packet's VID before each
        # servo's data.
        pos = frame.byte_positions
        if frame.kind in ('ack', 'nack'):
            return
        def put(index, texts):
            if index < len(pos):
                self.putann(pos[index][0], pos[index][1], Ann.HEADER, texts)
        if len(pos) >= 2:
            self.putann(pos[0][0], pos[1][1], Ann.HEADER,
                ['Header %s' % frame.raw[:2].hex().upper(), 'Header', 'H'])
        put(2, ['ID: %d' % frame.id, 'ID %d' % frame.id, 'ID'])
        flags = ', '.join(frame.flags)
        what = 'Flags' if frame.kind == 'return' else 'Flag'
        put(3, ['%s: %02X%s' % (what, frame.flag, ' (%s)' % flags if flags else ''),
            '%s %02X' % (what, frame.flag), 'F'])
        put(4, ['Address: %d' % frame.address, 'Addr %d' % frame.address, 'A'])
        put(5, ['Length: %d' % frame.length, 'Len %d' % frame.length, 'L'])
        put(6, ['Count: %d' % frame.count, 'Cnt %d' % frame.count, 'C'])
        if frame.kind == 'long' and frame.length:
            # Each record is its VID, then Length - 1 data bytes.
            last = len(pos) - PROTOCOL['sum_size']
            for index in range(PROTOCOL['header_size'], last, frame.length):
                vid = frame.raw[index]
                put(index, ['VID: %d' % vid, 'VID %d' % vid, 'V'])

def value_text(field):
    # The core's text glues the unit on (90.0deg): here it stands apart.
    text, unit = field.get('text'), field['unit']
    if text is None:
        text = str(field['value']) + (unit or '')
    if unit and text.endswith(unit):
        text = text[:-len(unit)] + ' ' + unit
    return text

def field_texts(field):
    # Longest first: PulseView shows the longest that fits, and elides the
    # last one only when none does (a value, then the value without its unit).
    name = field['name'] or field.get('label') or 'address %d' % field['address']
    value = value_text(field)
    texts = ['%s: %s (ID %d)' % (name, value, field['id']), '%s: %s' % (name, value), value]
    unit = field['unit']
    if unit and value.endswith(' ' + unit):
        value = value[:-len(unit) - 1]
        texts.append(value)
    # The same number without its trailing zeros (7.40 -> 7.4, 90.0 -> 90):
    # narrower, and still exact.
    if '.' in value and value.replace('.', '', 1).lstrip('-').isdigit():
        short = value.rstrip('0').rstrip('.')
        if short != value:
            texts.append(short)
    return texts

def words(name):
    # A name of the maps or the core (temperature_alarm) as people write it.
    return name.replace('_', ' ').replace('-', ' ')

def warning_texts(frame, warning):
    label = words(warning)
    if warning == 'unsolicited':
        what = frame.kind.upper()
        return ['%s that no request asked for' % what, 'Unsolicited %s' % what, 'Unsolicited', '!']
    texts = [label[:1].upper() + label[1:]]
    if frame.id is not None:
        texts.insert(0, '%s (ID %d)' % (texts[0], frame.id))
    return texts + ['!']

def no_reply_texts(request):
    return ['No reply from ID %d (NO-REPLY)' % request.id, 'No reply from ID %d' % request.id,
            'No reply', 'NR']

def packet_texts(frame):
    bad = '' if frame.checksum_ok is not False else ' (bad checksum)'
    if frame.kind == 'short':
        flags = ', '.join(frame.flags)
        return ['Short packet to ID %d: flag %02X%s, address %d, length %d, count %d%s' % (
                    frame.id, frame.flag, ' (%s)' % flags if flags else '', frame.address,
                    frame.length, frame.count, bad),
                'Short ID %d' % frame.id, 'S']
    if frame.kind == 'long':
        return ['Long packet: flag %02X, address %d, length %d, count %d%s' % (
                    frame.flag, frame.address, frame.length, frame.count, bad),
                'Long', 'L']
    if frame.kind == 'return':
        flags = ', '.join(frame.flags)
        return ['Return from ID %d: flags %02X%s, address %d, length %d%s' % (
                    frame.id, frame.flag, ' (%s)' % flags if flags else '', frame.address,
                    frame.length, bad),
                'Return ID %d' % frame.id, 'R']
    word = 'ACK' if frame.kind == 'ack' else 'NACK'
    if frame.id is None:
        return ['%s (no request asked for it)' % word, word, word[0]]
    return ['%s from ID %d' % (word, frame.id), word, word[0]]

def garbage_texts(frame):
    reason = ' (%s)' % frame.reason if frame.reason else ''
    return ['Garbage: %d bytes %s%s' % (len(frame.raw), frame.raw.hex().upper(), reason),
            'Garbage: %d bytes%s' % (len(frame.raw), reason), 'Garbage: %d bytes' % len(frame.raw),
            'Garbage', 'G']
"""


def core_source() -> str:
    """The standalone decoding core the plug-in embeds (rs30x_sniff/plugins/pycore.py), verbatim."""
    from . import __file__ as package_file
    return Path(package_file).with_name("pycore.py").read_text(encoding="utf-8")


def maps_module(maps: dict[str, Any]) -> str:
    return (HEADER + "\n'''The memory maps and the wire's constants the decoder names packets by (data only).'''\n\n"
            + "MAPS = " + py_literal(maps) + "\n")


def readme(maps: dict[str, Any]) -> str:
    models = ", ".join(m["name"] for m in maps["models"])
    return f"""# rs30x: a sigrok protocol decoder for the Futaba RS30x servo bus

Written by `{maps['generator']}` (`rs30x-sniff plugin sigrok -o DIR`) from the memory maps it knew:
{models} (default {maps['default_model']}). After changing a map (`$RS30X_DECODERS`) write it again; do
not edit it.

It stacks on sigrok's `uart` decoder. With `DIR` the folder that holds this `rs30x/` folder:

    SIGROKDECODE_DIR=DIR sigrok-cli -i capture.sr -P uart:rx=D0:baudrate=115200,rs30x -A rs30x
    SIGROKDECODE_DIR=DIR sigrok-cli -i capture.sr -P uart:rx=D0:baudrate=115200,rs30x:model=MODEL \\
        -A rs30x=register
    SIGROKDECODE_DIR=DIR sigrok-cli -i capture.sr -P uart:rx=D0:baudrate=115200,rs30x -B rs30x=frames > frames.jsonl

For PulseView, copy `rs30x/` into `~/.local/share/libsigrokdecode/decoders/` (or start PulseView with
`SIGROKDECODE_DIR=DIR`), add a UART decoder on the bus wire at the bus's baud rate, and stack RS30x on it.

Options: `model` (the memory map that names the registers until a servo's model number is read),
`gap` (idle byte times that end a frame, default 20; the byte time is measured from the uart's frames).

Rows: Packets (request, return, ACK, NACK), Fields (header bytes, registers with scaled values and units,
checksum; a bad one in a class of its own, `bad-sum`), Warnings (`error`: a bad checksum, cut frames, garbage,
framing errors; `warning`: the return flags a servo sets, an unsolicited ACK/NACK; `no-reply`: a request whose
reply never came, as `rs30x-sniff decode` says NO-REPLY; `note`: bytes cut by the capture's start or end). In
PulseView each class of a row has its own colour. Binary output
`frames`: one JSON object per frame; a decoder stacked on this one gets the same dict as Python output.
With both uart lines (rx and tx) each line is framed on its own; the frame's `line` says which.

A frame still open when the capture ends is shown only if the line stays idle for `gap` byte times
after its last byte (libsigrokdecode 0.5 tells a stacked decoder nothing at the end of the data).
"""


def generate(maps: dict[str, Any]) -> dict[str, str]:
    """The decoder's files (path relative to the decoders folder -> text)."""
    return {
        f"{PACKAGE}/__init__.py": INIT,
        f"{PACKAGE}/pd.py": PD,
        f"{PACKAGE}/core.py": core_source(),
        f"{PACKAGE}/maps.py": maps_module(maps),
        f"{PACKAGE}/README.md": readme(maps),
    }


def install_hint(out: Path) -> str:
    """How to use the folder ``out`` just written (the decoders folder that holds ``rs30x/``)."""
    return (f"wrote the sigrok protocol decoder '{PACKAGE}' in {out / PACKAGE}\n"
            f"run: SIGROKDECODE_DIR={out} sigrok-cli -i CAPTURE.sr -P uart:rx=D0:baudrate=115200,{PACKAGE} "
            f"-A {PACKAGE}\n"
            f"or, for PulseView: copy {out / PACKAGE} into ~/.local/share/libsigrokdecode/decoders/ "
            f"(or start it as SIGROKDECODE_DIR={out} pulseview) and stack RS30x on a UART decoder")
