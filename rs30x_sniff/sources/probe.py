"""What a capture says about how it was made: its recorded or probed rate, its models, the unit of its times."""

from __future__ import annotations

import itertools
from typing import Any

from ..protocol.wire import DEFAULT_BAUD
from . import foreign
from .base import open_capture
from .captures import MCAP, MCAP_MAGIC, TIMESTAMPED, CaptureError, detect_format, read_capture, regular_file

TIMESTAMP_SAMPLE = 2000  # chunks of a timestamped capture read ahead to tell its baud rate


def capture_layer(path: str | None, fmt: str | None = None, options: dict[str, Any] | None = None) -> dict[str, Any]:
    """What a capture says about how it was made: an MCAP of ours its baud and models, a timestamped
    capture the rate its back-to-back frames show and the unit of its times, another tool's format
    what its ``probe`` finds (a logic capture the rate its samples show; ``options`` are the reader's,
    e.g. the channel, or a timestamped capture's ``time_unit``); {} otherwise (``origin`` says where
    each came from)."""
    if not path or not regular_file(path):  # "-" too, when stdin is a file (decode - < x.mcap)
        return {}
    if fmt is None:
        try:
            with open_capture(path) as f:
                magic = f.read(len(MCAP_MAGIC))
        except (OSError, CaptureError):
            return {}
        if magic == MCAP_MAGIC:
            return _mcap_layer(path)
        try:
            fmt = detect_format(path)
        except CaptureError:
            return {}  # the reading command says why, with the line
    if fmt == MCAP:
        return _mcap_layer(path)
    if fmt == TIMESTAMPED:
        return _timestamps_layer(path, (options or {}).get("time_unit"))
    other = foreign.get(fmt)
    if other is not None and other.probe is not None:
        return _probe_layer(path, other, options or {})
    return {}


def _probe_layer(path: str, other: foreign.ForeignFormat, options: dict[str, Any]) -> dict[str, Any]:
    """What another tool's capture records or shows (its ``probe``), as the capture layer."""
    try:
        found = other.probe(path, options)  # type: ignore[misc]
    except CaptureError:
        return {}  # the reading command says why
    if not found.get("baud"):
        return {}
    note = found.get("baud_note") or f"recorded in the {other.name} capture"
    return {"baud": found["baud"], "origin": {"baud": f"capture ({note})"}, "note": note}


def _mcap_layer(path: str) -> dict[str, Any]:
    from .mcap_reader import McapRawReader  # only MCAP inputs need the mcap library
    from ..protocol.memmap import ModelError, default_registry

    reader = McapRawReader(path, warn=None)
    try:
        meta = reader.read_metadata()
    except Exception:  # noqa: BLE001 - unreadable metadata: the reader says why when the data is read
        return {}
    out: dict[str, Any] = {"origin": {"baud": "capture (the MCAP's metadata)"}}
    if reader.baud:
        out["baud"] = reader.baud
    reg = default_registry()
    try:
        models = {sid: reg.get(name).name for sid, name in reader.models.items() if 1 <= sid <= 127}
        default = meta.get("rs30x", {}).get("default_model")
        if default:
            out["model"] = reg.get(default).name
    except ModelError:
        models = {}  # a model this installation does not know: decode with the others' defaults
    if models:
        out["models"] = models
    # Its times can contradict a --baud as a timestamped capture's can (or the rate it recorded): the
    # same check, on its first messages (issue 32: the same warning and absent figures).
    from ..protocol.baud import estimate_baud, rate_fit

    try:
        chunks = [(d, t) for d, t, _, _ in itertools.islice(McapRawReader(path, warn=None), TIMESTAMP_SAMPLE)
                  if t is not None and d]
    except CaptureError:
        chunks = []  # the reading command says why
    if chunks:
        out.update(estimate=estimate_baud(chunks), fit=rate_fit(chunks), recorded=True)
    return out


def _timestamps_layer(path: str, time_unit: str | None = None) -> dict[str, Any]:
    """The rate a timestamped capture's back-to-back chunks show, the rates its spacing rules out, and
    the unit of its times when the content tells one other than seconds (its first lines are read)."""
    from ..protocol.baud import estimate_baud, estimate_from_spacings, rate_fit

    sample = read_capture(path, TIMESTAMPED, warn=None, options={"time_unit": time_unit, "locate": False})
    try:
        chunks = [(d, t) for d, t in itertools.islice(sample, TIMESTAMP_SAMPLE) if t is not None and d]
    except CaptureError:
        return {}  # a bad line: the reading command reports it where it is
    finally:
        sample.close()
    # Stamped at the first byte, back-to-back chunks are one byte time apart per byte of the earlier
    # chunk; stamped at arrival, per byte of the later one. The reading that fits a rate better wins.
    est = max(estimate_baud(chunks),
              estimate_from_spacings(((t2 - t1) / len(d2), len(d1)) for (d1, t1), (d2, t2) in zip(chunks, chunks[1:])
                                     if t2 > t1),
              key=lambda e: (e.baud is not None, e.score))
    fit = rate_fit(chunks)
    out: dict[str, Any] = {"estimate": est, "fit": fit, "origin": {}}
    unit = sample.time_unit
    if unit is not None and unit.said:
        # Any reading but plain seconds since the capture began (epoch seconds too): read in this unit by
        # every reader of the file from here on, and said once by settings_for. (Every unit, plain seconds
        # included, leads the reason info gives for the times: timebase.TimedSource.)
        out["time_unit"] = unit.unit
        how = unit.how_known()
        evidence = f": {unit.evidence}" if unit.told else ""
        out["origin"]["time_unit"] = f"capture ({unit.describe()}, {how}{evidence})"
        out["unit_note"] = f"{unit.describe()}, {how}"
    if est.baud is not None:
        out["baud"] = est.baud
        out["origin"]["baud"] = f"capture (its timestamps: {est.evidence})"
    elif fit.rules_out(DEFAULT_BAUD) and (rate := fit.slowest()) is not None:
        # No cluster of back-to-back bytes names a rate, but the default would have chunks overlap:
        # the slowest rate the spacing allows is the one close neighbours point to.
        out["baud"] = rate
        out["origin"]["baud"] = (f"capture (its timestamps: {fit.evidence(DEFAULT_BAUD)}; "
                                 f"{rate} bit/s is the slowest rate they allow)")
    return out
