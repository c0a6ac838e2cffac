"""The Wireshark dissector `rs30x-sniff plugin wireshark` writes: run by tshark on `convert -o x.pcapng` files, it
agrees with `decode --format jsonl` frame by frame, and hostile maps stay data."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from rs30x_sniff.cli import main
from rs30x_sniff.plugins.maps import plugin_maps
from rs30x_sniff.plugins.wireshark import generate, install_hint, lua_value
from rs30x_sniff.protocol import wire
from rs30x_sniff.sim import SCENARIOS
from tests.conftest import CAPTURES
from tests.plugins.user_maps import toml_string, write_user_maps

TSHARK = shutil.which("tshark")
needs_tshark = pytest.mark.skipif(TSHARK is None, reason="tshark is not installed (apt-get install tshark)")


def write_plugin(folder: Path, maps: dict) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for rel, text in generate(maps).items():
        (folder / rel).parent.mkdir(parents=True, exist_ok=True)
        (folder / rel).write_text(text, encoding="utf-8")
    return folder / "rs30x.lua"


# tshark reads the user's personal folders (plug-ins, preferences, profiles): a dissector installed there as
# docs/integrations.md says would register the protocol twice ("there cannot be two protocols"). Every tshark
# here runs with a HOME and XDG folders of its own (own_home), and none of Wireshark's folder overrides.
OWN_HOME: dict[str, str] = {}
WIRESHARK_OVERRIDES = ("WIRESHARK_CONFIG_DIR", "WIRESHARK_PLUGIN_DIR", "WIRESHARK_DATA_DIR", "WIRESHARK_EXTCAP_DIR")


@pytest.fixture(scope="module", autouse=True)
def own_home(tmp_path_factory):
    """A fresh HOME (and XDG config, data and cache folders under it) for every tshark this module runs."""
    home = tmp_path_factory.mktemp("home")
    OWN_HOME.update(HOME=str(home), XDG_CONFIG_HOME=str(home / ".config"), XDG_DATA_HOME=str(home / ".local/share"),
                    XDG_CACHE_HOME=str(home / ".cache"))
    yield home
    OWN_HOME.clear()


def tshark_env(env: dict | None = None) -> dict[str, str]:
    assert OWN_HOME, "own_home sets the HOME tshark runs with"
    base = {k: v for k, v in os.environ.items() if k not in WIRESHARK_OVERRIDES}
    return {**base, **OWN_HOME, **(env or {})}


def tshark(lua: Path | None, pcapng: Path, *args: str, env: dict | None = None) -> str:
    cmd = [TSHARK, "-n", "-r", str(pcapng), *args]
    if lua is not None:
        cmd[1:1] = ["-X", f"lua_script:{lua}"]
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=120, env=tshark_env(env))
    assert run.returncode == 0, run.stderr
    assert "Lua: Error" not in run.stderr and "lua_script" not in run.stderr, run.stderr
    return run.stdout


def walk(node, out: list[tuple[str, object]]) -> list[tuple[str, object]]:
    """Every (field, value) under a tshark JSON tree, in order (lists of merged duplicate keys flattened)."""
    if isinstance(node, dict):
        for k, v in node.items():
            if isinstance(v, list):
                for x in v:
                    if isinstance(x, dict):
                        walk(x, out)
                    else:
                        out.append((k, x))
            elif isinstance(v, dict):
                walk(v, out)
            else:
                out.append((k, v))
    return out


def dissected(lua: Path, pcapng: Path) -> list[list[tuple[str, object]]]:
    """Each packet's rs30x fields as tshark shows them (JSON, the rs30x tree with its children)."""
    text = tshark(lua, pcapng, "-T", "json", "--no-duplicate-keys", "-J", "rs30x")
    return [walk(p["_source"]["layers"].get("rs30x", {}), []) for p in json.loads(text)]


def field_name(reg_name: str) -> str:
    return "rs30x." + reg_name


class Maps:
    """What the test reads of the maps to turn tshark's displayed values back into decode's (enum labels)."""

    def __init__(self, maps: dict) -> None:
        self.names = {r["name"] for m in maps["models"] for r in m["registers"] if r["name"]}
        self.enums = {(m["name"], r["name"]): r["enum"] for m in maps["models"] for r in m["registers"]
                      if r["name"] and r["enum"]}


def ours(packet: list[tuple[str, object]], maps: Maps) -> dict:
    """One packet of tshark's output in decode's terms."""
    one = {}
    for k, v in packet:
        one.setdefault(k, v)
    model = one.get("rs30x.model")
    fields = []
    for k, v in packet:
        name = k[len("rs30x."):]
        if k.startswith("rs30x.") and name in maps.names:
            enum = maps.enums.get((model, name))
            number = float(int(v, 16)) if v.startswith("0x") else float(v)
            value = number if enum is None else enum.get(int(number), int(number))
            fields.append((name, value))
    kind = one["rs30x.kind"]
    out = {"type": kind, "id": None if "rs30x.id" not in one else int(one["rs30x.id"]), "fields": fields}
    if kind in ("short", "long", "return"):
        out.update(flag=int(one["rs30x.flag"], 16), address=int(one["rs30x.address"]),
                   length=int(one["rs30x.length"]), count=int(one["rs30x.count"]),
                   checksum_ok=one["rs30x.checksum_status"] == "1")
        if kind == "short":
            out["op"] = one["rs30x.op"]
    return out


def theirs(rec: dict) -> dict:
    """One record of `decode --format jsonl` in the same terms."""
    fields = [(f["name"], f["value"] if isinstance(f["value"], str) else float(f["value"]))
              for f in rec["fields"] if f["name"] is not None and "partial" not in f and f["value"] is not None]
    kind = rec["type"]
    out = {"type": kind, "id": rec["id"], "fields": fields}
    if kind in ("short", "long", "return"):
        out.update({k: rec[k] for k in ("flag", "address", "length", "count", "checksum_ok")})
        if kind == "short":
            out["op"] = rec["op"]
    return out


def same(a: dict, b: dict) -> bool:
    """Equal, the values of fields to 6 decimals (what decode's JSON keeps)."""
    fa, fb = a["fields"], b["fields"]
    if {k: v for k, v in a.items() if k != "fields"} != {k: v for k, v in b.items() if k != "fields"}:
        return False
    return len(fa) == len(fb) and all(
        na == nb and (va == vb if isinstance(va, str) or isinstance(vb, str) else abs(va - vb) <= 1e-6)
        for (na, va), (nb, vb) in zip(fa, fb))


# ---- the inputs -----------------------------------------------------------------------------------
def input_files(scenario_files: list[Path]) -> dict[str, Path]:
    """Every bundled capture, the manual's examples and each simulator scenario (conftest's scenario_files)."""
    files = {str(p.relative_to(CAPTURES)): p for p in
             [*sorted(CAPTURES.glob("*.hex")), *sorted(CAPTURES.glob("*.thex")),
              *sorted((CAPTURES / "lint").iterdir())] if p.is_file()}
    files.update({f"sim:{p.stem}": p for p in scenario_files})
    return files


@pytest.fixture(scope="module")
def plugin(tmp_path_factory):
    saved = os.environ.pop("RS30X_DECODERS", None)  # the bundled maps only, as `decode` below reads them
    try:
        maps = plugin_maps()
    finally:
        if saved is not None:
            os.environ["RS30X_DECODERS"] = saved
    return write_plugin(tmp_path_factory.mktemp("plugin") / "rs30x", maps), Maps(maps)


@pytest.fixture(scope="module")
def converted(tmp_path_factory, scenario_files):
    """name -> (pcapng, decode's records, the input) for every input, converted and decoded in process."""
    tmp = tmp_path_factory.mktemp("converted")
    out = {}
    for k, (name, path) in enumerate(input_files(scenario_files).items()):
        pcapng, jsonl = tmp / f"{k}.pcapng", tmp / f"{k}.jsonl"
        assert main(["convert", str(path), "-o", str(pcapng), "--isolated"]) == 0
        assert main(["decode", str(path), "--format", "jsonl", "-o", str(jsonl), "--isolated"]) == 0
        records = [json.loads(line) for line in jsonl.read_text().splitlines()]
        out[name] = (pcapng, [r for r in records if r.get("type") != "diagnostic"], path)
    return out


@pytest.fixture(scope="module")
def dissections(plugin, converted):
    """name -> tshark's packets, the runs two at a time."""
    lua, _ = plugin
    with ThreadPoolExecutor(2) as pool:
        runs = {name: pool.submit(dissected, lua, pcapng) for name, (pcapng, *_) in converted.items()}
        return {name: run.result() for name, run in runs.items()}


# ---- the differential test ------------------------------------------------------------------------
@needs_tshark
def test_every_input_is_dissected_as_decode_reads_it(plugin, converted, dissections):
    _, maps = plugin
    assert len(converted) >= 40 + len(SCENARIOS)
    differ = []
    for name, (_, records, _) in converted.items():
        packets = dissections[name]
        assert len(packets) == len(records), name
        for k, (p, rec) in enumerate(zip(packets, records)):
            a, b = ours(p, maps), theirs(rec)
            if not same(a, b):
                differ.append(f"{name} frame {k + 1}: tshark {a} / decode {b}")
    assert not differ, "\n".join(differ[:10])


@needs_tshark
def test_the_inputs_hold_every_kind_and_many_registers(converted):
    """The differential test above means something: every kind of packet and many registers are in it."""
    kinds = {r["type"] for _, recs, _ in converted.values() for r in recs}
    assert kinds >= {"short", "long", "return", "ack", "nack", "garbage"}
    names = {f["name"] for _, recs, _ in converted.values() for r in recs for f in r["fields"] if f["name"]}
    assert {"present_temperature", "goal_position", "torque_enable", "present_voltage"} <= names


@needs_tshark
def test_a_reply_names_its_request_as_decode_pairs_them(plugin, converted):
    lua, _ = plugin
    pcapng, records, _ = converted["sim:hexapod"]
    text = tshark(lua, pcapng, "-2", "-T", "fields", "-e", "frame.number", "-e", "rs30x.request",
                  "-e", "rs30x.response")
    rows = [line.split("\t") for line in text.splitlines()]
    frame_of = {r["offset"]: k + 1 for k, r in enumerate(records)}
    expect_request = [str(frame_of[r["reply_to"]]) if r["reply_to"] is not None else "" for r in records]
    expect_reply = [str(frame_of[r["reply"]]) if r.get("reply") is not None else "" for r in records]
    assert [row[1] for row in rows] == expect_request
    assert [row[2] for row in rows] == expect_reply
    assert sum(1 for x in expect_request if x) > 20


@needs_tshark
def test_a_display_filter_selects_what_decode_filter_selects(plugin, converted, tmp_path):
    lua, _ = plugin
    pcapng, records, path = converted["sim:overheat"]
    text = tshark(lua, pcapng, "-Y", "rs30x.id == 2 && rs30x.present_temperature > 60", "-T", "fields",
                  "-e", "frame.number")
    got = [int(x) for x in text.split()]
    out = tmp_path / "f.jsonl"
    assert main(["decode", str(path), "--format", "jsonl", "--filter", "id:2 present_temperature>60",
                 "-o", str(out), "--isolated"]) == 0
    frame_of = {r["offset"]: k + 1 for k, r in enumerate(records)}
    want = [frame_of[json.loads(line)["offset"]] for line in out.read_text().splitlines()
            if json.loads(line).get("type") != "diagnostic"]
    assert want and got == want


@needs_tshark
def test_expert_info_on_bad_sums_cut_frames_and_noise(plugin, converted):
    lua, _ = plugin
    seen = {}
    for name in ("lint/F001-checksum-mismatch.hex", "lint/F003-truncated-frame.thex", "lint/F002-garbage-bytes.hex"):
        text = tshark(lua, converted[name][0], "-T", "fields", "-e", "_ws.expert.message",
                      "-e", "_ws.expert.severity", "-e", "_ws.expert.group")
        seen[name] = {item for line in text.splitlines() if line.strip()
                      for item in zip(*(column.split(",") for column in line.split("\t")))}
    # Severity and group numbers are Wireshark's PI_ERROR (8388608), PI_WARN (6291456), PI_CHECKSUM (16777216),
    # PI_MALFORMED (117440512), PI_PROTOCOL (150994944).
    assert ("Bad checksum", "8388608", "16777216") in seen["lint/F001-checksum-mismatch.hex"]
    assert ("Cut frame", "8388608", "117440512") in seen["lint/F003-truncated-frame.thex"]
    assert ("Noise or garbage bytes", "6291456", "150994944") in seen["lint/F002-garbage-bytes.hex"]


# ---- maps from $RS30X_DECODERS --------------------------------------------------------------------
@pytest.fixture(scope="module")
def user_maps(tmp_path_factory):
    """$RS30X_DECODERS with a hostile model EVIL1 (code-like enum labels and descriptions) and an RS303MR whose
    present_temperature is renamed case_temperature; the sentinel file the hostile text would create."""
    folder = tmp_path_factory.mktemp("maps")
    sentinel = Path(f"/tmp/pwned{os.getpid()}")  # short: a label is at most 64 characters
    sentinel.unlink(missing_ok=True)
    evil = f'"); os.execute("touch {sentinel}") --'
    labels = {"off": "]]", "on": evil, "brake": "back\\slash \\ 'quote' \"dq\" ]=] é"}

    def edit(hostile: str) -> str:
        assert hostile.count(toml_string(evil)[1:-1]) == 2
        # A register named like a header field (rs30x.count) gets a field of its own name, rs30x.reg_count.
        return hostile.replace('name = "present_temperature"', 'name = "count"')

    write_user_maps(folder, labels, evil + " ]] [[ " + chr(92), edit)
    return folder, sentinel, labels


def cli(*argv: str, env: dict) -> None:
    run = subprocess.run([sys.executable, "-m", "rs30x_sniff", *argv], capture_output=True, text=True,
                         timeout=120, env={**os.environ, **env})
    assert run.returncode == 0, run.stderr


@pytest.fixture(scope="module")
def user_run(user_maps, tmp_path_factory):
    """The plug-in made with the user's maps, and a pcapng of torque_enable writes and a temperature read."""
    folder, sentinel, labels = user_maps
    env = {"RS30X_DECODERS": str(folder)}
    tmp = tmp_path_factory.mktemp("user")
    cli("plugin", "wireshark", "-o", str(tmp / "plugin"), env=env)
    bus = [wire.encode_short(1, 0, 36, bytes([k])) for k in (0, 1, 2)]
    bus += [wire.encode_read(1, 50, 2), wire.encode_return(1, 50, (41).to_bytes(2, "little"))]
    capture = tmp / "bus.hex"
    capture.write_text("\n".join(frame.hex(" ") for frame in bus) + "\n")
    pcapngs = {}
    for model in ("EVIL1", "RS303MR"):
        pcapngs[model] = tmp / f"{model}.pcapng"
        cli("convert", str(capture), "--model", model, "-o", str(pcapngs[model]), "--isolated", env=env)
    return tmp / "plugin" / "rs30x.lua", pcapngs


@needs_tshark
def test_hostile_labels_load_as_data_and_show_verbatim(user_maps, user_run):
    folder, sentinel, labels = user_maps
    lua, pcapngs = user_run
    source = lua.read_text()
    assert "os.execute" in source and 'os.execute("' not in source  # the quote is escaped, never code
    text = tshark(lua, pcapngs["EVIL1"], "-T", "pdml")
    assert not sentinel.exists()
    import xml.etree.ElementTree as ET
    shown = [f.get("showname") for f in ET.fromstring(text).iter("field") if f.get("name") == "rs30x.torque_enable"]
    assert shown == [f"torque_enable: {labels[k]} ({n})" for n, k in enumerate(("off", "on", "brake"))]
    assert not sentinel.exists()


@needs_tshark
def test_a_register_named_like_a_header_field_gets_its_own_field(user_run):
    lua, pcapngs = user_run
    text = tshark(lua, pcapngs["EVIL1"], "-Y", "rs30x.reg_count == 41", "-T", "fields", "-e", "frame.number",
                  "-e", "rs30x.count")
    assert text.split("\n")[0].split("\t") == ["5", "1"]  # the return's Count byte is 1


@needs_tshark
def test_the_model_preference_decodes_with_the_map_it_names(plugin, converted):
    lua, _ = plugin
    pcapng, records, _ = converted["manual-examples.hex"]
    for model in ("RS304MD", "RS303MR"):
        text = tshark(lua, pcapng, "-o", f"rs30x.model:{model}", "-T", "fields", "-e", "rs30x.model")
        assert {x for x in text.split("\n") if x} == {model}


@needs_tshark
def test_a_user_map_replaces_the_bundled_model_of_its_name(user_run):
    lua, pcapngs = user_run
    text = tshark(lua, pcapngs["RS303MR"], "-Y", "rs30x.case_temperature == 41", "-T", "fields",
                  "-e", "frame.number", "-e", "rs30x.case_temperature", "-e", "rs30x.present_temperature")
    assert text.split("\n")[0].split("\t") == ["5", "41", ""]


# ---- the generator --------------------------------------------------------------------------------
def test_lua_value_keeps_strings_as_data():
    text = lua_value({"a": ['"]] --', None, 1.5], 3: {"x": None}, "b": True})
    assert text == ('{\n ["a"] = {\n  "\\034]] --",\n  false,\n  1.5,\n },\n [3] = {},\n ["b"] = true,\n}')
    with pytest.raises(ValueError):
        lua_value(float("inf"))
    with pytest.raises(ValueError):
        lua_value({1.5: 1})


def test_install_hint_names_the_personal_lua_folder_and_the_one_run_form():
    hint = install_hint(Path("out"))
    assert "~/.local/lib/wireshark/plugins/" in hint
    assert "tshark -X lua_script:out/rs30x.lua -r OUT.pcapng" in hint


@needs_tshark
def test_the_personal_lua_folder_is_where_the_hint_says(own_home):
    run = subprocess.run([TSHARK, "-G", "folders"], capture_output=True, text=True, timeout=60, env=tshark_env())
    folders = dict(line.split(":", 1) for line in run.stdout.splitlines() if ":" in line)
    assert folders["Personal Lua Plugins"].strip() == str(own_home / ".local/lib/wireshark/plugins")


@needs_tshark
def test_a_dissector_installed_in_the_users_home_is_not_read(plugin, converted, own_home, monkeypatch, tmp_path):
    """The user's HOME may hold the plug-in, installed as docs/integrations.md says: the tests above run beside it
    (here, a HOME holding it, as the user's would, and a WIRESHARK_PLUGIN_DIR pointing at it)."""
    lua, _ = plugin
    users = tmp_path / "users-home"
    installed = users / ".local/lib/wireshark/plugins"
    installed.mkdir(parents=True)
    (installed / "rs30x.lua").write_text(lua.read_text())
    monkeypatch.setenv("HOME", str(users))
    monkeypatch.setenv("WIRESHARK_PLUGIN_DIR", str(installed))
    pcapng = converted["manual-examples.hex"][0]
    bare = subprocess.run([TSHARK, "-n", "-r", str(pcapng), "-X", f"lua_script:{lua}"], capture_output=True,
                          text=True, timeout=120, env={**os.environ, "XDG_CONFIG_HOME": str(users / ".config")})
    assert "two protocols" in bare.stderr  # what the test would meet with the user's own HOME
    text = tshark(lua, pcapng, "-T", "fields", "-e", "rs30x.kind")
    assert text.split()
