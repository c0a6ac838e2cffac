"""The sigrok decoder `rs30x-sniff plugin sigrok` writes: run by sigrok-cli, it agrees with `decode --format jsonl`."""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

np = pytest.importorskip("numpy", reason="logic captures need numpy")

from rs30x_sniff.plugins.maps import plugin_maps  # noqa: E402
from rs30x_sniff.plugins.sigrok import install_hint  # noqa: E402
from rs30x_sniff.protocol import wire  # noqa: E402
from rs30x_sniff.protocol.memmap import ModelRegistry, decoders_dirs  # noqa: E402
from tests.conftest import ROOT  # noqa: E402
from tests.plugins.user_maps import write_user_maps  # noqa: E402
from tests.plugins.sigrok_fixtures import (  # noqa: E402
    BAUD, RATE, SIGROK_CLI, annotations, frames_json, inputs, lay_end_to_end, reference, write_sr,
)

needs_sigrok = pytest.mark.skipif(SIGROK_CLI is None,
                                  reason="sigrok-cli is not installed (apt-get install sigrok-cli)")
BIT = RATE / BAUD  # samples per bit


def make_plugin(out: Path, env: dict | None = None) -> str:
    """`rs30x-sniff plugin sigrok -o OUT` in a process of its own (the maps of ``env``): what it prints."""
    done = subprocess.run([sys.executable, "-m", "rs30x_sniff", "plugin", "sigrok", "-o", str(out)],
                          env={**os.environ, **(env or {})}, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return done.stdout


def packet(event: dict) -> tuple:
    """What must agree between the plug-in's frame and the reference's event."""
    kind = event.get("kind", event.get("type"))
    return (kind, event["raw"].lower(), event["checksum_ok"], event["id"], event["flag"], event["address"],
            event["length"], event["count"], event.get("reason"))


def fields(event: dict) -> list[tuple]:
    return [(f["id"], f["address"], f["name"], f["raw"].lower(), f["value"], f["unit"]) for f in event["fields"]]


def first_difference(ours: list, theirs: list) -> str:
    for k, (a, b) in enumerate(zip(ours, theirs)):
        if a != b:
            return f"#{k}: plug-in {a} != reference {b}"
    return f"lengths differ: plug-in {len(ours)}, reference {len(theirs)}"


# ---- fixtures ------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def plugin(tmp_path_factory) -> Path:
    return_dir = tmp_path_factory.mktemp("sigrok") / "decoders"
    make_plugin(return_dir, {"RS30X_DECODERS": ""})
    return return_dir


@pytest.fixture(scope="module")
def everything(tmp_path_factory):
    """All inputs on one 1 MHz line, a pause between two: the .sr and where each input lies (s)."""
    stream, spans = lay_end_to_end(inputs())
    sr = write_sr(tmp_path_factory.mktemp("sr") / "all.sr", stream)
    return sr, spans


@pytest.fixture(scope="module")
def decoded(plugin, everything):
    """(the plug-in's frames, the reference's events) on the capture of every input."""
    sr, _ = everything
    return frames_json(sr, plugin), reference(sr, env={"RS30X_DECODERS": ""})


# ---- the generated files -------------------------------------------------------------------------
def test_files_are_python_38_and_the_maps_only_data(tmp_path):
    out = tmp_path / "decoders"
    make_plugin(out, {"RS30X_DECODERS": ""})
    names = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    assert names == ["rs30x/README.md", "rs30x/__init__.py", "rs30x/core.py", "rs30x/maps.py", "rs30x/pd.py"]
    for name in ("__init__.py", "pd.py", "core.py", "maps.py"):
        ast.parse((out / "rs30x" / name).read_text(), feature_version=(3, 8))
    assert (out / "rs30x" / "core.py").read_text() == (ROOT / "rs30x_sniff" / "plugins" / "pycore.py").read_text()
    # maps.py is one assignment of a literal that gives the maps back.
    tree = ast.parse((out / "rs30x" / "maps.py").read_text())
    assigns = [n for n in tree.body if isinstance(n, ast.Assign)]
    assert len(assigns) == 1 and assigns[0].targets[0].id == "MAPS"
    saved = os.environ.pop("RS30X_DECODERS", None)
    try:
        assert ast.literal_eval(assigns[0].value) == plugin_maps()
    finally:
        if saved is not None:
            os.environ["RS30X_DECODERS"] = saved


def test_install_hint_says_how_to_run_it_and_where_pulseview_looks(tmp_path):
    out = tmp_path / "decoders"
    printed = make_plugin(out, {"RS30X_DECODERS": ""})
    hint = install_hint(out)
    assert hint.strip() in printed
    assert f"SIGROKDECODE_DIR={out} sigrok-cli" in hint
    assert "-P uart:rx=D0:baudrate=115200,rs30x" in hint
    assert f"copy {out / 'rs30x'} into ~/.local/share/libsigrokdecode/decoders/" in hint


@needs_sigrok
def test_sigrok_cli_lists_the_decoder_with_the_models(plugin):
    shown = subprocess.run([SIGROK_CLI, "--show", "-P", "rs30x"], env={**os.environ, "SIGROKDECODE_DIR": str(plugin)},
                           capture_output=True, text=True, check=True).stdout
    assert "Futaba RS30x servo bus" in shown
    for model in ("RS303MR", "RS304MD"):
        assert model in shown


# ---- the differential test -----------------------------------------------------------------------
@needs_sigrok
def test_same_packets_as_decode(decoded):
    ours, theirs = decoded
    assert len(theirs) > 700  # every input is there (the simulator's seconds alone make hundreds)
    a, b = [packet(e) for e in ours], [packet(e) for e in theirs]
    assert a == b, first_difference(a, b)
    kinds = {e["type"] for e in theirs}
    assert {"short", "long", "return", "ack", "nack", "garbage"} <= kinds  # the inputs reach every kind
    sides = {"short": "host", "long": "host", "return": "servo", "ack": "servo", "nack": "servo", "garbage": None}
    assert all(e["direction"] == sides[e["kind"]] for e in ours)


@needs_sigrok
def test_same_fields_as_decode(decoded):
    ours, theirs = decoded
    a, b = [fields(e) for e in ours], [fields(e) for e in theirs]
    assert a == b, first_difference(a, b)
    assert sum(map(len, b)) > 1000


@needs_sigrok
def test_frames_lie_where_decode_puts_them(decoded):
    ours, theirs = decoded
    for mine, ref in zip(ours, theirs):
        assert abs(mine["start"] - ref["t"] * RATE) <= BIT, (mine, ref)
        assert abs(mine["end"] - ref["t_end"] * RATE) <= 2 * BIT, (mine, ref)
        for f in mine["fields"]:
            assert mine["start"] <= f["start"] < f["end"] <= mine["end"]


def shows(text: str, field: dict) -> bool:
    """Whether an annotation's text "name: value[ unit] (ID n)" says what the reference's field does."""
    m = re.fullmatch(r"(\w+): (.+?)(?: (\S+))? \(ID (\d+)\)", text)
    names = [field["name"]] if field["name"] else [f"reserved_{field['address']}", f"addr_{field['address']}"]
    if m is None or m[1] not in names or int(m[4]) != field["id"]:
        return False
    if field["value"] is None:  # a table's raw value it has no row for: no number, no unit
        return m[2] == f"?{int.from_bytes(bytes.fromhex(field['raw']), 'little')}" and m[3] is None
    shown, unit = (m[2], m[3]) if field["unit"] else ((m[2] + " " + m[3]) if m[3] else m[2], None)
    if unit != field["unit"]:
        return False
    value = field["value"]
    if isinstance(value, str):
        return shown == value
    if shown.startswith("0x"):  # a hex register, an unnamed byte, one byte of a 2-byte register
        return int(shown[2:4] if "(" in shown else shown[2:], 16) == int.from_bytes(
            bytes.fromhex(field["raw"]), "little") or int(shown[2:].split("(")[0], 16) == value
    return abs(float(shown) - value) <= 0.5 * 10 ** -len(shown.partition(".")[2])


@needs_sigrok
def test_annotations_name_the_registers_with_values_and_units(plugin, everything, decoded):
    sr, _ = everything
    _, theirs = decoded
    texts = [text for _, _, text in annotations(sr, plugin, "register")]
    expected = [f for event in theirs for f in event["fields"]]
    assert len(texts) == len(expected) > 1000
    wrong = [(t, f) for t, f in zip(texts, expected) if not shows(t, f)]
    assert not wrong, wrong[:5]
    assert any(re.fullmatch(r"present_temperature: \d+ degC \(ID \d+\)", t) for t in texts)
    assert any(re.fullmatch(r"goal_position: -?\d+\.\d deg \(ID \d+\)", t) for t in texts)


@needs_sigrok
def test_packets_row_has_a_packet_per_event_where_it_lies(plugin, everything, decoded):
    sr, _ = everything
    ours, theirs = decoded
    rows = annotations(sr, plugin, "request:return:ack:nack")
    packets = [(o, e) for o, e in zip(ours, theirs) if e["type"] != "garbage"]
    assert [(ss, es) for ss, es, _ in rows] == [(o["start"], o["end"]) for o, _ in packets]
    for (_, _, text), (_, e) in zip(rows, packets):
        if e["type"] == "short":
            assert text.startswith(f"Short packet to ID {e['id']}: flag {e['flag']:02X}"), (text, e)
        elif e["type"] == "long":
            assert text.startswith(f"Long packet: flag {e['flag']:02X}, address {e['address']}, "
                                   f"length {e['length']}, count {e['count']}"), (text, e)
        elif e["type"] == "return":
            assert text.startswith(f"Return from ID {e['id']}: flags {e['flag']:02X}"), (text, e)
        else:
            word = e["type"].upper()
            assert text == (f"{word} from ID {e['id']}" if e["id"] is not None
                            else f"{word} (no request asked for it)"), (text, e)
        assert text.endswith(" (bad checksum)") == (e["checksum_ok"] is False), (text, e)


@needs_sigrok
def test_warnings_row_shows_bad_sums_and_garbage(plugin, everything, decoded):
    sr, _ = everything
    _, theirs = decoded
    rows = annotations(sr, plugin, "note:warning:no-reply:error")
    bad_sums = sum(1 for e in theirs if e["checksum_ok"] is False and e["type"] != "garbage")
    garbage = sum(1 for e in theirs if e["type"] == "garbage")
    assert bad_sums and garbage
    assert sum(1 for *_, t in rows if t == "Bad checksum") == bad_sums
    assert sum(1 for *_, t in rows if t.startswith("Garbage: ")) == garbage


# ---- the edges of a capture and a broken stop bit ------------------------------------------------------
@needs_sigrok
def test_cut_frames_and_a_framing_error_as_decode_has_them(plugin, tmp_path):
    """A capture that starts in the middle of a frame, a byte with a low stop bit, a frame cut by an idle gap,
    and a frame cut by the end of the line's bytes (idle for 20 ms after it, so the uart says IDLE)."""
    goal = wire.encode_short(1, 0, 30, (900).to_bytes(2, "little"))
    read = wire.encode_read(2, 42, 2)
    chunks = [(goal[-5:], 0.0), (goal, 0.002), (b"\x55", 0.004), (read, 0.006), (goal[:6], 0.008), (goal, 0.010),
              (read[:5], 0.012)]
    sr = tmp_path / "edges.sr"
    write_sr(sr, chunks, broken_stop=[(0.004, 0)])
    ours = frames_json(sr, plugin)
    theirs = reference(sr, env={"RS30X_DECODERS": ""})
    assert [e["reason"] for e in theirs if e["type"] == "garbage"][:3] == ["capture-start", "framing-error",
                                                                          "truncated"]
    a, b = [packet(e) for e in ours], [packet(e) for e in theirs]
    assert a[:-1] == b[:-1], first_difference(a, b)
    # The last frame: sigrok's IDLE says the line stayed quiet (a cut frame); decode saw its input end.
    assert (a[-1][:-1], a[-1][-1], b[-1][-1]) == (b[-1][:-1], "truncated", "capture-end")


# ---- two lines: RX and TX each framed on its own --------------------------------------------------
@needs_sigrok
def test_rx_and_tx_lines_are_framed_apart(plugin, tmp_path):
    chunks = list(dict(inputs())["sim:hexapod"])
    host = [(d, t) for d, t in chunks if d[:2] != bytes(wire.RETURN_HEADER)]
    servo = [(d, t) for d, t in chunks if d[:2] == bytes(wire.RETURN_HEADER)]
    assert host and servo
    both = write_sr(tmp_path / "both.sr", host, tx=servo)
    ours = frames_json(both, plugin, f"uart:rx=D0:tx=D1:baudrate={BAUD},rs30x")
    one_wire = frames_json(write_sr(tmp_path / "one.sr", chunks), plugin)
    assert sorted(packet(e) for e in ours) == sorted(packet(e) for e in one_wire)
    assert {e["line"] for e in ours if e["kind"] == "return"} == {1}
    assert {e["line"] for e in ours if e["kind"] in ("short", "long")} == {0}


# ---- maps from $RS30X_DECODERS --------------------------------------------------------------------
HOSTILE = '"""); open({path!r}, "w"); ("'


@pytest.fixture(scope="module")
def user_maps(tmp_path_factory):
    """$RS30X_DECODERS with a hostile model EVIL1 (code-like enum labels and descriptions) and an RS303MR whose
    present_temperature is renamed case_temperature; the sentinel file the hostile text would create."""
    folder = tmp_path_factory.mktemp("maps")
    sentinel = Path(f"/tmp/rs30x-pwned-{os.getpid()}")  # short: an enum label holds at most 64 characters
    sentinel.unlink(missing_ok=True)
    evil = HOSTILE.format(path=str(sentinel))
    labels = {"on": evil, "brake": "'''", "off": "back\\slash \\"}
    description = evil + " ''' \\ "  # one printable line: the loader refuses control characters
    write_user_maps(folder, labels, description)
    registry = ModelRegistry.from_dirs([folder, *decoders_dirs()])
    torque = registry.get("EVIL1").register("torque_enable")
    assert (torque.enum, torque.description) == ({0: labels["off"], 1: evil, 2: labels["brake"]}, description)
    yield folder, sentinel, labels
    sentinel.unlink(missing_ok=True)


@pytest.fixture(scope="module")
def user_run(user_maps, tmp_path_factory):
    folder, sentinel, labels = user_maps
    env = {"RS30X_DECODERS": str(folder)}
    out = tmp_path_factory.mktemp("user") / "decoders"
    make_plugin(out, env)
    bus = [wire.encode_short(1, 0, 36, bytes([k])) for k in (0, 1, 2)]
    bus += [wire.encode_read(1, 50, 2), wire.encode_return(1, 50, (41).to_bytes(2, "little"))]
    chunks = [(frame, 0.002 * k) for k, frame in enumerate(bus)]
    sr = write_sr(out.parent / "user.sr", chunks)
    return out, sr, env


@needs_sigrok
def test_hostile_labels_load_as_data_and_show_verbatim(user_maps, user_run):
    folder, sentinel, labels = user_maps
    out, sr, env = user_run
    rows = annotations(sr, out, "register", f"uart:rx=D0:baudrate={BAUD},rs30x:model=EVIL1")
    assert not sentinel.exists()
    texts = [t for *_, t in rows]
    for k in (0, 1, 2):
        label = labels[("off", "on", "brake")[k]]
        assert f"torque_enable: {label} (ID 1)" in texts
    ours = frames_json(sr, out, f"uart:rx=D0:baudrate={BAUD},rs30x:model=EVIL1")
    theirs = reference(sr, "--model", "EVIL1", env=env)
    assert [fields(e) for e in ours] == [fields(e) for e in theirs]
    assert not sentinel.exists()


@needs_sigrok
def test_a_user_map_replaces_the_bundled_model_of_its_name(user_run):
    out, sr, env = user_run
    rows = annotations(sr, out, "register")
    assert "case_temperature: 41 degC (ID 1)" in [t for *_, t in rows]
    assert not any("present_temperature" in t for *_, t in rows)
    ours = frames_json(sr, out)
    theirs = reference(sr, env=env)
    assert [fields(e) for e in ours] == [fields(e) for e in theirs]
