"""Servo states, transactions and lint findings as tables (CSV, or Parquet through pyarrow), streamed."""

from __future__ import annotations

import csv
from datetime import datetime, UTC
from typing import IO, Any
from collections.abc import Callable, Iterable

from ..protocol.chunks import EPOCH_MIN
from ..protocol.events import LongPacket, ReturnPacket, ShortPacket
from ..protocol.memmap import ModelRegistry
from .pipeline import Sink
from ..decode.decoder import Step
from ..decode.pairing import Record
from ..render.records import direction, summary
from ..protocol.wire import byte_time
from .mcap.transactions import transaction_json
from .mcap.servo_states import ServoStates


KINDS = ("states", "transactions", "findings", "packets")
CSV, PARQUET = "csv", "parquet"
TABLE_FORMATS = (CSV, PARQUET)
EXTENSIONS = {".csv": CSV, ".parquet": PARQUET, ".pq": PARQUET}
PARQUET_HINT = "Parquet needs pyarrow: pip install 'rs30x-sniff[parquet]'"

# Column types: what a column holds in Parquet (CSV writes them all as text).
INT, FLOAT, STR, BOOL, STRS, WALL = "int", "float", "str", "bool", "strs", "wall"
Column = tuple[str, str]

# Rows buffered per Parquet row group: a long capture is written as it is read, never held whole.
BATCH_ROWS = 64 * 1024


class MissingPyarrow(ImportError):
    """Parquet was asked for and pyarrow is not installed (the message says how to install it)."""


def require_pyarrow() -> tuple[Any, Any]:
    """(pyarrow, pyarrow.parquet), or :class:`MissingPyarrow` with the one line to show."""
    try:
        import pyarrow
        import pyarrow.parquet
    except ImportError:
        raise MissingPyarrow(PARQUET_HINT) from None
    return pyarrow, pyarrow.parquet


def table_format(path: str, fmt: str | None = None) -> str | None:
    """The table format ``fmt`` names, else ``path``'s extension tells (``-`` is CSV); None if neither."""
    if fmt:
        return fmt
    if path == "-":
        return CSV
    lower = path.lower()
    for ext, kind in EXTENSIONS.items():
        if lower.endswith(ext):
            return kind
    return None


def _iso(t: float) -> str:
    return datetime.fromtimestamp(t, UTC).isoformat(timespec="microseconds")


# ---- writers ---------------------------------------------------------------------------------------
class CsvTable:
    """Rows as CSV: a header, numbers as Python prints them (no rounding), empty for None."""

    def __init__(self, stream: IO[str]) -> None:
        # LF on every platform (files are opened with newline=""): every spreadsheet and dataframe
        # library reads it, and Unix tools see no stray carriage returns.
        self._writer = csv.writer(stream, lineterminator="\n")
        self._stream = stream
        self._convert: list[tuple[int, Callable[[Any], Any]]] = []

    def start(self, columns: list[Column]) -> None:
        self._writer.writerow([name for name, _ in columns])
        conv: dict[str, Callable[[Any], Any]] = {STRS: " ".join, WALL: _iso}
        self._convert = [(i, conv[kind]) for i, (_, kind) in enumerate(columns) if kind in conv]

    def write(self, row: tuple) -> None:
        if self._convert:
            cells = list(row)
            for i, f in self._convert:
                v = cells[i]
                if v is not None:
                    cells[i] = f(v)
            self._writer.writerow(cells)
        else:
            self._writer.writerow(row)

    def close(self) -> None:
        self._stream.flush()


class ParquetTable:
    """Rows as a Parquet file with typed columns, written one row group per :data:`BATCH_ROWS` rows."""

    def __init__(self, path: str, batch_rows: int = BATCH_ROWS) -> None:
        self._pa, self._pq = require_pyarrow()
        self.path = path
        self.batch_rows = batch_rows
        self._rows: list[tuple] = []
        self._writer: Any = None
        self._kinds: list[str] = []
        self._schema: Any = None

    def _type(self, kind: str) -> Any:
        pa = self._pa
        return {INT: pa.int64(), FLOAT: pa.float64(), STR: pa.string(), BOOL: pa.bool_(),
                STRS: pa.list_(pa.string()), WALL: pa.timestamp("us", tz="UTC")}[kind]

    def start(self, columns: list[Column]) -> None:
        pa = self._pa
        self._kinds = [kind for _, kind in columns]
        self._schema = pa.schema([pa.field(name, self._type(kind)) for name, kind in columns])
        self._writer = self._pq.ParquetWriter(self.path, self._schema, compression="zstd")

    def write(self, row: tuple) -> None:
        rows = self._rows
        rows.append(row)
        if len(rows) >= self.batch_rows:
            self._flush()

    def _flush(self) -> None:
        rows = self._rows
        if not rows:
            return
        pa = self._pa
        arrays = []
        for kind, values, field in zip(self._kinds, zip(*rows), self._schema):
            if kind == WALL:
                # Epoch seconds to whole microseconds: pyarrow takes integers for a timestamp column.
                micros = pa.array([None if v is None else round(v * 1e6) for v in values], pa.int64())
                arrays.append(micros.cast(field.type))
            else:
                arrays.append(pa.array(values, field.type))
        self._writer.write_table(pa.Table.from_arrays(arrays, schema=self._schema), row_group_size=len(rows))
        rows.clear()

    def close(self) -> None:
        if self._writer is None:
            return
        try:
            self._flush()
        finally:
            self._writer.close()


def open_table(path: str, fmt: str, stream: IO[str] | None = None) -> CsvTable | ParquetTable:
    """A writer of ``fmt``: CSV to ``stream`` (opened by the caller), Parquet to the file ``path``."""
    if fmt == PARQUET:
        return ParquetTable(path)
    if stream is None:
        raise ValueError("a CSV table needs a text stream")
    return CsvTable(stream)


# ---- sinks -----------------------------------------------------------------------------------------
class TableSink(Sink[Record]):
    """One table of the decoded traffic, a pipeline sink: rows start with ``t`` (seconds), and
    ``wall_time`` (UTC) when the capture's times are epoch times; a subclass gives the rest.

    ``t`` is the capture's time; a capture without timestamps gets each byte's position at the baud
    rate, as the MCAP log times are made, so every row has a time to plot against.
    """

    kind = ""

    def __init__(self, table: CsvTable | ParquetTable, *, baud: int) -> None:
        self.table = table
        self.rows = 0
        self._byte_time = byte_time(baud)
        self._wall: bool | None = None  # settled by the first row's time
        self._closed = False

    def columns(self) -> list[Column]:
        raise NotImplementedError

    def _time(self, t: float | None, offset: int) -> float:
        return t if t is not None else offset * self._byte_time

    def _begin(self, t: float) -> bool:
        wall = self._wall = t >= EPOCH_MIN
        self.table.start([("t", FLOAT), *([("wall_time", WALL)] if wall else []), *self.columns()])
        return wall

    def _row(self, t: float, rest: tuple) -> None:
        wall = self._wall
        if wall is None:
            wall = self._begin(t)
        self.table.write((t, t, *rest) if wall else (t, *rest))
        self.rows += 1

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        if self._wall is None:
            self._begin(0.0)  # no rows: the header (the schema) alone
        self.table.close()


def _register_kind(reg: Any) -> str:
    """The column type of a register's engineering value (as Register.convert makes it)."""
    if reg.enum is not None:
        return STR  # a label; an unknown code is written as its number, as text
    if reg.table is not None:
        return FLOAT
    if reg.scale == 1 and (not reg.offset or type(reg.offset) is int):
        return INT
    return FLOAT


_WIDER = {INT: 0, FLOAT: 1, STR: 2}


def register_columns(registry: ModelRegistry) -> list[Column]:
    """Every named register of every model (the union, by address), with the type that holds them all."""
    kinds: dict[str, str] = {}
    where: dict[str, int] = {}
    for model in registry.models.values():
        for reg in model.registers:
            name = reg.name
            if not name or reg.reserved:
                continue
            kind = _register_kind(reg)
            old = kinds.get(name)
            if old is None or _WIDER[kind] > _WIDER[old]:
                kinds[name] = kind
            where.setdefault(name, reg.address)
    return [(name, kinds[name]) for name in sorted(kinds, key=lambda n: (where[n], n))]


class StatesTable(TableSink):
    """One row per (time, servo) whenever a packet changes a register of that servo: the whole state
    known so far, one column per register (empty until seen), as the MCAP /rs30x/servo/<id>/state
    channel has it (the same packets count: intact requests and returns, a broadcast for every servo
    seen before it)."""

    kind = "states"

    def __init__(self, table: CsvTable | ParquetTable, *, baud: int, registry: ModelRegistry,
                 models: dict[int, str] | None = None) -> None:
        super().__init__(table, baud=baud)
        self.registers = register_columns(registry)
        self._index = {name: i for i, (name, _) in enumerate(self.registers)}
        self._text = {i for i, (_, kind) in enumerate(self.registers) if kind == STR}
        self._servos = ServoStates(models)
        self._states: dict[int, list] = {}  # servo -> value per register column

    def columns(self) -> list[Column]:
        return [("offset", INT), ("id", INT), ("model", STR), *self.registers]

    def batch(self, step: Step) -> None:
        changes = self._servos.changes
        for rec in step:
            changed = changes(rec)
            if changed:
                self._update(rec, changed)

    def _update(self, rec: Record, changed: dict[int, list[tuple[str, Any]]]) -> None:
        states = self._states
        index = self._index
        width = len(self.registers)
        rows = []
        for tid, pairs in changed.items():
            st = states.get(tid)
            if st is None:
                st = states[tid] = [None] * width
            hit = False
            for name, v in pairs:
                i = index.get(name)
                if i is None:
                    continue
                if i in self._text and v is not None and type(v) is not str:
                    v = str(v)
                st[i] = v
                hit = True
            if hit:
                rows.append((tid, st))
        ev = rec.event
        t = self._time(ev.t_start, ev.offset)
        fallback = rec.model.name if rec.model is not None else None
        models = self._servos.models
        for tid, st in rows:
            self._row(t, (ev.offset, tid, models.get(tid) or fallback, *st))


class TransactionsTable(TableSink):
    """One row per request that expects a reply: what it asked, what came back, and how fast."""

    kind = "transactions"

    def __init__(self, table: CsvTable | ParquetTable, *, baud: int) -> None:
        super().__init__(table, baud=baud)
        # One list per (model, read range), shared by its rows: a batch of buffered Parquet rows
        # would otherwise hold a fresh copy of the same names for every request.
        self._names: dict[tuple, list[str] | None] = {}

    def columns(self) -> list[Column]:
        return [("offset", INT), ("id", INT), ("op", STR), ("expects", STR), ("read_address", INT),
                ("read_length", INT), ("read_names", STRS), ("status", STR), ("reply_type", STR),
                ("reply_offset", INT), ("t_reply", FLOAT), ("latency_s", FLOAT), ("reply_checksum_ok", BOOL),
                ("request_raw", STR), ("reply_raw", STR)]

    def batch(self, step: Step) -> None:
        for rec in step:
            if rec.expects is None:
                continue
            tj = transaction_json(rec)
            ev = rec.event
            rr = rec.read_range  # the servo's model's reading of its flag (return modes beyond table 4.3)
            key = (rec.model.name if rec.model is not None else None, rr)
            names = self._names.get(key)
            if names is None:
                names = self._names[key] = tj["read"] or None
            t_reply = tj["t_reply"]
            if t_reply is None and tj["reply_offset"] is not None:
                t_reply = self._time(None, tj["reply_offset"])
            self._row(self._time(ev.t_start, ev.offset), (
                ev.offset, tj["id"], tj["op"], tj["expects"], rr[0] if rr else None, rr[1] if rr else None,
                names, tj["status"], tj["reply_type"], tj["reply_offset"], t_reply, tj["latency_s"],
                tj["reply_checksum_ok"], tj["request_raw"], tj["reply_raw"]))


class FindingsTable(TableSink):
    """One row per lint finding; ``line`` and ``column`` of a text capture when ``locate`` is given
    (the capture reader's: it maps a stream offset to where the byte is written)."""

    kind = "findings"

    def __init__(self, table: CsvTable | ParquetTable, *, baud: int,
                 locate: Callable[[int], tuple[int, int] | None] | None = None) -> None:
        super().__init__(table, baud=baud)
        self.locate = locate

    def columns(self) -> list[Column]:
        where = [("line", INT), ("column", INT)] if self.locate is not None else []
        return [("offset", INT), *where, ("code", STR), ("name", STR), ("severity", STR), ("id", INT),
                ("message", STR)]

    def batch(self, step: Step) -> None:
        if step.findings:
            self.add(step.findings)

    def add(self, findings: Iterable[Any]) -> None:
        locate = self.locate
        for f in findings:
            tail = (f.code, f.name, f.severity, f.id, f.message)
            if locate is not None:
                loc = locate(f.offset) or (None, None)
                rest = (f.offset, *loc, *tail)
            else:
                rest = (f.offset, *tail)
            self._row(self._time(f.t, f.offset), rest)


class PacketsTable(TableSink):
    """One row per event (every packet, ACK/NACK and garbage run), as `decode` lists them."""

    kind = "packets"

    def columns(self) -> list[Column]:
        return [("offset", INT), ("type", STR), ("direction", STR), ("id", INT), ("op", STR), ("flag", INT),
                ("address", INT), ("length", INT), ("count", INT), ("checksum_ok", BOOL), ("status", STR),
                ("reply_to", INT), ("latency_s", FLOAT), ("summary", STR), ("findings", STRS), ("raw", STR)]

    def batch(self, step: Step) -> None:
        for rec in step:
            ev = rec.event
            t = type(ev)
            header = (ev.id, ev.flag if t is not ReturnPacket else ev.flags, ev.address, ev.length, ev.count) \
                if t is ShortPacket or t is LongPacket or t is ReturnPacket else (rec.id, None, None, None, None)
            self._row(self._time(ev.t_start, ev.offset), (
                ev.offset, ev.kind, direction(rec), header[0], rec.op if t is ShortPacket else
                ("write" if t is LongPacket else None), *header[1:], ev.checksum_ok, rec.status,
                rec.request.offset if rec.request is not None else None, rec.latency,
                summary(rec, bare=False, keep=False), [f.code for f in rec.findings] or None, ev.raw.hex()))


SINKS = {"states": StatesTable, "transactions": TransactionsTable, "findings": FindingsTable, "packets": PacketsTable}
