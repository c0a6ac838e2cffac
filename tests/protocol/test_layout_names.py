"""Events are read by field name and frames by layout name: no module but wire.py and events.py uses a literal.

Parsed with ``ast``, every module of rs30x_sniff is checked for
(a) an event indexed with a literal field position: ``ev[9]``, ``event[5]``, ``rec.event[4]``, ``pe[3]``
    (use OFFSET, RAW, T_START, ..., REASON of rs30x_sniff.protocol.events, or the attribute);
(b) a frame's bytes indexed at a header position or sliced at the header's size: ``raw[2]``, ``raw[7:-1]``,
    ``ev.raw[:7]``, ``ev[RAW][2:-1]`` (use AT_ID ... AT_DATA, HEADER_SIZE, SUM_SIZE of rs30x_sniff.protocol.wire);
(c) a frame's first byte compared with a literal header byte: ``raw[0] == 0xFD`` (REQUEST_FIRST, RETURN_FIRST).

What is an event or a frame is known by the names the code gives them (EVENT_NAMES, FRAME_NAMES, the
``.event`` and ``.raw`` attributes, an event's RAW field), and by a name assigned one of those in the same
function (``pe = prev.event``, ``asked = req.event[RAW] if req else b""``, ``h = raw[:HEADER_SIZE]``). Other
tuples (chunks ``(data, t)``, rows, a long packet's ``LongRecord``, numpy columns) are not events and may be
indexed as they like. A frame's first byte ``raw[0]``, its second ``raw[1]`` and its Sum ``raw[-1]`` are
positions every reader knows; the test leaves them alone.
"""

from __future__ import annotations

import ast
from pathlib import Path

import rs30x_sniff
from rs30x_sniff.protocol import wire

PACKAGE = Path(rs30x_sniff.__file__).parent

# The two modules that define the names: the layout is written out there, once.
DEFINING = {"protocol/wire.py", "protocol/events.py"}

# Names the code gives an event (a frame decoder's output: ShortPacket, ..., Garbage).
EVENT_NAMES = {"ev", "event", "pe", "request", "reply"}
# Names the code gives a whole frame's bytes (an event's raw field).
FRAME_NAMES = {"raw", "frame"}

# Header positions a literal must not stand for: ID, flag, address, length, count, the first data byte.
HEADER_POSITIONS = set(range(wire.AT_ID, wire.AT_DATA + 1))
# Slice bounds that cut a frame at its header: after the sync bytes (ID on), after the header (data on).
HEADER_BOUNDS = {wire.AT_ID, wire.HEADER_SIZE}
# Header bytes a frame's first byte must not be compared with as literals.
HEADER_BYTES = {wire.REQUEST_FIRST, wire.RETURN_FIRST}
RAW_FIELD = 1  # events.RAW: the one literal position whose read makes a frame (checked as an event read too)


def _int(node: ast.AST | None) -> int | None:
    """The value of an integer literal (``-1`` included), else None."""
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        v = _int(node.operand)
        return None if v is None else -v
    if isinstance(node, ast.Constant) and type(node.value) is int:
        return node.value
    return None


class _Scope:
    """What one function (or a module's top level) calls events and frames."""

    def __init__(self, body: ast.AST) -> None:
        self.events = set(EVENT_NAMES)
        self.frames = set(FRAME_NAMES)
        assigns = [n for n in ast.walk(body) if isinstance(n, ast.Assign) and len(n.targets) == 1
                   and isinstance(n.targets[0], ast.Name)]
        for _ in range(3):  # a name assigned from a name assigned from an event: a short chain
            for a in assigns:
                name = a.targets[0].id
                if self.is_event(a.value):
                    self.events.add(name)
                elif self.is_frame(a.value) or self.is_header(a.value):
                    self.frames.add(name)

    def is_event(self, e: ast.AST) -> bool:
        if isinstance(e, ast.Name):
            return e.id in self.events
        if isinstance(e, ast.Attribute):
            return e.attr == "event"
        return False

    def is_frame(self, e: ast.AST) -> bool:
        if isinstance(e, ast.Name):
            return e.id in self.frames
        if isinstance(e, ast.Attribute):
            return e.attr == "raw"
        if isinstance(e, ast.Subscript) and self.is_event(e.value):  # ev[RAW], ev[1]
            s = e.slice
            return (isinstance(s, ast.Name) and s.id == "RAW") or _int(s) == RAW_FIELD
        if isinstance(e, ast.IfExp):  # raw = ev[RAW] if ev is not None else b""
            return self.is_frame(e.body) or self.is_frame(e.orelse)
        return False

    def is_header(self, e: ast.AST) -> bool:
        """A frame's bytes from its start on (``raw[:HEADER_SIZE]``): its positions are the frame's."""
        return (isinstance(e, ast.Subscript) and isinstance(e.slice, ast.Slice) and self.is_frame(e.value)
                and _int(e.slice.lower) in (None, 0) and e.slice.step is None)


def _offences(tree: ast.Module) -> list[tuple[int, str]]:
    scopes = [tree] + [n for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef,
                                                                        ast.Lambda))]
    found: dict[tuple[int, int], tuple[int, str]] = {}
    for body in scopes:
        scope = _Scope(body)
        for node in ast.walk(body):
            why = None
            if isinstance(node, ast.Subscript):
                s = node.slice
                if scope.is_event(node.value) and _int(s) is not None:
                    why = "an event's field by a literal position"
                elif scope.is_frame(node.value) or scope.is_header(node.value):
                    if _int(s) in HEADER_POSITIONS:
                        why = "a frame's header byte by a literal position"
                    elif isinstance(s, ast.Slice) and (_int(s.lower) in HEADER_BOUNDS or _int(s.upper) in HEADER_BOUNDS):
                        why = "a frame sliced at a literal header size"
            elif isinstance(node, ast.Compare) and len(node.comparators) == 1:
                sides = (node.left, node.comparators[0])
                first = [x for x in sides if isinstance(x, ast.Subscript) and _int(x.slice) == 0
                         and (scope.is_frame(x.value) or scope.is_header(x.value))]
                if first and any(_int(x) in HEADER_BYTES for x in sides):
                    why = "a frame's first byte compared with a literal header byte"
            if why:
                found.setdefault((node.lineno, node.col_offset), (node.lineno, f"{why}: {ast.unparse(node)}"))
    return sorted(found.values())


def _checked_modules():
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).as_posix()
        if rel in DEFINING:
            continue
        yield rel, path


def test_no_module_reads_events_or_frames_by_literal_positions():
    offenders = [f"{rel}:{line}: {what}" for rel, path in _checked_modules()
                 for line, what in _offences(ast.parse(path.read_text(), str(path)))]
    assert not offenders, ("read events by the field names of protocol/events.py and frames by the layout names "
                           "of protocol/wire.py:\n" + "\n".join(offenders))


def _caught(src: str) -> list[str]:
    return [what for _, what in _offences(ast.parse(src))]


def test_the_check_catches_literal_positions():
    for src in ("t = ev[9]", "x = event[5]", "c = rec.event[4]", "d = raw[7:-1]", "i = raw[2]",
                "s = ev.raw[2:-1]", "h = ev[1][:7]", "k = ev[RAW][7]", "r = prev.event[3]",
                "def f(prev):\n    pe = prev.event\n    return pe[4]",
                "def f(rec):\n    asked = rec.request.event[RAW] if rec.request else b''\n    return asked[:7]",
                "def f(ev):\n    h = ev.raw[:HEADER_SIZE]\n    return h[5]",
                "ok = raw[0] == 0xFD", "ok = 0xFA == ev.raw[0]"):
        assert _caught(src), src


def test_the_check_leaves_named_reads_and_other_tuples_alone():
    for src in ("t = ev[T_START]", "d = raw[AT_DATA:-SUM_SIZE]", "i = raw[AT_ID]", "s = ev.raw[-1]",
                "first = raw[0]", "ok = raw[0] == RETURN_FIRST", "n = len(chunk[0])", "t = chunk[1]",
                "name = row[2]", "vid = r[0]", "line, col = loc[0], loc[1]", "v = self.mem[4]",
                "vids = tuple(r[0] for r in ev.records)", "entry = flashed[sid]; ready = entry[0]",
                "lo = a[at + 7]", "x = data[7:]", "k = ev[RAW][AT_DATA]", "head = raw_lines[:7]", "b = ev.data[:2]"):
        assert not _caught(src), src
