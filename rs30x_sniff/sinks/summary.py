"""What the figures say as JSON-ready data: each servo's health, capture and wall times, and "what happened"."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime, UTC
from typing import Any

from ..protocol.chunks import EPOCH_MIN
from ..render.times import ABSOLUTE
from .figures import FIGURES
from .health import FLAG_NAMES, PRESENT, WRITTEN, HealthRecorder, ServoHealth

# The figures the summary tells in lines of its own (the status flags, missing replies, damaged bytes): the
# findings of their rules (the figure table's ``rules``) are not told again as rule lines. Q009 (torque switched
# back on after the temperature limit) is told in the limit's line.
TOLD_FIGURES = (*FLAG_NAMES, "missing_replies", "bad_checksums", "garbage_bytes")
SWITCHED_BACK_ON = "Q009"
TOLD = frozenset({code for name in TOLD_FIGURES for code in FIGURES[name].rules} | {SWITCHED_BACK_ON})
_MAX_LINES = 8
_SEV_RANK = {"error": 0, "warning": 1, "info": 2}


def servo_health(h: ServoHealth | None, when: Any) -> dict[str, Any]:
    """One servo's health as JSON-ready data; ``when(t, offset)`` gives (t, wall)."""
    regs: dict[str, Any] = {}
    m = h.model if h is not None else None
    if h is not None:
        for name in (*PRESENT, *WRITTEN):
            if name not in h.lo:
                continue
            reg = (m or _any_model()).register(name)
            a, b = reg.convert(h.lo[name]), reg.convert(h.hi[name])
            regs[name] = {"min": min(a, b), "max": max(a, b), "unit": reg.unit, "count": h.samples[name]}
    flags = {}
    if h is not None:
        for name in FLAG_NAMES:
            seen = h.flags.get(name)
            if seen is not None:
                t, wall = when(seen[1], seen[2])
                flags[name] = {"count": seen[0], "first_t": t, "first_wall": wall}
    return {"model": None if m is None else m.name, "registers": regs, "flags": flags,
            "findings": dict(sorted(h.findings.items())) if h is not None else {}}


def _recovery(name: str | None) -> str:
    """What brings a servo of this model back from a temperature stop (its map's [behaviour])."""
    from ..protocol.memmap import ModelError, behaviour_of, default_registry
    try:
        model = default_registry().get(name) if name else None
    except ModelError:  # a model no map names now (a recording read with other maps)
        model = None
    return behaviour_of(model).recovery


def _any_model() -> Any:
    from ..protocol.memmap import default_registry
    return default_registry().default


def timer(first_t: float | None, timed: bool, byte_s: float, anchor: float | None = None):
    """``when(t, offset)`` -> (capture time, ISO wall clock or None): the times ``lint`` and ``decode``
    print, and the wall clock where the capture has one (epoch times, or ``anchor``: the epoch time of
    capture time 0); an untimed capture is measured in line time, as its duration is."""
    epoch = anchor if anchor is not None else (0.0 if timed and first_t is not None and first_t > EPOCH_MIN else None)

    def when(t: float | None, offset: int) -> tuple[float | None, str | None]:
        if timed and t is not None and first_t is not None:
            wall = None
            if epoch is not None:
                try:
                    wall = (datetime.fromtimestamp(epoch + t, tz=UTC).isoformat(timespec="milliseconds")
                            .replace("+00:00", "Z"))
                except (OverflowError, OSError, ValueError):
                    wall = None  # no calendar date: the capture time alone
            return round(t, 6), wall
        if not timed:
            return round(offset * byte_s, 6), None
        return None, None
    return when


def seconds_text(t: float, form: Any = None) -> str:
    """A time in a summary's text: ``12.34 s`` of capture time, or as ``form`` shows it (render.times.TimeForm,
    --time-format: since the start, the date and time of day, epoch seconds)."""
    if form is None or not form.started:
        return f"{t:.2f} s"
    return form.seconds(t)


def _at(t: float | None, wall: str | None, form: Any = None) -> str:
    if t is None:
        return ""
    if form is not None and form.started and form.shown == ABSOLUTE:
        return f" at {form.seconds(t)}"  # the wall clock itself: no second form beside it
    return f" at {seconds_text(t, form)}" + (f" [{wall.replace('T', ' ').replace('Z', ' UTC')}]" if wall else "")


def _times(n: int) -> str:
    return {1: "once", 2: "twice"}.get(n, f"{n} times")


def _ids(ids: list[int]) -> str:
    return ", ".join(map(str, ids[:6])) + (", ..." if len(ids) > 6 else "")


def _plural(n: int, word: str) -> str:
    return f"{n} {word}" + ("" if n == 1 else "s")


When = Callable[[float | None, int], tuple[float | None, str | None]]


@dataclass
class _Lines:
    """The summary's lines as they are said, and how their texts show a time (``form``: render.times.TimeForm)."""

    form: Any = None
    items: list[dict[str, Any]] = field(default_factory=list)

    def at(self, t: float | None, wall: str | None) -> str:
        return _at(t, wall, self.form)

    def say(self, sev: str, sid: int | None, text: str, tw: tuple = (None, None)) -> None:
        self.items.append({"severity": sev, "id": sid, "text": text, "t": tw[0], "wall": tw[1]})


def what_happened(stats: Any, health: dict[str, dict], when: When, form: Any = None) -> list[dict[str, Any]]:
    """A handful of plain-language lines, most severe first: what a capture says went wrong; ``form``
    (render.times.TimeForm, started) says how their texts show times, by default as capture seconds."""
    lines = _Lines(form)
    refused = _status_lines(lines, health)
    _refused_line(lines, refused)
    _missing_lines(lines, stats.servos, when)
    _damage_lines(lines, stats, when)
    _finding_lines(lines, stats.health, when)
    lines.items.sort(key=lambda it: _SEV_RANK[it["severity"]])  # stable: the order above ranks within a severity
    _trim(lines, stats)
    _load_line(lines, stats, when)
    return lines.items


def _status_lines(lines: _Lines, health: dict[str, dict]) -> list[tuple[int, dict]]:
    """Status flags the servos themselves reported (table 4.4): the hardware's own word on what happened. Gives
    the received-packet-error flags, told in one line for every servo (:func:`_refused_line`)."""
    refused: list[tuple[int, dict]] = []
    for sid in sorted(health, key=int):
        flags = health[sid]["flags"]
        _temperature_line(lines, int(sid), health[sid])
        fe = flags.get("flash_write_error")
        if fe:
            lines.say("error", int(sid), f"ID {sid} reported a failed flash ROM write"
                      f"{lines.at(fe['first_t'], fe['first_wall'])}", (fe["first_t"], fe["first_wall"]))
        re_ = flags.get("received_packet_error")
        if re_:
            refused.append((int(sid), re_))
    return refused


def _temperature_line(lines: _Lines, sid: int, hv: dict) -> None:
    """A servo at its temperature limit (torque cut, or switched back on: Q009), or at its alarm."""
    flags, regs, found = hv["flags"], hv["registers"], hv["findings"]
    peak = regs.get("present_temperature")
    peak_s = f"peak {peak['max']:g} {peak['unit'] or ''}".rstrip() if peak else ""
    lim = flags.get("temperature_limit")
    if lim:
        al = flags.get("temperature_alarm")
        alarm = f"alarm from {seconds_text(al['first_t'], lines.form)}" if al and al["first_t"] is not None else ""
        why = ", ".join(x for x in (alarm, peak_s) if x)
        text = f"ID {sid} reached its temperature limit{lines.at(lim['first_t'], lim['first_wall'])}" + \
            (f" ({why})" if why else "")
        q = found.get(SWITCHED_BACK_ON, 0)
        text += (f" and was switched back on {_times(q)} ({SWITCHED_BACK_ON})" if q
                 else f" and cut its torque ({_recovery(hv['model'])})")
        lines.say("error", sid, text, (lim["first_t"], lim["first_wall"]))
    elif "temperature_alarm" in flags:
        al = flags["temperature_alarm"]
        lines.say("warning", sid, f"ID {sid} came within 10 degC of its temperature limit"
                  f"{lines.at(al['first_t'], al['first_wall'])}" + (f" ({peak_s})" if peak_s else ""),
                  (al["first_t"], al["first_wall"]))


def _refused_line(lines: _Lines, refused: list[tuple[int, dict]]) -> None:
    """Packets the servos could not accept: one line, however many servos said so (one bad host, usually)."""
    if not refused:
        return
    n = sum(v["count"] for _, v in refused)
    first = min((v for _, v in refused), key=lambda v: (v["first_t"] is None, v["first_t"] or 0))
    ids = [sid for sid, _ in refused]
    who = f"ID {ids[0]}" if len(ids) == 1 else "IDs " + _ids(ids)
    lines.say("warning", ids[0] if len(ids) == 1 else None,
              f"{who} flagged {_plural(n, 'packet')} {'it' if len(ids) == 1 else 'they'} could not accept "
              f"(status bit 1), first"
              f"{lines.at(first['first_t'], first['first_wall'])}", (first["first_t"], first["first_wall"]))


def _missing_lines(lines: _Lines, servos: dict, when: When) -> None:
    """Replies that never came."""
    for sid, st in sorted(servos.items()):
        if not st.missing:
            continue
        tw = when(*st.first_missing) if st.first_missing else (None, None)
        if st.returns + st.acks + st.nacks == 0:
            lines.say("error", sid, f"ID {sid} never answered: {_plural(st.missing, 'request')} missing", tw)
        else:
            asked = st.missing + st.answered  # requests that asked for a reply, not the replies heard
            lines.say("error", sid, f"ID {sid} left {st.missing} of {asked} requests unanswered, first{lines.at(*tw)}",
                      tw)


def _damage_lines(lines: _Lines, stats: Any, when: When) -> None:
    """Damaged traffic: packets with a bad checksum (by kind, with the IDs they claim), bytes of no frame."""
    if stats.bad_checksums:
        by_kind: dict[str, list] = {}
        for (kind, sid), n in stats.bad_by.items():
            k = by_kind.setdefault(kind, [0, set()])
            k[0] += n
            if sid is not None:
                k[1].add(sid)
        words = {"return": ("return", " from "), "short": ("request", " to "), "long": ("long packet", "")}
        parts = []
        for kind, (n, ids) in sorted(by_kind.items(), key=lambda kv: -kv[1][0]):
            word, prep = words.get(kind, (kind, ""))
            parts.append(_plural(n, word) + (f"{prep}ID{'s' if len(ids) > 1 else ''} {_ids(sorted(ids))}"
                                            if prep and ids else ""))
        sole = by_kind.get("return", [0, set()])[1]
        sid = next(iter(sole)) if len(by_kind) == 1 and len(sole) == 1 else None
        lines.say("error", sid, "; ".join(parts) + " with a bad checksum", when(*stats.first_bad))
    if stats.garbage_bytes:
        lines.say("warning", None, f"{_plural(stats.garbage_bytes, 'byte')} of garbage (no intact frame)",
                  when(*stats.first_garbage))


def _finding_lines(lines: _Lines, rec: HealthRecorder, when: When) -> None:
    """What the linter found that the lines above do not already tell (TOLD), most severe and frequent first."""
    for code, (n, t, off, sev, name, ids) in sorted(rec.codes.items(), key=lambda kv: (_SEV_RANK.get(kv[1][3], 3),
                                                                                       -kv[1][0])):
        if code in TOLD or sev == "info":
            continue
        who = ""
        if ids:
            who = (" from ID " if len(ids) == 1 else " from IDs ") + _ids(sorted(ids))
        tw = when(t, off)
        sole = next(iter(ids)) if len(ids) == 1 else None
        lines.say(sev, sole, f"{code} {name}: {_times(n)}{who}, first{lines.at(*tw)}", tw)


def _trim(lines: _Lines, stats: Any) -> None:
    """At most _MAX_LINES lines (the last one says how many more); none at all says so, empty or clean."""
    items = lines.items
    if len(items) > _MAX_LINES:
        rest = items[_MAX_LINES - 1:]
        del items[_MAX_LINES - 1:]
        lines.say(rest[0]["severity"], None, f"and {len(rest)} more: see the findings and the health table")
    if not items and not stats.bytes:
        lines.say("warning", None, "nothing to tell: the capture holds no data")  # empty is no clean bill of health
    elif not items:
        servos = stats.servos
        answered = sum(st.returns + st.acks + st.nacks for st in servos.values())
        lines.say("info", None, f"nothing wrong seen: {_plural(len(servos), 'servo')}, {answered} replies, none "
                  "missing, no status flags, no damaged packets")


def _load_line(lines: _Lines, stats: Any, when: When) -> None:
    """The bus load, last: a figure to know whether or not anything went wrong (a warning near a full bus)."""
    peak = stats.load_peak
    if peak is None:
        return
    load, start = peak
    tw = when(start, 0)
    assert tw[0] is not None  # a peak needs times: its start has a capture time
    sev = "warning" if load >= 0.95 else "info"
    line = {"severity": sev, "id": None, "t": tw[0], "wall": tw[1],
            "text": f"the bus load peaked at {load * 100:.0f} % in the second from "
                    f"{seconds_text(tw[0], lines.form)}, "
                    f"{(stats.bus_load or 0) * 100:.0f} % on average"
                    + ("; little room for more traffic" if sev == "warning" else "")}
    items = lines.items
    if sev == "warning":
        k = next((i for i, it in enumerate(items) if it["severity"] == "info"), len(items))
        items.insert(k, line)
    else:
        items.append(line)
