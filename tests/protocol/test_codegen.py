"""Generated code (rs30x_sniff.protocol.codegen) equals its reference, and is made nowhere else.

Each generated function against the plain form it stands for, on random values (hypothesis):
Layout.values against Register.value_of, the fields' JSON text against json.dumps of field_json,
Plan.apply against setattr; line_function's pieces come out as written. The text line against
text_line is tests/render/test_block_text.py's (Blocks and single records, random and arbitrary frames).
"""

from __future__ import annotations

import ast
import json
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import rs30x_sniff
from rs30x_sniff.lint.state import Plan, Shadow
from rs30x_sniff.protocol import codegen
from rs30x_sniff.protocol.memmap import default_registry, parse_model
from rs30x_sniff.render.layout_json import fields_json
from rs30x_sniff.render.records import field_json

PACKAGE = Path(rs30x_sniff.__file__).parent

# A map with every kind of conversion the shipped ones may not have: a scale that is no decimal step,
# one whose inverse is an integer, float and integer offsets, signed 2-byte values, a table of floats,
# an enum, a hex format, reserved bytes between.
ODD = parse_model({
    "model": {"name": "ODD", "model_number": 1, "top_speed_s_per_60deg": 0.1},
    "register": [
        {"name": "third", "address": 0, "size": 2, "scale": 0.3, "unit": "x", "access": "read-write"},
        {"name": "quarter", "address": 2, "size": 2, "signed": True, "scale": 0.25, "offset": -40.5},
        {"name": "stepped", "address": 4, "scale": 50, "offset": 100, "unit": "us"},
        {"name": "signed_tenths", "address": 5, "size": 2, "signed": True, "scale": 0.1, "unit": "deg"},
        {"address": 7, "access": "reserved"},
        {"name": "gain", "address": 8, "table": {"0": 0.5, "1": 1.25, "2": 3}},
        {"name": "mode", "address": 9, "enum": {"0": "off", "1": "on"}, "access": "read-write"},
        {"name": "word", "address": 10, "size": 2, "format": "hex"},
        {"name": "plain", "address": 12, "size": 2, "signed": True, "offset": 1.5},
        {"name": "hundredths", "address": 14, "size": 2, "scale": 0.01, "unit": "s"},
    ],
}, "<odd map>")
MODELS = [*default_registry().models.values(), ODD]


@st.composite
def layouts(draw):
    """(layout, data bytes): a short packet's or return's data, or a whole long packet's (VIDs in it)."""
    model = draw(st.sampled_from(MODELS))
    address = draw(st.integers(0, 140))
    length = draw(st.integers(1, 40))
    count = draw(st.integers(0, 4))
    if count:
        lay = model.long_layout(address, length + 1, count)
        size = (length + 1) * count
    else:
        lay = model.layout(address, length)
        size = length
    return lay, draw(st.binary(min_size=size, max_size=size))


def _typed(values):
    return [(type(v), v) for v in values]


def _reference_values(lay, data):
    """Register.value_of of each part's raw value, by plain Python (no generated code)."""
    out = []
    stride = lay.size + 1
    for rec in range(max(lay.records, 1)):
        base = rec * stride + 1 if lay.records else 0
        for start, size, reg, partial in lay.parts:
            raw = data[base + start:base + start + size]
            rv = raw[0] if partial else int.from_bytes(raw, "little", signed=reg.signed)
            out.append(reg.value_of(rv, partial))
    return out


# ---- only codegen compiles code ------------------------------------------------------------------
def _compiling_calls(tree: ast.AST) -> list[str]:
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            f = node.func
            name = f.id if isinstance(f, ast.Name) else (f.attr if isinstance(f, ast.Attribute)
                                                          and isinstance(f.value, ast.Name)
                                                          and f.value.id == "builtins" else None)
            if name in ("eval", "exec", "compile"):
                found.append(f"{node.lineno}: {ast.unparse(node)[:60]}")
    return found


def test_only_codegen_compiles_code():
    found = [f"{p.relative_to(PACKAGE)}:{where}" for p in sorted(PACKAGE.rglob("*.py"))
             if p.relative_to(PACKAGE).as_posix() != "protocol/codegen.py"
             for where in _compiling_calls(ast.parse(p.read_text(), str(p)))]
    assert not found, "generated code goes through rs30x_sniff.protocol.codegen:\n" + "\n".join(found)


def test_the_check_finds_eval_exec_and_compile():
    src = "eval('1')\nexec('x = 1')\nbuiltins.compile('1', 'f', 'eval')\nre.compile('x')\nliteral_eval('1')\n"
    assert [w.split(":")[0] for w in _compiling_calls(ast.parse(src))] == ["1", "2", "3"]


# ---- Layout.values (codegen.values_function) ------------------------------------------------------
@settings(max_examples=400, deadline=None)
@given(layouts())
def test_layout_values_are_the_reference(case):
    lay, data = case
    assert _typed(lay.values(data)) == _typed(_reference_values(lay, data))


def test_every_register_of_every_map_converts_as_register_convert():
    for model in MODELS:
        for reg in model.registers:
            lay = model.layout(reg.address, reg.size)
            for raw in range(0, 1 << (8 * reg.size), 1 if reg.size == 1 else 257):
                data = raw.to_bytes(reg.size, "little")
                want = [reg.value_of(int.from_bytes(data, "little", signed=reg.signed))]
                assert _typed(lay.values(data)) == _typed(want), (model.name, reg.label, raw)


# ---- the fields' JSON text (codegen.percent_function, render.layout_json) -------------------------
@settings(max_examples=300, deadline=None)
@given(layouts(), st.booleans(), st.one_of(st.none(), st.sets(st.integers(0, 6), max_size=3)),
       st.one_of(st.none(), st.integers(0, 254)))
def test_fields_json_is_json_dumps_of_field_json(case, compact, only, servo_id):
    lay, data = case
    values = lay.values(data)
    sid = 0 if lay.records else servo_id
    fields = [field_json(f) for f in lay.fields(data, values, sid) if only is None or f.id in only]
    want = json.dumps(fields, separators=(",", ":") if compact else None)[1:-1]
    assert fields_json(lay, data, values, sid, only, compact) == want


# ---- the text line (codegen.line_function) ---------------------------------------------------------
def test_line_function_writes_its_pieces():
    texts = {5: "=five", 7: "=seven"}
    line = codegen.line_function([
        "it's {not} an \"f-string\" \\n", ("arg", "t", "8.3f"), " @", ("arg", "o", "<4"), "|",
        ("text", texts, 1), ("join", lambda p, xs: p + "+".join(xs), " g:", ((texts, 0), (texts, 1))),
        " q=", ("arg", "q", ""), " l=", ("arg", "l", ".1f", 1e3), "\n"])
    assert line(1.5, 12, (7, 5), 0.00125, 3) == ("it's {not} an \"f-string\" \\n   1.500 @12  |=five g:=seven+=five"
                                                  " q=3 l=1.2\n")
    assert codegen.line_function([])(None, 0, None, None, None) == ""


# ---- Plan.apply (codegen.attribute_setter) ---------------------------------------------------------
@settings(max_examples=200, deadline=None)
@given(st.sampled_from(MODELS), st.integers(0, 60), st.integers(1, 30), st.data())
def test_plan_apply_sets_the_tracked_attributes(model, address, n, data):
    plan = Plan(model, address, n)
    raws = data.draw(st.lists(st.integers(-32768, 65535), min_size=len(plan.parts), max_size=len(plan.parts)))
    got, want = Shadow(), Shadow()
    plan.apply(got, raws)
    for attr, j in plan.tracked:
        setattr(want, attr, raws[j])
    assert {a: getattr(got, a) for a in Shadow.__slots__} == {a: getattr(want, a) for a in Shadow.__slots__}


def test_a_plan_over_the_tracked_registers_tracks_them():
    reg = default_registry().default.register("goal_position")
    assert ("pos", 0) in Plan(default_registry().default, reg.address, reg.size).tracked


# ---- what codegen refuses -------------------------------------------------------------------------
@pytest.mark.parametrize("call", [
    lambda: codegen.identifier("a b"),
    lambda: codegen.identifier("import"),
    lambda: codegen.identifier("x);import os;("),
    lambda: codegen.index("1"),
    lambda: codegen.index(True),
    lambda: codegen.literal(object()),
    lambda: codegen.literal([1]),
    lambda: codegen.line_function([("arg", "t", "}")]),
    lambda: codegen.line_function([("arg", "__import__('os')", "")]),
    lambda: codegen.line_function([("text", {}, "0]]")]),
    lambda: codegen.percent_function("%s", [("hex", 0, "2]")]),
    lambda: codegen.attribute_setter([("pos = 0; import os; s.x", 0)]),
])
def test_codegen_refuses_what_it_cannot_vouch_for(call):
    with pytest.raises((ValueError, TypeError)):
        call()


def test_literals_read_back_as_themselves():
    for x in (0, -3, 2.5, 0.1, 1e-300, "a'b\"c\\{d}", True, None, float("inf"), float("-inf")):
        assert eval(codegen.literal(x)) == x  # noqa: S307 - the test of the literal writer
