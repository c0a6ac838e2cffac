"""The family's maps (RS301CR, RS302CD, RS204MD, RS405CB/RS406CB) held to the tables of docs/futaba-family.md,
the sourced facts they are written from (issue 34), as the RS303MR/RS304MD maps are held to their manual."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest

from rs30x_sniff.protocol.memmap import ModelError, default_registry, load_model
from rs30x_sniff.protocol.wire import RETURN_FLAG_BITS
from rs30x_sniff.schemas import memory_map_schema
from rs30x_sniff.schemas.check import first_failure

ROOT = Path(__file__).resolve().parents[2]
SPEC = ROOT / "docs" / "futaba-family.md"
SHARED = ROOT.parent / "shared" / "spec" / "futaba-family.md"  # the research notes the copy is taken from
FILES = {"RS301CR": "rs301cr.toml", "RS302CD": "rs302cd.toml", "RS204MD": "rs204md.toml", "RS405CB": "rs405cb.toml"}
SECTIONS = {"RS301CR": "1", "RS302CD": "1", "RS204MD": "2", "RS405CB": "3", "RS406CB": "3"}
FAMILY = list(SECTIONS)


# ---- reading the notes --------------------------------------------------------------------------------------
def sections() -> dict[str, str]:
    """Each "## N." section's text by N."""
    parts = re.split(r"^## (\d+)\. ", SPEC.read_text(encoding="utf-8"), flags=re.M)
    return dict(zip(parts[1::2], parts[2::2]))


def table(text: str) -> list[dict[str, str]]:
    """The section's first table: one dict per row, by column title, bold marks taken out."""
    lines = [ln for ln in text.splitlines() if ln.startswith("|")]
    cells = [[c.strip().replace("**", "") for c in ln.strip().strip("|").split("|")] for ln in lines]
    head, rows = cells[0], cells[2:]
    return [dict(zip(head, row)) for row in rows]


# A row's name as the notes write it -> the registers it covers, in address order.
NAMES = {
    "cw/ccw_compliance_margin": ["cw_compliance_margin", "ccw_compliance_margin"],
    "cw/ccw_compliance_slope": ["cw_compliance_slope", "ccw_compliance_slope"],
    "compliance margin": ["cw_compliance_margin", "ccw_compliance_margin"],
    "compliance slope": ["cw_compliance_slope", "ccw_compliance_slope"],
    "compliance": ["cw_compliance_margin", "ccw_compliance_margin", "cw_compliance_slope", "ccw_compliance_slope"],
    "present_load (current)": ["present_current"],
    "cw/ccw angle limit": ["cw_angle_limit", "ccw_angle_limit"],
    "torque_in_silence / warm_up_time": ["torque_in_silence", "warm_up_time"],
    "goal position/time": ["goal_position", "goal_time"],
    "goal position / time": ["goal_position", "goal_time"],
    "present pos/time/speed/current/temp/volts": ["present_position", "present_time", "present_speed",
                                                  "present_current", "present_temperature", "present_voltage"],
}
# A unit as the notes write it -> (scale, unit, offset) of the map.
UNITS = {
    "0.1°": (0.1, "deg", 0), '"about 0.1°"': (0.1, "deg", 0), "1°": (1, "deg", 0), "10 ms": (0.01, "s", 0),
    "°C": (1, "degC", 0), "deg/s": (1, "deg/s", 0), "mA": (1, "mA", 0), "10 mV": (0.01, "V", 0),
    "1 %": (1, "%", 0), "0.01 %": (0.01, "%", 0), "% (64H = 100 %)": (1, "%", 0),
    "100 µs + 50 µs×n": (50, "us", 100),
    "conflict": (0.01, "%", 0),  # RS204MD's punch: the manual's example (1 % = 100) is taken
}
# The libraries the notes cite -> the source keys of the maps.
LIBRARIES = {"ZMP": "zmp-header", "pyFutabaServo": "pyfutabaservo", "RS20X30Xlib": "rs20x30xlib", "pyfrs": "pyfrs",
             "M5Stack_RSTester": "m5stack-rstester", "isri": "isri", "lastVIZSLA": "lastvizsla", "gs2d": "gs2d",
             "javatea": "javatea", "pyrs": "pyrs", "CmdServo": "cmdservo", "Shimada": "shimada"}


def number(text: str) -> int:
    """A number as the notes write it: 64H and 0A are hexadecimal, 1300 decimal, 0x05DC too."""
    text = text.strip()
    if text.lower().startswith("0x"):
        return int(text, 16)
    if text.endswith("H") or re.search(r"[A-F]", text):
        return int(text.rstrip("H"), 16)
    return int(text)


def addresses(cell: str) -> tuple[int, int]:
    """First and last address of a row: 0-1, 24/25, 22 / 23, 38."""
    found = [int(n) for n in re.findall(r"\d+", cell)]
    return found[0], found[-1]


def units(cell: str, n: int) -> list[tuple[float, str, float] | None]:
    """The (scale, unit, offset) of each of a row's ``n`` registers, None where the notes give no unit."""
    parts = [p for p in re.split(r",\s*|\s+/\s+", cell) if p]
    if not parts or len(parts) > n or n % len(parts):
        return [None] * n
    return [UNITS.get(p) for p in parts for _ in range(n // len(parts))]


def defaults(cell: str, model: str) -> int | None | str:
    """The factory value a row gives the model: a number, None ("default unknown"), or "none" (not said)."""
    m = re.search(r"default ([^;]*)", cell)
    if m is None:
        return "none"
    said = m.group(1).strip()
    if said.startswith("unknown"):
        return None
    for piece in said.split(", "):
        named = re.findall(r"RS\d{3}[A-Z]{2}", piece)
        if not named or model in named:
            return number(piece.split()[0])
    return "none"


def ranges(cell: str, regs: list) -> list[tuple[int, int] | None]:
    """The settable range a row gives each of its registers; None where it gives none."""
    n = len(regs)
    if re.fullmatch(r"\d+ \w+(, \d+ \w+)+", cell):  # 0 off, 1 on, 2 brake
        return [(0, max(int(x) for x in re.findall(r"\d+", cell)))] * n
    head = re.split(r"[,;]", cell)[0].strip()
    if m := re.match(r"([0-9A-F]+H?)-([0-9A-F]+H?)\b", head):
        return [(number(m.group(1)), number(m.group(2)))] * n
    if re.fullmatch(r"(\d+H?)( \w+)?( ?/ ?\d+H?( \w+)?)+", head):  # 0/1/2, 00H/01H, 0 normal / 1 reverse
        return [(0, max(number(x) for x in re.findall(r"\d+H?", head)))] * n
    if m := re.fullmatch(r"±(\d+)", head):
        top = int(m.group(1))
        if [r.name for r in regs] == ["cw_angle_limit", "ccw_angle_limit"]:
            return [(0, top), (-top, 0)]
        return [(-top, top) if r.unit == "deg" else None for r in regs]
    sides = re.findall(r"0…([+-])(\d+)(°?)", head if "/" not in head else cell)
    if sides and len(sides) in (1, n):
        out = []
        for sign, size, deg in sides * (n // len(sides)):
            top = int(size) * (10 if deg else 1)
            out.append((0, top) if sign == "+" else (-top, 0))
        return out
    return [None] * n


def reading(row: dict[str, str]) -> str:
    """A row's range and default as the map takes them: where the sources conflict, the manual's reading."""
    cell = row["Range / default"]
    if "conflict" not in row["Unit / scale"]:
        return cell
    return next(piece for piece in cell.split(";") if piece.strip().startswith("manual"))


def rows(model: str) -> list[tuple[dict[str, str], list]]:
    """The model's table rows (model number aside) with the registers of its map each covers, in order."""
    m = default_registry().get(model)
    out = []
    for row in table(sections()[SECTIONS[model]]):
        first, last = addresses(row["Addr"])
        if row["Name"] == "reserved":
            out.append((row, [m.register_at(a) for a in range(first, last + 1)]))
            continue
        names = NAMES.get(row["Name"], [row["Name"]])
        out.append((row, [m.register(n) for n in names]))
    return out


# ---- the copy and the files ----------------------------------------------------------------------------------
@pytest.mark.skipif(not SHARED.exists(), reason="the shared research notes are not beside this tree")
def test_the_copy_of_the_notes_is_the_notes():
    assert SPEC.read_text(encoding="utf-8") == SHARED.read_text(encoding="utf-8")


@pytest.mark.parametrize("model", FILES)
def test_each_map_passes_the_schema(model):
    doc = tomllib.loads((ROOT / "decoders" / FILES[model]).read_text(encoding="utf-8"))
    assert first_failure(doc, memory_map_schema()) is None
    load_model(ROOT / "decoders" / FILES[model])


def test_the_registry_knows_the_family():
    assert set(FAMILY) | {"RS303MR", "RS304MD"} <= set(default_registry().models)


# ---- section 0: model numbers ---------------------------------------------------------------------------------
def test_model_numbers_are_the_notes_and_none_is_guessed():
    reg = default_registry()
    seen = set()
    for row in table(sections()["0"]):
        value = row["u16 value"]
        names = re.findall(r"RS\d{3}[A-Z]{2}", row["Model"])
        for name in names:
            if name.upper() not in reg.models:
                assert value == "unknown", name  # a model without a map is one the notes know nothing of
                continue
            m = reg.get(name)
            seen.add(name)
            if value == "unknown":
                assert m.model_number is None and m.register("model_number").default is None
            else:
                value = re.match(r"0x[0-9A-F]{4}", value).group(0)  # 0x2040 ("20 40 means RS204MD")
                assert m.model_number == number(value) and reg.by_number[number(value)].name == name
                assert m.register("model_number").default == number(value)
    assert set(FAMILY) <= seen
    assert {hex(n): m.name for n, m in reg.by_number.items() if m.name in FAMILY} == {
        "0x3010": "RS301CR", "0x3020": "RS302CD", "0x2040": "RS204MD"}


def test_rs406cb_is_rs405cbs_map_under_its_own_name():
    reg = default_registry()
    a, b = reg.get("RS405CB"), reg.get("rs406cb")
    assert b.name == "RS406CB" and b is not a
    assert b.registers == a.registers and b.behaviour == a.behaviour and b.sources == a.sources
    assert (a.model_number, b.model_number) == (None, None)
    assert a.top_speed_s_per_60deg is None and b.top_speed_s_per_60deg is None


# ---- sections 1-3: each row of each table -------------------------------------------------------------------
@pytest.mark.parametrize("model", FAMILY)
def test_every_address_0_to_59_is_described_once(model):
    m = default_registry().get(model)
    covered = sorted(a for r in m.registers for a in range(r.address, r.address + r.size))
    assert covered == list(range(60))


@pytest.mark.parametrize("model", FAMILY)
def test_each_row_places_its_registers(model):
    for row, regs in rows(model):
        first, last = addresses(row["Addr"])
        if row["Name"] == "reserved":
            assert all(r.reserved and r.name is None for r in regs), row
            continue
        at = first
        for r in regs:  # the row's registers follow one another from its first address to its last
            assert r.address == at, (row, r.name)
            at += r.size
        assert at == last + 1, row
        size = row["Size"]
        if "s16" in size:
            assert all(r.size == 2 and r.signed for r in regs), row
        elif m := re.fullmatch(r"(\d) each", size):
            assert all(r.size == int(m.group(1)) for r in regs), row
        elif size.isdigit() and len(regs) == 1:
            assert regs[0].size == int(size), row
        for r in regs:  # a sign the notes do not give (s16, a negative range) says where it is from
            if r.signed and "s16" not in size and not (r.range and r.range[0] < 0):
                assert "signed" in r.note, (model, r.name)


@pytest.mark.parametrize("model", FAMILY)
def test_each_row_has_its_access(model):
    for row, regs in rows(model):
        access = row["Access"] or "-"  # a reserved span may leave it blank
        want = {"R": "read", "RW": "read-write", "-": "reserved"}[access.split()[0]]
        assert all(r.access == want for r in regs), row
        if "conflict" in access:
            assert all("conflict" in r.note for r in regs), row


@pytest.mark.parametrize("model", FAMILY)
def test_each_row_has_its_unit(model):
    for row, regs in rows(model):
        if row["Name"] == "reserved":
            continue
        cell = row["Unit / scale"]
        for r, unit in zip(regs, units(cell, len(regs))):
            if unit is not None:
                assert (r.scale, r.unit, r.offset) == unit, (row, r.name)
            if "conflict" in cell:
                assert "conflict" in r.note, r.name
        if cell == "hex":
            assert all(r.format == "hex" for r in regs)
        if cell == "code":
            assert all(r.table for r in regs)
        if cell == "enum":
            assert all(r.enum for r in regs)
        if "PWM" in cell:
            assert all(r.mode == "pwm" for r in regs)
        if "unit unknown" in cell:
            assert all(r.unit is None for r in regs)


@pytest.mark.parametrize("model", FAMILY)
def test_defaults_only_where_a_source_gives_them(model):
    m = default_registry().get(model)
    for row, regs in rows(model):
        if row["Name"] == "reserved":
            continue
        for r in regs:
            if r.name == "model_number":
                assert r.default == m.model_number
                continue
            want = defaults(reading(row), model)
            assert r.default == (None if want == "none" else want), (model, r.name)


@pytest.mark.parametrize("model", FAMILY)
def test_settable_ranges_are_the_notes(model):
    for row, regs in rows(model):
        if row["Name"] == "reserved":
            continue
        for r, want in zip(regs, ranges(reading(row), regs)):
            if r.writable:
                assert r.range == want, (model, r.name)


@pytest.mark.parametrize("model", FAMILY)
def test_a_fact_from_elsewhere_than_the_main_source_names_its_source(model):
    m = default_registry().get(model)
    keys = {s.key for s in m.sources}
    assert "manual" in keys and all(s.title for s in m.sources)
    for r in m.registers:  # every source a register names is one of its map's
        cited = [k.strip() for k in r.source.split(",")] if r.source else []
        assert set(cited) <= keys, (model, r.label, cited)
    for row, regs in rows(model):
        said = row["Source"] + " " + row["Range / default"]
        libraries = {key for lib, key in LIBRARIES.items() if re.search(rf"\b{lib}", said)}
        main = re.match(r"(manual|p\.\d|same page|—)", row["Source"]) is not None
        for r in regs:
            cited = {k.strip() for k in r.source.split(",")} if r.source else set()
            assert libraries <= cited, (model, r.label, libraries, cited)
            if not main:
                assert cited, (model, r.label)
        if row["Source"] == "see note":
            assert all(r.note and r.source for r in regs), row


@pytest.mark.parametrize("model", FAMILY)
def test_where_nothing_is_known_a_reserved_byte_says_so(model):
    m = default_registry().get(model)
    listed = set()
    for row, _ in rows(model):
        first, last = addresses(row["Addr"])
        listed |= set(range(first, last + 1))
    listed |= {0, 1}  # the model number's row
    for a in set(range(60)) - listed:
        r = m.register_at(a)
        assert r.reserved and r.name is None and r.note, (model, a)


# ---- baud tables, return flags and areas, behaviour -----------------------------------------------------------
def test_baud_tables_per_model():
    reg = default_registry()
    said = re.search(r"Baud codes \(p\.19\):(.*?)\.\n", sections()["1"], re.S).group(1)
    rs301 = {number(code): float(rate) for code, rate in re.findall(r"([0-9A]{2}) (\d+)", said.replace("**", ""))}
    assert rs301[10] == 460800 and len(rs301) == 11
    for name in ("RS301CR", "RS302CD"):
        assert reg.get(name).register("baud_rate").table == rs301
    rs303 = reg.get("RS303MR").register("baud_rate").table
    assert reg.get("RS204MD").register("baud_rate").table == rs303 and "no 0A" in sections()["2"]
    assert "0A = 460800" in sections()["3"]
    assert reg.get("RS405CB").register("baud_rate").table == rs301


def test_return_flags_per_model():
    reg = default_registry()
    text = sections()["1"]
    bits = re.search(r"Return-packet flags \(p\.16, Table 4\.3\):([^\n]*)", text).group(1)
    said = {1 << int(b) for b in re.findall(r"bit(\d) [a-z]", bits)}
    assert "bit3 is \"Reserved\"" in text.replace("**", "")
    for name in ("RS301CR", "RS302CD"):
        flags = reg.get(name).behaviour.return_flags
        assert set(flags) == said == {0x80, 0x20, 0x02}
        assert all(flags[b] == RETURN_FLAG_BITS[b] for b in flags)
    checked = re.search(r"real-hardware code checks ([^(]*\(Flash write error\) and 0x02)", sections()["3"]).group(1)
    assert set(reg.get("RS405CB").behaviour.return_flags) == {int(x, 16) for x in re.findall(r"0x[0-9A-F]{2}", checked)}
    for name in ("RS303MR", "RS304MD", "RS204MD", "RS405CB"):  # the RS204MD's: not said, the RS303MR's kept
        assert dict(reg.get(name).behaviour.return_flags) == RETURN_FLAG_BITS


def test_return_mode_0d_reads_60_to_127_where_the_sources_show_it():
    reg = default_registry()
    for name, section in (("RS204MD", "2"), ("RS405CB", "3"), ("RS406CB", "3")):
        assert re.search(r"0x0D = .*60-127|Flag 0x0D = read 60-127", sections()[section])
        assert dict(reg.get(name).behaviour.return_areas) == {0x0D: (60, 127 - 60 + 1)}
    assert "identical to RS303MR" in sections()["1"]
    for name in ("RS301CR", "RS302CD", "RS303MR", "RS304MD"):
        assert dict(reg.get(name).behaviour.return_areas) == {}


def test_behaviour_per_model():
    reg = default_registry()
    one, two = sections()["1"], sections()["2"]
    assert re.search(r"Flags 0x60 .* is allowed", one) and "must be separate packets" in two
    assert "An invalid code falls back to 115200" in one and "send a No.36 Torque" in one.replace("\n", " ")
    assert "ID and Reverse can be written only while torque is OFF" in two
    volts = float(re.search(r"accuracy ±([\d.]+) V", one.replace("**", "")).group(1))
    for name in ("RS301CR", "RS302CD"):
        b = reg.get(name).behaviour
        assert (b.flash_and_reboot_together, b.invalid_baud_code_gives, b.over_temperature_recovery) == (
            True, 115200, "torque-enable")
        assert b.voltage_accuracy_v == volts == 0.5 and b.torque_off_only == ()
    b = reg.get("RS204MD").behaviour
    assert b.torque_off_only == ("servo_id", "reverse") and not b.flash_and_reboot_together
    assert b.invalid_baud_code_gives is None and b.voltage_accuracy_v is None  # not said for this model
    for name in ("RS405CB", "RS406CB"):
        b = reg.get(name).behaviour
        assert b.invalid_baud_code_gives is None and b.voltage_accuracy_v is None and b.torque_off_only == ()
    assert reg.get("RS303MR").behaviour.voltage_accuracy_v == 0.3


# ---- the traps the notes name --------------------------------------------------------------------------------
def test_the_damper_is_at_20_not_0x20():
    m = default_registry().get("RS405CB")
    assert m.register("damper").address == 20 and m.register_at(0x20).name == "goal_time"
    assert m.register("damper").default == 0x10 and "0x20" in m.register("damper").note


def test_pid_coefficient_at_38_where_the_sources_show_it():
    reg = default_registry()
    for name in ("RS204MD", "RS405CB", "RS406CB"):
        assert reg.get(name).register("pid_coefficient").address == 38
    for name in ("RS301CR", "RS302CD", "RS303MR", "RS304MD"):
        assert reg.get(name).register_at(38).name is None


def test_rs405cb_is_not_the_bla21_layout():
    # The BLA21-12M-C01 layout names 12-13, 16-19, 37, 39-41 and 48 otherwise; the RS405CB's leaves them be.
    m = default_registry().get("RS405CB")
    assert all(m.register_at(a).reserved for a in (12, 13, 16, 17, 18, 19, 37, 39, 40, 41))
    assert m.register_at(48).name == "present_current"
    assert "BLA21" in m.register_at(37).note


def test_conflicting_sources_are_noted_and_the_manuals_reading_taken():
    m = default_registry().get("RS204MD")
    punch, limit = m.register("punch"), m.register("temperature_limit")
    assert punch.scale == 0.01 and "conflict" in punch.note and "M5Stack" in punch.note
    assert limit.access == "read" and "conflict" in limit.note and "pyfrs" in limit.note


# ---- what a wrong map says ------------------------------------------------------------------------------------
def test_torque_off_only_naming_no_register_is_one_line(tmp_path):
    text = (ROOT / "decoders" / "rs204md.toml").read_text(encoding="utf-8")
    path = tmp_path / "x.toml"
    wrong = text.replace('torque_off_only = ["servo_id", "reverse"]', 'torque_off_only = ["servo_id", "revers"]')
    path.write_text(wrong, encoding="utf-8")
    with pytest.raises(ModelError) as e:
        load_model(path)
    assert str(e.value) == f"{path}: behaviour.torque_off_only.1: 'revers' names no register of this map"
