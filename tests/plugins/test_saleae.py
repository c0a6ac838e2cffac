"""The Saleae Logic 2 extension (`rs30x-sniff plugin saleae`) decodes Async Serial frames as `decode --format jsonl` does.

Logic 2 does not run here: tests/plugins/saleae_stub/ stands in for its ``saleae.analyzers`` module.
"""

from __future__ import annotations

import ast
import contextlib
import importlib.util
import io
import json
import shutil
import sys
from fractions import Fraction
from functools import reduce
from operator import xor
from pathlib import Path

import pytest

from rs30x_sniff.cli import build_parser, main
from rs30x_sniff.commands.common import open_input, settings_for
from rs30x_sniff.decode.decoder import Decoder
from rs30x_sniff.protocol.chunks import marks
from rs30x_sniff.protocol.memmap import default_registry
from rs30x_sniff.protocol.wire import byte_time
from rs30x_sniff.render.records import format_value
from rs30x_sniff.sim import SCENARIOS

ROOT = Path(__file__).resolve().parents[2]
STUB = Path(__file__).with_name("saleae_stub")
SALEAE_CSVS = sorted(ROOT.glob("captures/foreign/saleae-*.csv"))
FRAME_BITS = 9.5  # a Logic 2 Async Serial frame: start bit to the middle of the stop bit


@pytest.fixture(scope="module")
def saleae():
    """The stand-in ``saleae`` package on sys.path (and out of it afterwards)."""
    sys.path.insert(0, str(STUB))
    import saleae.analyzers
    import saleae.data

    yield saleae
    sys.path.remove(str(STUB))
    for name in [n for n in sys.modules if n == "saleae" or n.startswith("saleae.")]:
        del sys.modules[name]


def generate(out: Path) -> str:
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        assert main(["plugin", "saleae", "-o", str(out)]) == 0
    return text.getvalue()


def load(folder: Path, name: str):
    """Import the generated HighLevelAnalyzer.py under a module name of its own."""
    spec = importlib.util.spec_from_file_location(name, folder / "HighLevelAnalyzer.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def plugin(saleae, tmp_path_factory):
    folder = tmp_path_factory.mktemp("saleae") / "rs30x-saleae"
    hint = generate(folder)
    return folder, load(folder, "rs30x_hla_bundled"), hint


# ---- driving the analyzer ---------------------------------------------------------------------------
def serial_frames(saleae, chunks: list, baud: int) -> list:
    """The Async Serial analyzer's frames for our reader's chunks: one per byte, flagged bytes with an error."""
    AnalyzerFrame, GraphTime = saleae.analyzers.AnalyzerFrame, saleae.data.GraphTime
    bt = byte_time(baud)
    frames = []
    for chunk in chunks:
        data, t = chunk
        error = marks(chunk)[1]
        for k, b in enumerate(data):
            start = Fraction(t) + Fraction(k * bt)
            extra = {"error": error.split("-")[0].capitalize()} if error else {}
            frames.append(AnalyzerFrame("data", GraphTime(start), GraphTime(start + Fraction(FRAME_BITS) / baud),
                                        {"data": bytes((b,)), **extra}))
    return frames


def run(saleae, module, frames: list, **settings) -> list:
    hla = saleae.analyzers.make(module.Rs30x, **{"model": module.MODEL_NAMES[0], "gap": 0, **settings})
    out = []
    for fr in frames:
        got = hla.decode(fr)
        assert got is None or isinstance(got, list)
        out += got or []
    return out + hla.flush()


def capture(path: Path):
    """Our reader's chunks of ``path``, its settings, `decode --format jsonl` and our Records of it."""
    args = build_parser().parse_args(["decode", str(path)])
    s = settings_for(args, str(path))
    chunks = list(open_input(str(path), None, s))
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        assert main(["decode", str(path), "--format", "jsonl", "--no-lint"]) == 0
    events = [json.loads(line) for line in text.getvalue().splitlines()]
    dec = Decoder(s.decode_options())
    records = []
    for chunk in chunks:
        records += dec.feed(chunk[0], chunk[1], error=marks(chunk)[1]).expanded()
    records += dec.close().expanded()
    assert [(r.kind, r.offset) for r in records] == [(e["type"], e["offset"]) for e in events]
    return chunks, s, events, records


def field_texts(rec) -> dict:
    long = rec.kind == "long"
    return {(f"{f.id}:{f.label}" if long else f.label): format_value(f) for f in rec.fields}


def check_same(saleae, module, path: Path) -> int:
    chunks, s, events, records = capture(path)
    frames = serial_frames(saleae, chunks, s.baud)
    got = run(saleae, module, frames, model=s.default_model or module.MODEL_NAMES[0])
    assert len(got) == len(events), f"{path.name}: {len(got)} frames, decode has {len(events)}"
    for k, (g, ev, rec) in enumerate(zip(got, events, records)):
        where = f"{path.name}: event {k} (@{ev['offset']})"
        d = g.data
        assert g.type == ev["type"], where
        for key in ("id", "flag", "address", "length", "count"):
            assert d.get(key) == ev[key], (where, key)
        assert d["raw"] == bytes.fromhex(ev["raw"]).hex(" ").upper(), where
        if ev["type"] == "garbage":
            assert d["reason"] == ev["reason"] and "checksum" not in d, where
        else:
            assert d["checksum"] == ("ok" if ev["checksum_ok"] else "bad"), where
            assert d["model"] == ev["model"], where
        assert d["flags"] == ", ".join(ev["flags"]), where
        fields = {key: v for key, v in d.items() if key not in
                  ("summary", "raw", "direction", "id", "flag", "address", "length", "count", "model", "reason",
                   "checksum", "flags", "warnings")}
        assert fields == field_texts(rec), where
        assert d.get("direction") == {"short": "host", "long": "host", "garbage": None}.get(ev["type"], "servo"), where
        assert all(type(v) in (str, int, float, bool) for v in d.values()), where
        # The bubble spans the packet: from its first byte's frame start to its last byte's frame end.
        n = len(bytes.fromhex(ev["raw"]))
        assert (g.start_time, g.end_time) == (frames[ev["offset"]].start_time, frames[ev["offset"] + n - 1].end_time)
    return len(got)


@pytest.mark.parametrize("path", SALEAE_CSVS, ids=lambda p: p.name)
def test_saleae_exports_decode_as_decode_does(saleae, plugin, path: Path) -> None:
    assert check_same(saleae, plugin[1], path) > 30


def test_scenarios_decode_as_decode_does(saleae, plugin, scenario_files: list[Path]) -> None:
    assert len(scenario_files) >= 8
    for path in scenario_files:
        check_same(saleae, plugin[1], path)


def test_the_csvs_hold_flagged_bytes(saleae) -> None:
    """The comparison above meets bytes the analyzer flagged (a framing error), not only clean ones."""
    flagged = [c for p in SALEAE_CSVS for c in capture(p)[0] if marks(c)[1]]
    assert len(flagged) >= 3


def test_an_idle_gap_cuts_a_frame_at_the_next_byte(saleae, plugin) -> None:
    """A request cut short, then silence longer than the gap setting: the cut shows when the next byte comes."""
    AnalyzerFrame, GraphTime = saleae.analyzers.AnalyzerFrame, saleae.data.GraphTime
    module = plugin[1]
    hla = saleae.analyzers.make(module.Rs30x, model=module.MODEL_NAMES[0], gap=1.0)  # 1 ms
    head = bytes.fromhex("faaf010f2a02")
    bt = Fraction(10, 115200)
    out = []
    for k, b in enumerate(head + b"\x07"):
        start = k * bt + (Fraction(2, 1000) if k == len(head) else 0)
        out += hla.decode(AnalyzerFrame("data", GraphTime(start), GraphTime(start + bt * 95 / 100), {"data": bytes((b,))})) or []
    assert [(f.type, f.data["reason"], f.data["raw"]) for f in out] == [("garbage", "truncated", "FA AF 01 0F 2A 02")]
    assert hla.decode(AnalyzerFrame("other", GraphTime(0), GraphTime(0), {})) is None


# ---- the files ------------------------------------------------------------------------------------------
def test_files_are_what_logic2_loads(plugin) -> None:
    folder, module, hint = plugin
    assert sorted(p.name for p in folder.iterdir()) == ["HighLevelAnalyzer.py", "README.md", "extension.json"]
    manifest = json.loads((folder / "extension.json").read_text())
    assert manifest["apiVersion"] == "1.0.0"
    assert {"name", "author", "version", "description"} <= set(manifest)
    (name, ext), = manifest["extensions"].items()
    assert ext["type"] == "HighLevelAnalyzer"
    file, cls = ext["entryPoint"].split(".")
    assert (folder / f"{file}.py").is_file() and isinstance(getattr(module, cls), type)
    assert "extension.json" in hint and "Load Existing Extension" in hint


def test_source_is_python_38_and_imports_only_stdlib_and_saleae(plugin) -> None:
    src = (plugin[0] / "HighLevelAnalyzer.py").read_text(encoding="utf-8")
    tree = ast.parse(src, feature_version=(3, 8))
    imported = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imported |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            imported.add(node.module)
    roots = {m.split(".")[0] for m in imported}
    assert "saleae.analyzers" in imported
    assert roots - {"saleae"} <= set(sys.stdlib_module_names)
    settings = {n.targets[0].id: n.value.func.id for c in tree.body if isinstance(c, ast.ClassDef) and c.name == "Rs30x"
                for n in c.body if isinstance(n, ast.Assign) and isinstance(n.value, ast.Call)}
    assert settings == {"model": "ChoicesSetting", "gap": "NumberSetting"}


def test_settings_list_every_model(plugin) -> None:
    module = plugin[1]
    assert module.Rs30x.model.choices == tuple(m.name for m in [default_registry().default] + [
        m for m in default_registry().models.values() if m is not default_registry().default])


# ---- maps from $RS30X_DECODERS ---------------------------------------------------------------------------
# Texts that would run code if a generator pasted them into its source; {{...}} is Logic 2's template syntax.
HOSTILE = ['"""); open(r"SENTINEL", "w"); ("""', "'''); open(r'SENTINEL', 'w'); ('''", "back\\slash \\", "{{x}} %s {0}"]


def toml_string(text: str) -> str:
    return json.dumps(text)  # a JSON string is a TOML basic string for printable text


def user_map(tmp_path: Path, name: str, number: int, edit) -> Path:
    d = tmp_path / "decoders"
    d.mkdir(exist_ok=True)
    text = (ROOT / "decoders" / "rs303mr.toml").read_text(encoding="utf-8")
    text = text.replace('name = "RS303MR"', f'name = "{name}"', 1)
    text = text.replace("model_number = 0x3030", f"model_number = {number:#06x}", 1)
    (d / f"{name.lower()}.toml").write_text(edit(text), encoding="utf-8")
    return d


@pytest.fixture
def decoders_env(monkeypatch):
    """Set $RS30X_DECODERS for one test, the registry read afresh before and after it."""
    def use(folder: Path) -> None:
        monkeypatch.setenv("RS30X_DECODERS", str(folder))
        default_registry.cache_clear()
    yield use
    monkeypatch.delenv("RS30X_DECODERS", raising=False)
    default_registry.cache_clear()


def frames_of(saleae, raw: bytes) -> list:
    AnalyzerFrame, GraphTime = saleae.analyzers.AnalyzerFrame, saleae.data.GraphTime
    bt = Fraction(10, 115200)
    return [AnalyzerFrame("data", GraphTime(k * bt), GraphTime(k * bt + bt * 95 / 100), {"data": bytes((b,))})
            for k, b in enumerate(raw)]


def ret(sid: int, address: int, data: bytes) -> bytes:
    body = bytes((sid, 0, address, len(data), 1)) + data
    return b"\xfd\xdf" + body + bytes((reduce(xor, body, 0),))


def test_a_hostile_map_is_only_data(saleae, tmp_path, decoders_env, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)  # an enum label holds at most 64 characters: its sentinel is a relative name
    sentinel = tmp_path / "pwned"
    texts = [t.replace("SENTINEL", "pwned") for t in HOSTILE]
    description = HOSTILE[0].replace("SENTINEL", str(sentinel))

    def edit(text: str) -> str:
        text = text.replace('enum = { 0 = "normal", 1 = "reverse" }',
                            f"enum = {{ 0 = {toml_string(texts[0])}, 1 = {toml_string(texts[1])} }}", 1)
        text = text.replace('enum = { 0 = "off", 1 = "hold", 2 = "brake" }',
                            f"enum = {{ 0 = {toml_string(texts[2])}, 1 = {toml_string(texts[3])}, 2 = \"brake\" }}", 1)
        return text.replace('description = "Board temperature"', f"description = {toml_string(description)}", 1)

    decoders_env(user_map(tmp_path, "EVIL1", 0x4242, edit))
    folder = tmp_path / "evil-saleae"
    generate(folder)
    module = load(folder, "rs30x_hla_evil")
    assert not sentinel.exists()
    assert "EVIL1" in module.MODEL_NAMES
    reverse = [r for m in module.MAPS["models"] if m["name"] == "EVIL1" for r in m["registers"] if r["name"] == "reverse"]
    assert reverse[0]["enum"] == {0: texts[0], 1: texts[1]}
    assert [r["description"] for m in module.MAPS["models"] if m["name"] == "EVIL1" for r in m["registers"]
            if r["name"] == "present_temperature"] == [description]
    out = run(saleae, module, frames_of(saleae, ret(1, 5, b"\x00") + ret(1, 5, b"\x01")), model="EVIL1")
    assert [f.data["reverse"] for f in out] == texts[:2]
    assert not sentinel.exists()
    src = (folder / "HighLevelAnalyzer.py").read_text(encoding="utf-8")
    tree = ast.parse(src, feature_version=(3, 8))  # still one valid module, in which no code opens a file:
    assert not [n for n in ast.walk(tree) if isinstance(n, ast.Call) and getattr(n.func, "id", None) == "open"]
    maps = [n.value for n in tree.body if isinstance(n, ast.Assign) and getattr(n.targets[0], "id", None) == "MAPS"]
    assert ast.literal_eval(maps[0]) == module.MAPS  # the hostile texts are inside the one literal


def test_a_user_map_with_a_bundled_name_replaces_it(saleae, tmp_path, decoders_env) -> None:
    decoders_env(user_map(tmp_path, "RS303MR", 0x3030,
                          lambda text: text.replace('name = "present_temperature"', 'name = "case_temperature"', 1)))
    folder = tmp_path / "renamed-saleae"
    generate(folder)
    module = load(folder, "rs30x_hla_renamed")
    out = run(saleae, module, frames_of(saleae, ret(1, 50, (45).to_bytes(2, "little"))), model="RS303MR")
    assert [f.data.get("case_temperature") for f in out] == ["45degC"]
    assert "present_temperature" not in out[0].data
    shutil.rmtree(folder)
