"""Issue 34 in the plug-ins: faults stand out (sigrok classes, Wireshark's Info, columns, colouring rules), one
number format for model_number, PulseView's NO-REPLY, and maps with no model number or a second name."""

from __future__ import annotations

import copy
import json
import os
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from rs30x_sniff.cli import main
from rs30x_sniff.plugins import pycore, sigrok, wireshark
from rs30x_sniff.plugins.maps import plugin_maps
from rs30x_sniff.protocol import wire
from rs30x_sniff.protocol.memmap import default_registry
from tests.conftest import CAPTURES

TSHARK = shutil.which("tshark")
SIGROK_CLI = shutil.which("sigrok-cli")
needs_tshark = pytest.mark.skipif(TSHARK is None, reason="tshark is not installed (apt-get install tshark)")
needs_sigrok = pytest.mark.skipif(SIGROK_CLI is None, reason="sigrok-cli is not installed (apt-get install sigrok-cli)")


def bundled_maps() -> dict:
    saved = os.environ.pop("RS30X_DECODERS", None)  # the bundled maps only, as `decode` below reads them
    try:
        return plugin_maps()
    finally:
        if saved is not None:
            os.environ["RS30X_DECODERS"] = saved


def with_unnumbered(maps: dict) -> dict:
    """``maps`` and a model NONUM (RS303MR's registers) whose model number no source gives, also named NONUM2."""
    out = copy.deepcopy(maps)
    model = copy.deepcopy(out["models"][0])
    model.update(name="NONUM", model_number=None, also_named=["NONUM2"])
    out["models"].append(model)
    return out


def write(folder: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        (folder / rel).parent.mkdir(parents=True, exist_ok=True)
        (folder / rel).write_text(text, encoding="utf-8")
    return folder


def decoded(jsonl: Path) -> list[dict]:
    """The records of a `decode --format jsonl` file."""
    return [r for r in map(json.loads, jsonl.read_text().splitlines()) if r.get("type") != "diagnostic"]


# ---- Wireshark ----------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def home(tmp_path_factory) -> Path:
    """A HOME of its own for tshark, holding the RS30x profile the plug-in ships."""
    return tmp_path_factory.mktemp("home")


@pytest.fixture(scope="module")
def lua(tmp_path_factory, home) -> Path:
    folder = write(tmp_path_factory.mktemp("wireshark"), wireshark.generate(with_unnumbered(bundled_maps())))
    profiles = home / ".config" / "wireshark" / "profiles"
    profiles.mkdir(parents=True)
    shutil.copytree(folder / wireshark.PROFILE_DIR, profiles / wireshark.PROFILE)
    return folder / wireshark.LUA_FILE


def tshark(home: Path, lua: Path, pcapng: Path, *args: str) -> str:
    env = {k: v for k, v in os.environ.items() if not k.startswith("WIRESHARK_")}
    env.update(HOME=str(home), XDG_CONFIG_HOME=str(home / ".config"))
    run = subprocess.run([TSHARK, "-n", "-X", f"lua_script:{lua}", "-r", str(pcapng), *args], capture_output=True,
                         text=True, timeout=120, env=env)
    assert run.returncode == 0 and "Lua: Error" not in run.stderr, run.stderr
    return run.stdout


@pytest.fixture(scope="module")
def converted(tmp_path_factory):
    """name -> (pcapng, decode's records) for a few captures with faults."""
    tmp = tmp_path_factory.mktemp("converted")
    out = {}
    for name in ("lint/F001-checksum-mismatch.hex", "lint/S002-temperature-alarm.hex",
                 "lint/M005-unknown-model-number.hex", "lint/F002-garbage-bytes.hex", "manual-examples.hex",
                 "session-mixed.thex"):
        path = CAPTURES / name
        stem = tmp / name.replace("/", "_")
        pcapng, jsonl = stem.with_suffix(".pcapng"), stem.with_suffix(".jsonl")
        assert main(["convert", str(path), "-o", str(pcapng), "--isolated"]) == 0
        assert main(["decode", str(path), "--format", "jsonl", "-o", str(jsonl), "--isolated", "--no-lint"]) == 0
        out[name] = (pcapng, decoded(jsonl))
    return out


def columns(home: Path, lua: Path, pcapng: Path, *fields: str) -> list[list[str]]:
    args = [x for f in fields for x in ("-e", f)]
    return [line.split("\t") for line in tshark(home, lua, pcapng, "-T", "fields", *args).splitlines()]


@needs_tshark
def test_a_fault_leads_the_info_column(home, lua, converted):
    for name in ("lint/F001-checksum-mismatch.hex", "lint/S002-temperature-alarm.hex"):
        pcapng, records = converted[name]
        infos = [row[0] for row in columns(home, lua, pcapng, "_ws.col.Info")]
        assert len(infos) == len(records)
        for info, rec in zip(infos, records):
            faults = (["BAD CHECKSUM"] if rec.get("checksum_ok") is False else []) + \
                     [f.replace("_", " ") for f in rec.get("flags", []) if rec["type"] == "return"]
            if faults:
                assert info.startswith("[" + ", ".join(faults) + "] "), (info, rec)
            else:
                assert not info.startswith("["), info
        assert any(i.startswith("[BAD CHECKSUM] ") for i in infos) or any("temperature alarm" in i for i in infos)


@needs_tshark
def test_source_and_destination_say_host_or_servo(home, lua, converted):
    pcapng, records = converted["manual-examples.hex"]
    rows = columns(home, lua, pcapng, "_ws.col.Source", "_ws.col.Destination")
    want = []
    for rec in records:
        if rec["type"] == "short":
            want.append(["host", "all servos" if rec["id"] == wire.BROADCAST_ID else f"servo {rec['id']}"])
        elif rec["type"] == "long":
            want.append(["host", "servos"])
        elif rec["type"] == "return":
            want.append([f"servo {rec['id']}", "host"])
        elif rec["type"] in ("ack", "nack"):
            want.append([f"servo {rec['id']}" if rec["id"] is not None else "servo", "host"])
        else:
            want.append(["", ""])
    assert rows == want
    assert {"long", "return", "short"} <= {r["type"] for r in records}


@needs_tshark
def test_the_bus_bytes_field_counts_the_frame_not_the_export_header(home, lua, converted):
    pcapng, records = converted["session-mixed.thex"]
    rows = columns(home, lua, pcapng, "rs30x.bytes", "frame.len")
    assert [int(b) for b, _ in rows] == [len(r["raw"]) // 2 for r in records]
    assert all(int(n) > int(b) for b, n in rows)  # what Wireshark's own Length column counts


@needs_tshark
def test_the_profiles_columns_show_the_bus_bytes(home, lua, converted):
    pcapng, records = converted["lint/F001-checksum-mismatch.hex"]
    psml = tshark(home, lua, pcapng, "-C", wireshark.PROFILE, "-T", "psml")
    root = ET.fromstring(psml)
    titles = [s.text for s in root.find("structure")]
    assert "Bytes" in titles and "Length" not in titles
    k = titles.index("Bytes")
    assert [int(p.findall("section")[k].text) for p in root.iter("packet")] == [len(r["raw"]) // 2 for r in records]


@needs_tshark
def test_model_number_reads_0x_and_four_digits_in_the_info_and_the_tree(home, lua, converted):
    pcapng, records = converted["lint/M005-unknown-model-number.hex"]
    want = [f"0x{int.from_bytes(bytes.fromhex(r['raw'])[7:9], 'little'):04X}" for r in records
            if r["type"] == "return" and r["address"] == 0]
    infos = [row[0] for row in columns(home, lua, pcapng, "_ws.col.Info")]
    assert [re.search(r"model_number=(\S+)", i).group(1) for i in infos if "model_number=" in i] == want
    shown = [line.strip() for line in tshark(home, lua, pcapng, "-V").splitlines() if "model_number:" in line]
    assert shown == [f"model_number: {w}" for w in want]
    assert want and "0x300C" in want  # letters, not only digits: the case is decode's


@needs_tshark
def test_the_profiles_rules_colour_errors_and_warnings_as_wiresharks_own(home, lua, converted):
    """tshark --color applies the profile's colouring rules: a bad sum (an error) gets the colours of
    Wireshark's "Checksum Errors", a servo's fault flag (a warning) those of its state changes, others none."""
    error = ("#12272e", "#f78787")     # background, foreground
    warning = ("#12272e", "#fffc9c")
    for name in ("lint/F001-checksum-mismatch.hex", "lint/S002-temperature-alarm.hex"):
        pcapng, records = converted[name]
        psml = tshark(home, lua, pcapng, "-C", wireshark.PROFILE, "--color", "-T", "psml")
        got = [(p.get("background"), p.get("foreground")) for p in ET.fromstring(psml).iter("packet")]
        want = [error if r.get("checksum_ok") is False else warning if r["type"] == "return" and r["flags"]
                else (None, None) for r in records]
        assert got == want, name
        assert error in got or warning in got


@needs_tshark
def test_a_model_without_a_number_is_decoded_when_named_and_by_its_second_name(home, lua, converted):
    pcapng, records = converted["manual-examples.hex"]
    for name in ("NONUM", "NONUM2"):
        text = tshark(home, lua, pcapng, "-o", f"rs30x.model:{name}", "-T", "fields", "-e", "rs30x.model")
        assert {x for x in text.split("\n") if x} == {"NONUM"}, name
    # Not named, it is never learned: a return of any model number keeps the map decode used.
    pcapng, records = converted["lint/M005-unknown-model-number.hex"]
    text = tshark(home, lua, pcapng, "-T", "fields", "-e", "rs30x.model")
    assert "NONUM" not in text


# ---- the family's maps: every plug-in generates and loads them -----------------------------------------
def test_every_bundled_map_reaches_the_plugins_with_its_number_or_none():
    maps = bundled_maps()
    registry = default_registry()
    names = {m["name"] for m in maps["models"]}
    assert names == {m.name for m in registry.models.values()}
    for m in maps["models"]:
        assert m["model_number"] == registry.get(m["name"]).model_number
    unnumbered = [m["name"] for m in maps["models"] if m["model_number"] is None]
    if "RS405CB" in names:  # issue 34's maps: RS405CB/RS406CB are known only by name
        assert {"RS405CB", "RS406CB"} <= set(unnumbered)
    core = pycore.Core(maps)
    assert None not in core.by_number
    for name in names:
        assert pycore.Core(maps, name).default.name == name


def test_the_core_takes_a_second_name_and_never_learns_a_model_without_a_number():
    maps = with_unnumbered(bundled_maps())
    core = pycore.Core(maps, "nonum2")
    assert core.default.name == "NONUM"
    bus = wire.encode_return(2, 0, (0x7777).to_bytes(2, "little"))
    bus += wire.encode_return(1, 0, (0x3030).to_bytes(2, "little"))
    frames = [f for k, b in enumerate(bus) for f in core.feed(b, k, k + 1)] + core.flush()
    assert [f.model for f in frames] == ["NONUM", "RS303MR"]  # a number no map has keeps the named map
    assert 2 not in core.learned and core.learned[1].name == "RS303MR"  # a number a map has is learned
    core = pycore.Core(maps)
    assert all(m.name != "NONUM" for m in core.by_number.values())


@needs_sigrok
def test_sigrok_lists_every_model_and_second_name(tmp_path):
    folder = write(tmp_path / "decoders", sigrok.generate(with_unnumbered(bundled_maps())))
    shown = subprocess.run([SIGROK_CLI, "--show", "-P", "rs30x"], env={**os.environ, "SIGROKDECODE_DIR": str(folder)},
                           capture_output=True, text=True, check=True).stdout
    line = next(x for x in shown.splitlines() if x.startswith("- model:"))
    assert "'NONUM'" in line and "'NONUM2'" in line


# ---- the sigrok decoder's texts ---------------------------------------------------------------------
def pd_namespace() -> dict:
    """The generated pd.py's helpers (the texts), run without libsigrokdecode."""
    import types

    stub = types.ModuleType("sigrokdecode")
    stub.Decoder = object
    files = sigrok.generate(bundled_maps())
    pd = files[f"{sigrok.PACKAGE}/pd.py"].replace("from .core import Core", "Core = None").replace(
        "from .maps import MAPS", "MAPS = " + files[f"{sigrok.PACKAGE}/maps.py"].split("MAPS = ", 1)[1])
    saved = sys.modules.get("sigrokdecode")
    sys.modules["sigrokdecode"] = stub
    try:
        ns: dict = {}
        exec(compile(pd, "pd.py", "exec"), ns)
        return ns
    finally:
        if saved is None:
            sys.modules.pop("sigrokdecode", None)
        else:
            sys.modules["sigrokdecode"] = saved


def test_annotation_texts_are_for_people_and_have_shorter_forms():
    ns = pd_namespace()
    core = pycore.Core(bundled_maps())
    ret = bytes(wire.encode_return(1, 42, bytes.fromhex("8403 0000 0000 0000 2d00 e402")))
    ret = ret[:3] + bytes((0x20,)) + ret[4:-1]
    x = 0
    for b in ret[2:]:
        x ^= b
    ret += bytes((x,))
    frame = ([f for k, b in enumerate(ret) for f in core.feed(b, k, k + 1)] + core.flush())[0]
    assert frame.warnings == ["temperature_alarm"]
    assert ns["warning_texts"](frame, "temperature_alarm") == ["Temperature alarm (ID 1)", "Temperature alarm", "!"]
    voltage = next(f for f in frame.fields if f["name"] == "present_voltage")
    texts = ns["field_texts"](voltage)
    assert texts == ["present_voltage: 7.40 V (ID 1)", "present_voltage: 7.40 V", "7.40 V", "7.40", "7.4"]
    assert all(len(a) > len(b) for a, b in zip(texts, texts[1:]))  # longest first, each shorter


# ---- PulseView's NO-REPLY: sigrok-cli on a logic capture ---------------------------------------------
@needs_sigrok
def test_sigrok_shows_no_reply_where_decode_says_it_and_bad_sums_in_their_class(tmp_path):
    pytest.importorskip("numpy", reason="logic captures need numpy")
    from tests.plugins.screens import fault_chunks
    from tests.plugins.sigrok_fixtures import annotations, reference, write_sr

    folder = write(tmp_path / "decoders", sigrok.generate(bundled_maps()))
    sr = write_sr(tmp_path / "faults.sr", fault_chunks(), trail=0.02)
    theirs = reference(sr, env={"RS30X_DECODERS": ""})
    frames = json.loads("[" + ",".join(subprocess.run(
        [SIGROK_CLI, "-i", str(sr), "-P", "uart:rx=D0:baudrate=115200,rs30x", "-B", "rs30x=frames"],
        env={**os.environ, "SIGROKDECODE_DIR": str(folder)}, capture_output=True, text=True,
        check=True).stdout.splitlines()) + "]")
    missing = [(f["start"], f["end"]) for f, r in zip(frames, theirs) if r.get("status") == "missing"]
    assert len(frames) == len(theirs) and missing
    rows = annotations(sr, folder, "no-reply")
    assert [(ss, es) for ss, es, _ in rows] == missing
    assert all(text.startswith("No reply from ID ") for *_, text in rows)
    bad = annotations(sr, folder, "bad-sum")
    assert len(bad) == sum(1 for r in theirs if r["type"] != "garbage" and r["checksum_ok"] is False) >= 1
    assert all("(bad, should be " in text for *_, text in bad)
    assert not any("bad" in text for *_, text in annotations(sr, folder, "checksum"))
