"""What the figures say as JSON-ready data: each servo's health, capture and wall times, and "what happened"."""

from __future__ import annotations

from datetime import datetime, UTC
from typing import Any

from ..protocol.chunks import EPOCH_MIN
from ..render.times import ABSOLUTE
from .health import FLAG_NAMES, PRESENT, WRITTEN, HealthRecorder, ServoHealth

# The findings the summary tells through the figures (flags, missing replies, bad bytes), not as rule lines.
_TOLD = frozenset({"S001", "S002", "S003", "S004", "Q009", "B002", "F001", "F002"})
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


def what_happened(stats: Any, health: dict[str, dict], when: Any, form: Any = None) -> list[dict[str, Any]]:
    """A handful of plain-language lines, most severe first: what a capture says went wrong; ``form``
    (render.times.TimeForm, started) says how their texts show times, by default as capture seconds."""
    items: list[dict[str, Any]] = []

    def at(t: float | None, wall: str | None) -> str:
        return _at(t, wall, form)

    def say(sev: str, sid: int | None, text: str, tw: tuple = (None, None)) -> None:
        items.append({"severity": sev, "id": sid, "text": text, "t": tw[0], "wall": tw[1]})

    rec: HealthRecorder = stats.health
    servos = stats.servos
    refused: list[tuple[int, dict]] = []
    # Status flags the servos themselves reported (table 4.4): the hardware's own word on what happened.
    for sid in sorted(health, key=int):
        hv = health[sid]
        flags, regs, found = hv["flags"], hv["registers"], hv["findings"]
        peak = regs.get("present_temperature")
        peak_s = f"peak {peak['max']:g} {peak['unit'] or ''}".rstrip() if peak else ""
        lim = flags.get("temperature_limit")
        if lim:
            al = flags.get("temperature_alarm")
            alarm = f"alarm from {seconds_text(al['first_t'], form)}" if al and al["first_t"] is not None else ""
            why = ", ".join(x for x in (alarm, peak_s) if x)
            text = f"ID {sid} reached its temperature limit{at(lim['first_t'], lim['first_wall'])}" + \
                (f" ({why})" if why else "")
            q = found.get("Q009", 0)
            text += (f" and was switched back on {_times(q)} (Q009)" if q else " and cut its torque")
            say("error", int(sid), text, (lim["first_t"], lim["first_wall"]))
        elif "temperature_alarm" in flags:
            al = flags["temperature_alarm"]
            say("warning", int(sid), f"ID {sid} came within 10 degC of its temperature limit"
                f"{at(al['first_t'], al['first_wall'])}" + (f" ({peak_s})" if peak_s else ""),
                (al["first_t"], al["first_wall"]))
        fe = flags.get("flash_write_error")
        if fe:
            say("error", int(sid), f"ID {sid} reported a failed flash ROM write{at(fe['first_t'], fe['first_wall'])}",
                (fe["first_t"], fe["first_wall"]))
        re_ = flags.get("received_packet_error")
        if re_:
            refused.append((int(sid), re_))
    # Packets the servos could not accept: one line, however many servos said so (one bad host, usually).
    if refused:
        n = sum(v["count"] for _, v in refused)
        first = min((v for _, v in refused), key=lambda v: (v["first_t"] is None, v["first_t"] or 0))
        ids = [sid for sid, _ in refused]
        who = f"ID {ids[0]}" if len(ids) == 1 else "IDs " + _ids(ids)
        say("warning", ids[0] if len(ids) == 1 else None,
            f"{who} flagged {_plural(n, 'packet')} {'it' if len(ids) == 1 else 'they'} could not accept "
            f"(status bit 1), first"
            f"{at(first['first_t'], first['first_wall'])}", (first["first_t"], first["first_wall"]))
    # Replies that never came.
    for sid, st in sorted(servos.items()):
        if not st.missing:
            continue
        tw = when(*st.first_missing) if st.first_missing else (None, None)
        if st.returns + st.acks + st.nacks == 0:
            say("error", sid, f"ID {sid} never answered: {_plural(st.missing, 'request')} missing", tw)
        else:
            asked = st.missing + st.answered  # requests that asked for a reply, not the replies heard
            say("error", sid, f"ID {sid} left {st.missing} of {asked} requests unanswered, first{at(*tw)}", tw)
    # Damaged traffic.
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
        say("error", sid, "; ".join(parts) + " with a bad checksum", when(*stats.first_bad))
    if stats.garbage_bytes:
        say("warning", None, f"{_plural(stats.garbage_bytes, 'byte')} of garbage (no intact frame)",
            when(*stats.first_garbage))
    # What the linter found that the lines above do not already tell.
    for code, (n, t, off, sev, name, ids) in sorted(rec.codes.items(), key=lambda kv: (_SEV_RANK.get(kv[1][3], 3),
                                                                                       -kv[1][0])):
        if code in _TOLD or sev == "info":
            continue
        who = ""
        if ids:
            who = (" from ID " if len(ids) == 1 else " from IDs ") + _ids(sorted(ids))
        tw = when(t, off)
        sole = next(iter(ids)) if len(ids) == 1 else None
        say(sev, sole, f"{code} {name}: {_times(n)}{who}, first{at(*tw)}", tw)
    items.sort(key=lambda it: _SEV_RANK[it["severity"]])  # stable: the order above ranks within a severity
    if len(items) > _MAX_LINES:
        rest = items[_MAX_LINES - 1:]
        items = items[:_MAX_LINES - 1]
        say(rest[0]["severity"], None, f"and {len(rest)} more: see the findings and the health table")
    if not items and not stats.bytes:
        say("warning", None, "nothing to tell: the capture holds no data")  # empty is no clean bill of health
    elif not items:
        answered = sum(st.returns + st.acks + st.nacks for st in servos.values())
        say("info", None, f"nothing wrong seen: {_plural(len(servos), 'servo')}, {answered} replies, none missing, "
            "no status flags, no damaged packets")
    # The bus load, last: a figure to know whether or not anything went wrong.
    peak = stats.load_peak
    if peak is not None:
        load, start = peak
        tw = when(start, 0)
        sev = "warning" if load >= 0.95 else "info"
        line = {"severity": sev, "id": None, "t": tw[0], "wall": tw[1],
                "text": f"the bus load peaked at {load * 100:.0f} % in the second from "
                        f"{seconds_text(tw[0], form)}, "
                        f"{(stats.bus_load or 0) * 100:.0f} % on average"
                        + ("; little room for more traffic" if sev == "warning" else "")}
        if sev == "warning":
            k = next((i for i, it in enumerate(items) if it["severity"] == "info"), len(items))
            items.insert(k, line)
        else:
            items.append(line)
    return items
