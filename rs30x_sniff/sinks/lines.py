"""Small sinks of the drive loop: decode's text and JSON lines, lint's findings, a progress bar."""

from __future__ import annotations

import json
from typing import IO, Any
from collections.abc import Callable, Iterable

from ..render.block_json import block_json_lines, block_json_pieces, record_json_line
from ..render.block_text import block_text, record_line
from ..render.columns import Columns
from ..decode.blocks import Block
from ..decode.pairing import Record
from ..decode.frame_runs import LONG
from ..filters import Filter
from ..protocol.wire import AT_DATA, AT_ID, AT_LENGTH, SUM_SIZE
from .pipeline import Sink
from ..decode.decoder import Step
from ..render.records import text_line, verbose_lines
from ..render.times import LineClock, TimeForm, time_text


def block_rows_involving(blk: Block, ids: set[int]) -> list[int]:
    """The rows of a Block that ``involves`` keeps."""
    run = blk.run
    blob = run.blob
    out = []
    for k, (s, e, kind) in enumerate(zip(run.starts[blk.lo:blk.hi].tolist(), run.ends[blk.lo:blk.hi].tolist(),
                                         blk.cols["kind"].tolist())):
        if kind == LONG:  # each record's VID, every Length bytes of the data
            step = blob[s + AT_LENGTH]
            if step and not ids.isdisjoint(blob[s + AT_DATA:e - SUM_SIZE:step]):
                out.append(k)
        elif blob[s + AT_ID] in ids:
            out.append(k)
    return out


def involves(rec: Record, ids: set[int]) -> bool:
    """Whether a record is to or from one of ``ids`` (a long packet: any of its VIDs)."""
    ev = rec.event
    if ev.kind == "long":
        return any(r.vid in ids for r in ev.records)
    return rec.id in ids


class _LineSink(Sink[Record | Block]):
    """One line per record (and one per finding only the end of input reveals), optionally one servo's."""

    def __init__(self, out: IO[str], *, ids: set[int] | None = None, flush: bool = False,
                 filter: Filter | None = None) -> None:
        self.out = out
        self.ids = ids
        self.filter = filter  # decode --filter: the monitor's filter language
        self.flush = flush  # a person or a pipe watches a live bus: show each batch as it comes
        self.records = 0

    takes_blocks = True

    def batch(self, step: Step) -> None:
        ids = self.ids
        flt = self.filter
        write = self.out.write
        line = self.line
        if step.blocks and flt is not None:
            step = step.expanded()  # the filter language reads records
        # Findings between records (F010 at a seam: a clock restart, a lost port) go before the first record at
        # or past their place, as lint names them there.
        loose = [f for f in step.loose() if (ids is None or f.id is None or f.id in ids)
                 and (flt is None or flt.matches_finding(f))] if step.findings else ()
        for rec in step:
            if loose:
                first = int(rec.offsets[0]) if type(rec) is Block else rec.event.offset
                while loose and loose[0].offset <= first:
                    write(self.finding_line(loose.pop(0)))
            if type(rec) is Block:
                rows = None if ids is None else block_rows_involving(rec, ids)
                wrote = False
                for text in self.block_pieces(rec, rows):  # a long Block's text in pieces, never whole
                    if text:
                        write(text)
                        wrote = True
                if wrote:
                    self.records += len(rec) if rows is None else len(rows)
                continue
            if (ids is None or involves(rec, ids)) and (flt is None or flt.matches(rec)):
                write(line(rec))
                self.records += 1
            else:
                self.passed(rec)
        for f in loose:  # past every record of the step
            write(self.finding_line(f))
        # Findings only the end of input reveals belong to records already written: they come last,
        # each naming its record's offset. The filter judges them by what it can (id, sev, t, text).
        for f in step.late:
            if (ids is None or f.id in ids) and (flt is None or flt.matches_finding(f)):
                write(self.finding_line(f))
        if self.flush:
            self.out.flush()

    def line(self, rec: Record) -> str:
        raise NotImplementedError

    def passed(self, rec: Record) -> None:
        """A record not written (``ids``, ``filter``): what follows may depend on it (a delta's previous event)."""

    def block_lines(self, blk: Block, rows: list[int] | None) -> str:
        """The lines of a Block's rows (``rows``: those alone), as ``line`` would write their records."""
        recs = blk.records()
        return "".join([self.line(recs[k]) for k in (range(len(recs)) if rows is None else rows)])

    def block_pieces(self, blk: Block, rows: list[int] | None) -> Iterable[str]:
        """``block_lines`` in pieces to write one after the other (one piece unless a sink cuts it)."""
        return (self.block_lines(blk, rows),)

    def finding_line(self, f: Any) -> str:
        raise NotImplementedError


class TextSink(_LineSink):
    """``decode``'s text: one line per event with its findings, ``verbose`` adds the field tree; ``times``
    says how times are shown (--time-format; default: seconds since the capture's start)."""

    def __init__(self, out: IO[str], *, verbose: bool = False, times: TimeForm | None = None, **kw: Any) -> None:
        super().__init__(out, **kw)
        self.verbose = verbose
        self.clock = LineClock(times or TimeForm())

    def line(self, rec: Record) -> str:
        at = self.clock.record(rec.event.t_start)
        if self.verbose:
            return text_line(rec, self.ids, at) + "\n" + "\n".join(verbose_lines(rec)) + "\n"
        return record_line(rec, self.ids, at)

    def passed(self, rec: Record) -> None:
        self.clock.record(rec.event.t_start)

    def block_lines(self, blk: Block, rows: list[int] | None) -> str:
        return block_text(blk, self.ids, self.verbose, rows, self.clock.block(blk.t0))

    def finding_line(self, f: Any) -> str:
        return f"{time_text(self.clock.finding(f.t))} @{f.offset:<8} lint  {f.code} {f.name}: {f.message}\n"


class JsonlSink(_LineSink):
    """``decode --format jsonl``: one JSON object per event, end-of-input findings as diagnostics."""

    def line(self, rec: Record) -> str:
        return record_json_line(rec, self.ids) + "\n"

    def block_lines(self, blk: Block, rows: list[int] | None) -> str:
        return block_json_lines(blk, self.ids, rows=rows)

    def block_pieces(self, blk: Block, rows: list[int] | None) -> Iterable[str]:
        return block_json_pieces(blk, self.ids, rows)

    def finding_line(self, f: Any) -> str:
        return json.dumps({"type": "diagnostic", **f.as_json()}) + "\n"


class FieldsSink(_LineSink):
    """``decode --format fields``: the chosen columns of each event, tab-separated under a heading line; a
    finding only the end of input reveals is a line of its own (its record's offset, the code)."""

    def __init__(self, out: IO[str], columns: Columns, **kw: Any) -> None:
        super().__init__(out, **kw)
        self.columns = columns
        out.write(columns.heading())

    def line(self, rec: Record) -> str:
        return self.columns.line(rec, self.ids)

    def finding_line(self, f: Any) -> str:
        return f"# {f.code} {f.name} @{f.offset}: {f.message}\n"


class FindingsSink(Sink[Record | Block]):
    """Every lint finding and the record count: what a lint report needs of one capture."""

    takes_blocks = True  # counts a Block's rows; reads nothing else of them

    def __init__(self) -> None:
        self.findings: list = []
        self.records = 0

    def batch(self, step: Step) -> None:
        self.records += step.count
        if step.findings:
            self.findings += step.findings


class ProgressSink(Sink[Record | Block]):
    """Advances a progress bar by the bytes read."""

    takes_blocks = True

    def __init__(self, advance: Callable[[int], None]) -> None:
        self.advance = advance

    def chunk(self, data: bytes, t: float | None, sender: str | None = None, error: str | None = None) -> None:
        self.advance(len(data))
