"""`info`'s per-servo health and "what happened": the figures, the summary lines, and the same data in JSON and MCAP."""

from __future__ import annotations

import json
from collections import defaultdict
from pathlib import Path

import pytest
from mcap.reader import make_reader

from rs30x_sniff.sinks import health as health_module
from rs30x_sniff.cli import main
from rs30x_sniff.protocol.events import LongPacket, ReturnPacket, ShortPacket
from rs30x_sniff.sinks.health import PRESENT, WRITTEN
from rs30x_sniff.protocol.mcap_names import STATS_METADATA_NAME
from rs30x_sniff.sinks.pipeline import decode_records
from rs30x_sniff.sinks.stats import CaptureStats
from rs30x_sniff.protocol.wire import encode_read, encode_return

ROOT = Path(__file__).resolve().parents[2]
NEW_KEYS = ("health", "bus_load_peak", "what_happened")


def _run(capsys, argv: list[str]) -> str:
    code = main(argv)
    out = capsys.readouterr().out
    assert code in (0, 1), (argv, code)
    return out


@pytest.fixture(scope="module")
def sims(tmp_path_factory):
    d = tmp_path_factory.mktemp("health")
    made = {}
    for name, duration in (("overheat", "5"), ("hexapod", "2"), ("silent-servo", "2"), ("bad-checksum", "2")):
        path = d / f"{name}.thex"
        assert main(["simulate", "--scenario", name, "--duration", duration, "--seed", "1", "-o", str(path)]) == 0
        made[name] = path
    return made


def _info(capsys, path: Path, *opts: str) -> dict:
    return json.loads(_run(capsys, ["info", str(path), "--format", "json", "--isolated", *opts]))


def _chunks(path: Path):
    """A timestamped hex capture as (bytes, t) chunks, one per line."""
    for line in path.read_text().splitlines():
        t, _, hexes = line.partition(" ")
        yield bytes.fromhex(hexes), float(t)


# ---- the overheat scenario: servo 2 trips its temperature limit; the host keeps switching it back on ----
def test_overheat_health_shows_the_limit_with_its_time_flags_and_q009(capsys, sims):
    info = _info(capsys, sims["overheat"])
    lint = json.loads(_run(capsys, ["lint", str(sims["overheat"]), "--format", "json", "--isolated",
                                    "--fail-on", "never"]))
    s001 = next(f for f in lint if f["code"] == "S001")
    q009 = [f for f in lint if f["code"] == "Q009" and f["id"] == 2]
    assert len(q009) == 2  # at 4 s and 5 s: a torque-on every 50 cycles
    hot = info["health"]["2"]
    lim = hot["flags"]["temperature_limit"]
    assert lim["first_t"] == pytest.approx(s001["t"], abs=1e-6)  # the capture time lint (and decode) print
    assert lim["first_wall"] is None  # the simulator's clock starts at 0, not in 1970
    assert lim["count"] > 1 and "temperature_alarm" in hot["flags"]
    assert hot["flags"]["temperature_alarm"]["first_t"] < lim["first_t"]
    assert hot["findings"]["Q009"] == 2 and hot["findings"]["S001"] == 1
    temp = hot["registers"]["present_temperature"]
    assert temp["unit"] == "degC" and temp["max"] >= 75 > temp["min"]
    # The healthy servos show no flags and no findings.
    assert all(not info["health"][k]["flags"] and not info["health"][k]["findings"] for k in "13456")
    first = info["what_happened"][0]
    assert first["severity"] == "error" and first["id"] == 2 and first["t"] == lim["first_t"]
    assert first["text"].startswith(f"ID 2 reached its temperature limit at {lim['first_t']:.2f} s")
    assert first["text"].endswith("and was switched back on twice (Q009)")


def test_overheat_text_shows_the_health_table_and_the_summary(capsys, sims):
    out = _run(capsys, ["info", str(sims["overheat"]), "--isolated"])
    assert "health" in out and "temp degC" in out and "RS303MR" in out
    row = next(line for line in out.splitlines() if line.split()[:2] == ["2", "RS303MR"])
    assert ".." in row  # servo 2's temperature and current rose: ranges, not one value
    assert "ID 2    temperature_limit" in out and "Q009 2" in out
    summary = out[out.index("what happened"):]
    assert "error    ID 2 reached its temperature limit at 3.4" in summary
    assert "switched back on twice (Q009)" in " ".join(summary.split())


def test_a_healthy_hexapod_says_nothing_is_wrong(capsys, sims):
    info = _info(capsys, sims["hexapod"])
    said = info["what_happened"]
    assert said[0]["text"].startswith("nothing wrong seen: 18 servos")
    assert {x["severity"] for x in said} == {"info"}
    assert all(not h["flags"] for h in info["health"].values())
    assert info["bus_load_peak"]["load"] >= info["bus_load"]
    out = _run(capsys, ["info", str(sims["hexapod"]), "--isolated"])
    assert "nothing wrong seen" in out[out.index("what happened"):]


@pytest.mark.parametrize("name, needle", [
    ("silent-servo", "ID 4 never answered: "),
    ("bad-checksum", "with a bad checksum"),
])
def test_faults_are_told_in_plain_words(capsys, sims, name, needle):
    said = _info(capsys, sims[name])["what_happened"]
    assert said[0]["severity"] == "error"
    assert any(needle in x["text"] for x in said), said


def test_the_json_keys_are_the_mcap_metadata(capsys, sims, tmp_path):
    info = _info(capsys, sims["overheat"])
    out = tmp_path / "o.mcap"
    _run(capsys, ["convert", str(sims["overheat"]), "-o", str(out), "--isolated"])
    with open(out, "rb") as f:
        meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}[STATS_METADATA_NAME]
    stats = json.loads(meta["stats"])
    for key in NEW_KEYS:
        assert key in info and stats[key] == info[key]
    for item in info["what_happened"]:
        assert set(item) == {"severity", "id", "text", "t", "wall"}
    assert set(info["health"]) == set(info["servos"])
    assert set(info["health"]["1"]) == {"model", "registers", "flags", "findings"}


# ---- the figures against a plain oracle: every field of every packet, decoded one by one ----------------
def test_ranges_match_every_decoded_field(sims):
    stats = CaptureStats(115200)
    lo: dict = defaultdict(dict)
    hi: dict = defaultdict(dict)
    n: dict = defaultdict(lambda: defaultdict(int))
    for rec in decode_records(_chunks(sims["hexapod"])):
        stats.add(rec)
        ev = rec.event
        if not ev.checksum_ok:
            continue
        t = type(ev)
        if t is ReturnPacket:
            names = PRESENT
        elif (t is ShortPacket and ev.data and ev.id != 0xFF) or t is LongPacket:
            names = WRITTEN
        else:
            continue
        for f in rec.fields:
            if f.name in names and f.partial is None:
                sid = f.id if f.id is not None else ev.id
                lo[sid][f.name] = min(lo[sid].get(f.name, f.value), f.value)
                hi[sid][f.name] = max(hi[sid].get(f.name, f.value), f.value)
                n[sid][f.name] += 1
    got = stats.as_dict()["health"]
    assert lo, "the hexapod returns and writes carry these registers"
    for sid in lo:
        regs = got[str(sid)]["registers"]
        assert set(regs) == set(lo[sid])
        for name, r in regs.items():
            assert (r["min"], r["max"], r["count"]) == (lo[sid][name], hi[sid][name], n[sid][name]), (sid, name)


def test_asking_midway_changes_nothing(sims, monkeypatch):
    """The monitor reads as_dict() twice a second: partial reductions must add up to one pass's."""
    monkeypatch.setattr(health_module, "FLUSH_ROWS", 7)  # and small batches, as on a long capture
    recs = list(decode_records(_chunks(sims["overheat"])))
    once = CaptureStats(115200)
    for r in recs:
        once.add(r)
    often = CaptureStats(115200)
    for k, r in enumerate(recs):
        often.add(r)
        if k % 101 == 0:
            often.as_dict()
    assert often.as_dict() == once.as_dict()


@pytest.mark.parametrize("columnar", [False, True])
def test_without_ranges_the_figures_are_the_same_but_the_ranges(sims, columnar):
    """CaptureStats(ranges=False) (figure checks that read no min/max): the flags, findings and every other
    figure as with ranges, on both paths; only the register ranges are left out."""
    from rs30x_sniff.decode.decoder import Decoder
    from rs30x_sniff.sinks.pipeline import drive

    got = {}
    for ranges in (True, False):
        stats = CaptureStats(115200, ranges=ranges)
        drive(_chunks(sims["overheat"]), Decoder(columnar=columnar), stats)
        got[ranges] = stats.as_dict()
    with_ranges, without = got[True], got[False]
    assert any(h["registers"] for h in with_ranges["health"].values())
    assert not any(h["registers"] for h in without["health"].values())
    for h in with_ranges["health"].values():
        h["registers"] = {}
    # "what happened" names the peak a range showed ("... (peak 77 degC)"); its lines are otherwise the same.
    told = [{k: v for k, v in line.items() if k != "text"} for line in with_ranges.pop("what_happened")]
    assert [{k: v for k, v in line.items() if k != "text"} for line in without.pop("what_happened")] == told
    assert without == with_ranges
    assert any(h["flags"] for h in without["health"].values())  # overheat's flags are still counted


def test_wall_clock_for_epoch_times_and_line_time_without_timestamps():
    t0 = 1_700_000_000.0
    req, ret = encode_read(3, 42, 18), encode_return(3, 42, bytes(8) + (80).to_bytes(2, "little") + bytes(8),
                                                     flags=0x80)
    stats = CaptureStats(115200)
    for rec in decode_records([(req, t0), (ret, t0 + 0.5)]):
        stats.add(rec)
    d = stats.as_dict()
    lim = d["health"]["3"]["flags"]["temperature_limit"]
    assert lim["first_t"] == t0 + 0.5 and lim["first_wall"] == "2023-11-14T22:13:20.500Z"
    # Times rebased to 0 with the wall clock of time 0 beside them (a source that says it) give the same wall.
    anchored = CaptureStats(115200)
    anchored.wall_anchor = t0
    for rec in decode_records([(req, 0.0), (ret, 0.5)]):
        anchored.add(rec)
    lim = anchored.as_dict()["health"]["3"]["flags"]["temperature_limit"]
    assert lim["first_t"] == 0.5 and lim["first_wall"] == "2023-11-14T22:13:20.500Z"
    assert "[2023-11-14 22:13:20.500 UTC]" in d["what_happened"][0]["text"]
    assert d["health"]["3"]["registers"]["present_temperature"] == {"min": 80, "max": 80, "unit": "degC",
                                                                    "count": 1}
    # Without timestamps, a time is the line time of the bytes before it, as the duration is.
    untimed = CaptureStats(115200)
    for rec in decode_records([(req + ret, None)]):
        untimed.add(rec)
    lim = untimed.as_dict()["health"]["3"]["flags"]["temperature_limit"]
    assert lim["first_t"] == pytest.approx(len(req) * 10 / 115200, abs=1e-6) and lim["first_wall"] is None
    assert untimed.as_dict()["bus_load_peak"] is None


def test_frames_in_one_bytes_object_count_and_join_as_a_row_each():
    # The columnar path buffers a Block's frames as one bytes object: the buffer must still hold an
    # item a row (so it is flushed after the same rows) and join to the same frames, in order.
    size = 10
    a, b, c, d = (bytes([k]) * size for k in range(1, 5))
    items = health_module.Frames.rows(b + c, size)
    assert len(items) == 2 and health_module.Frames.rows(b"", size) == []
    rows = [a, *items, d]
    assert health_module._joined(rows, size) == (a + b + c + d, size)
    odd = b"\x09" * (size + 1)  # a frame of another size is left out; the others keep their order
    assert health_module._joined([a, odd, *items, d], size) == (a + b + c + d, size)


def test_an_empty_capture_is_no_clean_bill_of_health(capsys, tmp_path):
    empty = tmp_path / "empty.thex"
    empty.write_text("")
    info = _info(capsys, empty)
    said = [w["text"] for w in info["what_happened"]]
    assert said == ["nothing to tell: the capture holds no data"]
    assert info["what_happened"][0]["severity"] == "warning"
