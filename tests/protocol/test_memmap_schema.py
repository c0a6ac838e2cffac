"""The memory-map schema (schemas/memory_map.json) is JSON Schema, and our small checker agrees with jsonschema."""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path

import pytest
from hypothesis import given, settings, strategies as st

from rs30x_sniff.protocol.memmap import ModelError, parse_model
from rs30x_sniff.schemas import memory_map_schema
from rs30x_sniff.schemas.check import first_failure

jsonschema = pytest.importorskip("jsonschema")

ROOT = Path(__file__).resolve().parents[2]
MAPS = sorted((ROOT / "decoders").glob("*.toml"))
BUNDLED = tomllib.loads(MAPS[0].read_text(encoding="utf-8"))

# TOML's types, as the checker reads them: 5.0 is a float, not an integer (JSON Schema would take it).
_TOML_TYPES = jsonschema.Draft202012Validator.TYPE_CHECKER.redefine(
    "integer", lambda checker, v: isinstance(v, int) and not isinstance(v, bool))
Reference = jsonschema.validators.extend(jsonschema.Draft202012Validator, type_checker=_TOML_TYPES)

MODEL_KEYS = ["name", "model_number", "top_speed_s_per_60deg", "readable_to", "also_named", "vendor"]
REGISTER_KEYS = ["name", "address", "size", "signed", "scale", "offset", "unit", "access", "area", "default",
                 "range", "mode", "enum", "table", "format", "description", "source", "note", "colour"]
BEHAVIOUR_KEYS = ["flash_and_reboot_together", "invalid_baud_code_gives", "over_temperature_recovery",
                  "torque_off_only", "return_flags", "return_areas", "voltage_accuracy_v", "source", "colour"]
SOURCE_KEYS = ["key", "title", "where", "colour"]
# Text without a final newline: ECMA-262's $ (JSON Schema's) ends the text, Python's re.search (jsonschema's)
# also matches before a final newline; the checker holds to ECMA's (test_a_name_with_a_final_newline_is_refused).
TEXT = st.text(st.characters(blacklist_characters="\n"), max_size=8) | st.sampled_from(
    ["hex", "read", "reserved", "ram", "pwm", "deg", "id", "reserved_4", "a", "RS1", "é" * 600, "unknown",
     "reboot", "torque-enable", "servo_id", "manual"])
SCALAR = st.none() | st.booleans() | st.integers(-70000, 70000) | st.floats(-300, 300) | TEXT
VALUE = SCALAR | st.lists(SCALAR, max_size=3) | st.dictionaries(
    st.sampled_from(["0", "1", "0x10", "0x0D", "x"]), SCALAR | st.lists(st.integers(-1, 300), max_size=3),
    max_size=2)


@st.composite
def edited_maps(draw) -> dict:
    """A bundled map with a few keys set to any value, or taken out (None)."""
    doc = copy.deepcopy(BUNDLED)
    for _ in range(draw(st.integers(1, 3))):
        where = draw(st.sampled_from(["model", "behaviour", "source"] + ["register"] * 5))
        if where == "model":
            table, key = doc["model"], draw(st.sampled_from(MODEL_KEYS))
        elif where == "behaviour":
            table, key = doc.setdefault("behaviour", {}), draw(st.sampled_from(BEHAVIOUR_KEYS))
        elif where == "source" and doc.get("source"):
            table, key = draw(st.sampled_from(doc["source"])), draw(st.sampled_from(SOURCE_KEYS))
        else:
            table = draw(st.sampled_from(doc["register"]))
            key = draw(st.sampled_from(REGISTER_KEYS))
        value = draw(VALUE)
        if value is None:
            table.pop(key, None)
        else:
            table[key] = value
    return doc


def test_the_schema_is_json_schema():
    jsonschema.Draft202012Validator.check_schema(memory_map_schema())


@pytest.mark.parametrize("path", MAPS, ids=lambda p: p.name)
def test_the_bundled_maps_pass_both(path):
    doc = tomllib.loads(path.read_text(encoding="utf-8"))
    assert first_failure(doc, memory_map_schema()) is None
    Reference(memory_map_schema()).validate(doc)


@settings(max_examples=400, deadline=None)
@given(edited_maps())
def test_the_checker_agrees_with_jsonschema(doc):
    ours = first_failure(doc, memory_map_schema())
    theirs = next(iter(Reference(memory_map_schema()).iter_errors(doc)), None)
    assert (ours is None) == (theirs is None), (ours and ours.path, theirs and list(theirs.absolute_path))


@settings(max_examples=300, deadline=None)
@given(edited_maps())
def test_a_bad_map_is_one_line_naming_the_file_and_key(doc):
    try:
        parse_model(doc, "maps/x.toml")
    except ModelError as e:
        text = str(e)
        assert text.startswith("maps/x.toml: ") and "\n" not in text, text
        where = text.split(": ")[1]
        assert where.split(".")[0].split(" ")[0].split("[")[0] in (
            "model", "register", "behaviour", "source", "colour", "vendor"), text
    else:
        assert first_failure(doc, memory_map_schema()) is None


@pytest.mark.parametrize("edit,said", [
    (lambda r: r.update(signed="yes"), "register[0] (model_number).signed: must be true or false"),
    (lambda r: r.update(address=True), "register[0] (model_number).address: must be an integer 0-255"),
    (lambda r: r.update(address=1.0), "register[0] (model_number).address: must be an integer 0-255"),
    (lambda r: r.update(range=[0, "9"]), "register[0] (model_number).range: must be [min, max] with 0 <= min"),
    (lambda r: r.update(default=1.5), "register[0] (model_number).default: must be an integer 0-65535"),
    (lambda r: r.update(description="é" * 501), "register[0] (model_number).description: must be a string of at"),
    (lambda r: r.update(enum={"0": "é" * 65}), "register[0] (model_number).enum.0: must be a string of at most 64"),
    (lambda r: r.update(enum={"zero": "off"}), "register[0] (model_number).enum: keys must be integers"),
    (lambda r: r.update(name="a\n"), "register[0] ('a\\n').name: 'a\\n' is no register name"),
])
def test_what_the_schema_says_and_what_code_says(edit, said):
    doc = copy.deepcopy(BUNDLED)
    edit(doc["register"][0])
    with pytest.raises(ModelError) as e:
        parse_model(doc, "x.toml")
    assert str(e.value).startswith(f"x.toml: {said}"), str(e.value)


def test_a_name_with_a_final_newline_is_refused():
    # The one place the checker is stricter than jsonschema's re.search: ECMA-262's $ ends the text.
    doc = copy.deepcopy(BUNDLED)
    doc["register"][0]["name"] = "a\n"
    assert first_failure(doc, memory_map_schema()).path == ("register", 0, "name")


def test_a_missing_model_table_and_an_unknown_key():
    with pytest.raises(ModelError, match=r"^x.toml: model: missing$"):
        parse_model({"register": []}, "x.toml")
    with pytest.raises(ModelError, match=r"^x.toml: model.vendor: unknown key$"):
        parse_model({"model": {**BUNDLED["model"], "vendor": "Futaba"}}, "x.toml")
