"""Memory maps as data: both models load, every documented address is there, mistakes name file and key."""

import pytest

from rs30x_sniff.protocol.memmap import ModelError, default_registry, load_model, parse_model

NAMES = """model_number firmware_version servo_id reverse baud_rate return_delay cw_angle_limit ccw_angle_limit
temperature_limit torque_in_silence warm_up_time cw_compliance_margin ccw_compliance_margin cw_compliance_slope
ccw_compliance_slope punch goal_position goal_time max_torque torque_enable present_position present_time
present_speed present_current present_temperature present_voltage""".split()


@pytest.fixture(params=["RS303MR", "RS304MD"])
def model(request):
    return default_registry().get(request.param)


def test_every_address_0_to_59_is_described(model):
    covered = sorted(a for r in model.registers for a in range(r.address, r.address + r.size))
    assert covered == list(range(60))


def test_the_named_registers(model):
    assert model.names == NAMES


def test_models_differ_in_model_number_punch_and_speed():
    r3, r4 = default_registry().get("RS303MR"), default_registry().get("RS304MD")
    assert (r3.model_number, r4.model_number) == (0x3030, 0x3040)
    assert r3.register("model_number").default == 0x3030 and r4.register("model_number").default == 0x3040
    assert (r3.register("punch").default, r4.register("punch").default) == (100, 600)  # 1.00 % and 6.00 %
    assert (r3.top_speed_s_per_60deg, r4.top_speed_s_per_60deg) == (0.11, 0.16)


@pytest.mark.parametrize("name,raw,value", [
    ("goal_position", "84 03", 90.0), ("goal_position", "7C FC", -90.0), ("goal_time", "F4 01", 5.0),
    ("punch", "64 00", 1.0), ("present_voltage", "E4 02", 7.4), ("return_delay", "12", 1000),
    ("baud_rate", "07", 115200), ("baud_rate", "04", 38400), ("torque_enable", "02", "brake"),
    ("ccw_angle_limit", "24 FA", -150.0), ("present_temperature", "2D 00", 45), ("max_torque", "50", 80),
    ("warm_up_time", "C8", 2.0), ("cw_compliance_margin", "02", 0.2), ("reverse", "01", "reverse"),
])
def test_engineering_values(name, raw, value):
    m = default_registry().get("RS303MR")
    reg = m.register(name)
    [field] = m.decode(reg.address, bytes.fromhex(raw), 1)
    assert field.name == name and field.value == value


def test_undocumented_addresses_decode_as_unnamed_bytes():
    m = default_registry().get("RS303MR")
    fields = m.decode(60, bytes(range(80)))
    assert len(fields) == 80 and all(f.name is None for f in fields)
    assert [f.value for f in fields[:3]] == [0, 1, 2]


def test_partial_register_write_is_marked():
    m = default_registry().get("RS303MR")
    fields = m.decode(31, bytes([1, 2, 3]))
    assert [(f.name, f.partial) for f in fields] == [("goal_position", "high"), ("goal_time", None)]


def test_encode_is_the_inverse_of_decode():
    m = default_registry().get("RS303MR")
    assert m.register("goal_position").encode(-21.6) == (-216).to_bytes(2, "little", signed=True)
    assert m.register("baud_rate").encode(230400) == b"\x09"


GOOD = """
[model]
name = "X1"
model_number = 1
top_speed_s_per_60deg = 0.1
[[register]]
name = "a"
address = 0
size = 2
range = [0, 10]
"""


@pytest.mark.parametrize("text,where", [
    (GOOD + "colour = 3\n", "register[0] (a).colour: unknown key"),
    (GOOD.replace("[model]", "[model]\nvendor = 1"), "model.vendor: unknown key"),
    (GOOD + '[[register]]\nname = "b"\naddress = 1\n', "register[1] (b).address: overlaps a at address 1"),
    (GOOD.replace("range = [0, 10]", "range = [10, 0]"), "register[0] (a).range"),
    (GOOD.replace("size = 2", "size = 3"), "register[0] (a).size"),
    (GOOD.replace('name = "a"\n', ""), "register[0] (address 0).name"),
])
def test_mistakes_name_the_file_and_key(tmp_path, text, where):
    p = tmp_path / "x1.toml"
    p.write_text(text)
    with pytest.raises(ModelError) as e:
        load_model(p)
    assert str(p) in str(e.value) and where in str(e.value)


def test_not_toml_is_a_model_error(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text("[model\n")
    with pytest.raises(ModelError, match="not valid TOML"):
        load_model(p)


def test_a_new_model_is_a_new_file(tmp_path, monkeypatch):
    import tomllib
    from rs30x_sniff.protocol.memmap import ModelRegistry, decoders_dirs
    doc = tomllib.loads(GOOD)
    m = parse_model(doc, "mem")
    assert m.name == "X1" and m.register("a").range == (0, 10)
    (tmp_path / "x1.toml").write_text(GOOD)
    monkeypatch.setenv("RS30X_DECODERS", str(tmp_path))
    reg = ModelRegistry.from_dirs(decoders_dirs())
    assert {"X1", "RS303MR", "RS304MD"} <= set(reg.models)


# ---- a map is data, never code: names checked as it loads (issue 25) ------------------------------------------
HOSTILE = 'present_position"); __import__("os").system("id"); ("'


@pytest.mark.parametrize("edit,where", [
    (lambda t: t.replace('name = "a"', f"name = '{HOSTILE}'"), "register[0] ('present_position\"); __import__"),
    (lambda t: t.replace('name = "a"', 'name = "Present"'), "is no register name"),
    (lambda t: t.replace('name = "a"', 'name = "id"'), "'id' is taken"),
    (lambda t: t.replace('name = "a"', 'name = "reserved_3"'), "'reserved_3' is taken"),
    (lambda t: t.replace('name = "X1"', 'name = "X1\\"]] --"'), "model.name: 'X1\"]] --' is no model name"),
    (lambda t: t + 'unit = "deg\\"); os.exit()"\n', "register[0] (a).unit:"),
    (lambda t: t + 'description = "two\\nlines"\n', "register[0] (a).description: holds the control character"),
    (lambda t: t + 'enum = { 0 = "off\\u0000" }\n', "register[0] (a).enum.0: holds the control character"),
    (lambda t: t + 'enum = { 0 = 5 }\n', "register[0] (a).enum.0: must be a string"),
    (lambda t: t + 'table = { 0 = "9600" }\n', "register[0] (a).table.0: must be a number"),
    (lambda t: t + 'enum = 3\n', "register[0] (a).enum: must be a table"),
    (lambda t: t + 'format = "__import__"\n', "register[0] (a).format"),
    (lambda t: t + '[[register]]\nname = "a"\naddress = 5\n', "register[1] (a).name: 'a' names register[0] already"),
    (lambda t: t.replace("model_number = 1", "model_number = 70000"), "model.model_number"),
    (lambda t: t.replace("model_number = 1", 'model_number = "1"'), "model.model_number"),
])
def test_names_are_checked_as_the_map_loads(tmp_path, edit, where):
    path = tmp_path / "x.toml"
    path.write_text(edit(GOOD))
    with pytest.raises(ModelError) as e:
        load_model(path)
    assert str(e.value).startswith(f"{path}: ") and where in str(e.value), str(e.value)
    assert "\n" not in str(e.value)


def test_the_reserved_names_are_the_filter_keys():
    from rs30x_sniff.filters import KEYS
    from rs30x_sniff.protocol.memmap import RESERVED_NAMES

    assert set(KEYS) <= RESERVED_NAMES


def test_the_bundled_maps_pass_the_checks():
    reg = default_registry()
    assert {"RS303MR", "RS304MD"} <= set(reg.models)


# ---- what a map says beyond its registers (issue 34): sources, behaviour, unknowns, shared maps -------------
def test_a_map_without_behaviour_acts_as_the_rs303mr_manual_says():
    from rs30x_sniff.protocol.memmap import Behaviour
    from rs30x_sniff.protocol.wire import RETURN_FLAG_BITS

    m = parse_model(__import__("tomllib").loads(GOOD), "x.toml")
    assert m.behaviour == Behaviour() and m.sources == () and m.also_named == ()
    b = m.behaviour
    assert (b.flash_and_reboot_together, b.invalid_baud_code_gives, b.over_temperature_recovery) == (
        False, None, "reboot")
    assert dict(b.return_flags) == RETURN_FLAG_BITS and dict(b.return_areas) == {} and b.torque_off_only == ()
    # The bundled maps say so explicitly, with the manual's voltage accuracy.
    for name in ("RS303MR", "RS304MD"):
        got = default_registry().get(name).behaviour
        assert (got.flash_and_reboot_together, got.over_temperature_recovery, got.voltage_accuracy_v) == (
            False, "reboot", 0.3)
        assert dict(got.return_flags) == RETURN_FLAG_BITS


BEHAVIOUR = GOOD.replace("[[register]]", """[[source]]
key = "manual"
title = "A manual"
where = "p.12"
[behaviour]
flash_and_reboot_together = true
invalid_baud_code_gives = 115200
over_temperature_recovery = "torque-enable"
torque_off_only = ["a"]
return_flags = { 0x80 = "temperature_limit", 0x02 = "received_packet_error" }
return_areas = { 0x0D = [60, 127] }
voltage_accuracy_v = 0.5
[[register]]""", 1) + 'source = "manual"\nnote = "the sources disagree"\n'


def test_behaviour_sources_and_notes_load():
    import tomllib

    from rs30x_sniff.protocol.memmap import Source

    m = parse_model(tomllib.loads(BEHAVIOUR), "x.toml")
    b = m.behaviour
    assert (b.flash_and_reboot_together, b.invalid_baud_code_gives, b.over_temperature_recovery) == (
        True, 115200, "torque-enable")
    assert b.torque_off_only == ("a",) and b.voltage_accuracy_v == 0.5
    assert dict(b.return_flags) == {0x80: "temperature_limit", 0x02: "received_packet_error"}
    assert dict(b.return_areas) == {0x0D: (60, 68)}  # (first address, byte count), as wire.Expect.range
    assert m.sources == (Source("manual", "A manual", "p.12"),)
    assert (m.register("a").source, m.register("a").note) == ("manual", "the sources disagree")


@pytest.mark.parametrize("edit,said", [
    (lambda t: t.replace('torque_off_only = ["a"]', 'torque_off_only = ["a", "servo_id"]'),
     "behaviour.torque_off_only.1: 'servo_id' names no register of this map"),
    (lambda t: t.replace("0x02 = ", "0x03 = "), "behaviour.return_flags.0x3: must be one bit"),
    (lambda t: t.replace("0x0D = [60, 127]", "0x03 = [60, 127]"), "behaviour.return_areas.0x3: must be a return mode"),
    (lambda t: t.replace("0x0D = [60, 127]", "0x0D = [127, 60]"), "behaviour.return_areas.0xd: must be [first, last]"),
    (lambda t: t.replace('"torque-enable"', '"power-cycle"'), "behaviour.over_temperature_recovery: must be one of"),
    (lambda t: t.replace('key = "manual"', 'key = "Manual Book"'), "source[0].key: 'Manual Book' is no source key"),
    (lambda t: t.replace('title = "A manual"\n', ""), "source[0].title: missing"),
    (lambda t: t.replace('where = "p.12"', 'where = "p.\\u000712"'), "source[0].where: holds the control character"),
    (lambda t: t.replace('note = "the sources disagree"', 'note = "a\\nb"'), "register[0] (a).note: holds the control"),
    (lambda t: t.replace("model_number = 1", 'model_number = "none"'), "model.model_number: must be an integer"),
    (lambda t: t.replace("[model]", '[model]\nalso_named = ["X1"]'), "model.also_named.0: 'X1' is named already"),
])
def test_behaviour_mistakes_are_one_line(tmp_path, edit, said):
    path = tmp_path / "x.toml"
    path.write_text(edit(BEHAVIOUR))
    with pytest.raises(ModelError) as e:
        load_model(path)
    text = str(e.value)
    assert text.startswith(f"{path}: {said}") and "\n" not in text, text


def test_an_unknown_model_number_is_none_and_never_learned(tmp_path):
    import tomllib

    from rs30x_sniff.protocol.memmap import ModelRegistry

    text = GOOD.replace("model_number = 1", 'model_number = "unknown"').replace(
        "top_speed_s_per_60deg = 0.1", 'top_speed_s_per_60deg = "unknown"').replace(
        "[model]", '[model]\nalso_named = ["X2"]')
    m = parse_model(tomllib.loads(text), "x.toml")
    assert (m.model_number, m.top_speed_s_per_60deg, m.also_named) == (None, None, ("X2",))
    reg = ModelRegistry([default_registry().get("RS303MR"), m])
    assert None not in reg.by_number and set(reg.by_number) == {0x3030}
    x2 = reg.get("x2")
    assert x2.name == "X2" and x2 is not m and x2.registers is m.registers and x2.behaviour is m.behaviour
    assert x2.model_number is None and x2.also_named == ()
    assert reg.get("X1") is m
