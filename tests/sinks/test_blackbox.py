"""The black box (issue 26): windows around each fire of a trigger, merged where they overlap, bounded by
--max-saves and by the ring; on simulator traffic through both decoding paths, with a stand-in for the writer."""

from __future__ import annotations

import pytest

from rs30x_sniff.decode.decoder import Decoder
from rs30x_sniff.lint import LintConfig, Linter
from rs30x_sniff.sim import run
from rs30x_sniff.sinks.blackbox import BlackBox, TriggerError, parse_trigger, slug, wall_name
from rs30x_sniff.sinks.pipeline import Pipeline, decode_records

T0 = 1_790_000_000.0  # the chunks' times as a live port stamps them: epoch seconds


def traffic(name: str, duration: float | None = None, seed: int = 0, shift: float = 0.0) -> list:
    return [(d, T0 + shift + t) for d, t in run(name, duration=duration, seed=seed)]


def box_run(chunks, texts, pre, post, *, columnar=True, lint=False, **kw):
    saved = []
    codes = [r.code for r in Linter(LintConfig()).rules]
    box = BlackBox([parse_trigger(t, codes) for t in texts], pre, post,
                   lambda ch, w, name: saved.append((ch, w, name)), **kw)
    Pipeline(Decoder(None, Linter(LintConfig()) if lint else None, columnar=columnar), [box],
             group_bytes=2048).run(chunks)
    return box, saved


def fire_times(chunks, text) -> list[float]:
    flt = parse_trigger(text, []).filter
    return [r.t for r in decode_records(chunks) if flt.matches(r)]


@pytest.mark.parametrize("columnar", [True, False])
@pytest.mark.parametrize("pre", [1.0, 5.0])
def test_overheat_saves_one_window_from_pre_before_the_first_fire_to_post_after_the_last(columnar, pre):
    chunks = traffic("overheat")
    fires = fire_times(chunks, "present_temperature>70")
    assert len(fires) > 10
    box, saved = box_run(chunks, ["present_temperature>70"], pre, 2.0, columnar=columnar)
    assert len(saved) == 1
    got, w, name = saved[0]
    assert (w.start, w.end) == (fires[0] - pre, fires[-1] + 2.0)
    assert [t for t, _ in w.fires] == fires
    assert got == [c for c in chunks if fires[0] - pre <= c[1] <= fires[-1] + 2.0]  # the bus's bytes, as they came
    assert name == f"{wall_name(fires[0])}-present_temperature-gt-70.mcap"


def test_fires_apart_by_more_than_pre_and_post_are_windows_of_their_own():
    a = traffic("overheat")
    gap = a[-1][1] - T0 + 30.0  # the same traffic again 30 s after the first ends: windows cannot overlap
    chunks = a + traffic("overheat", seed=1, shift=gap)
    box, saved = box_run(chunks, ["present_temperature>70"], 2.0, 2.0)
    assert len(saved) == 2 and saved[0][1].end < saved[1][1].start
    assert not set(saved[0][0]) & set(saved[1][0])  # no byte saved twice


def test_a_fire_whose_pre_reaches_back_into_the_window_extends_it():
    chunks = traffic("overheat")
    fires = fire_times(chunks, "present_temperature>70")
    # post 0.01 s: the fires are ~0.02 s apart, so each window ends before the next fire, but pre reaches back.
    box, saved = box_run(chunks, ["present_temperature>70"], 0.5, 0.01)
    assert len(saved) == 1 and saved[0][1].end == fires[-1] + 0.01


def test_max_saves_counts_fires_past_the_hours_allowance():
    a = traffic("overheat")
    span = a[-1][1] - T0 + 10.0
    chunks = [c for k in range(3) for c in traffic("overheat", seed=k, shift=k * span)]
    lines = []
    box, saved = box_run(chunks, ["present_temperature>70"], 1.0, 1.0, max_per_hour=2, say=lines.append)
    assert len(saved) == 2 and box.suppressed > 0
    assert len(lines) == 1 and "--max-saves" in lines[0]


def test_rule_code_and_severity_triggers_fire_on_findings():
    chunks = traffic("overheat")
    box, saved = box_run(chunks, ["S001"], 1.0, 1.0, lint=True)
    assert len(saved) == 1 and saved[0][1].first.text == "S001"
    box, saved = box_run(chunks, ["sev>=error"], 1.0, 1.0, lint=True)
    assert len(saved) == 1


def test_the_ring_holds_only_pre_while_nothing_fires():
    chunks = traffic("hexapod", duration=6.0)
    box, saved = box_run(chunks, ["present_temperature>70"], 1.0, 1.0)
    assert not saved
    # --pre back from the last record decided (the decoder holds a window of bytes): about a second, never all.
    assert box.ring[-1][1] - box.ring[0][1] <= 1.0 + 0.5 and len(box.ring) < len(chunks) / 3


def test_a_window_still_open_at_the_end_is_saved_as_far_as_the_bus_went():
    chunks = traffic("overheat")
    fires = fire_times(chunks, "present_temperature>70")
    cut = [c for c in chunks if c[1] <= fires[3]]
    box, saved = box_run(cut, ["present_temperature>70"], 1.0, 5.0)
    assert len(saved) == 1 and saved[0][1].end == cut[-1][1]


def test_idle_time_closes_a_window_no_byte_closes():
    clock = [0.0]
    chunks = traffic("overheat")
    fires = fire_times(chunks, "present_temperature>70")
    saved = []
    box = BlackBox([parse_trigger("present_temperature>70", [])], 1.0, 1.0,
                   lambda ch, w, name: saved.append(w), now=lambda: clock[0])
    p = Pipeline(Decoder(None, None, columnar=True), [box], group_bytes=2048)
    for c in [c for c in chunks if c[1] <= fires[-1] + 0.5]:
        p.feed(*c)
    p.feed(b"", None)  # a quiet bus: not yet past the window and its pre
    clock[0] = fires[-1] + 1.5
    p.feed(b"", None)
    assert not saved
    clock[0] = fires[-1] + 2.5
    p.feed(b"", None)
    assert len(saved) == 1


def test_bad_triggers_are_one_line():
    for text, why in (("Z999", "no such rule"), ("present_temprature>70", "no register"), ("", "empty")):
        with pytest.raises(TriggerError, match=why):
            parse_trigger(text, ["S001"])
    assert slug("id:3 latency>5ms") == "id-3_latency-gt-5ms"
