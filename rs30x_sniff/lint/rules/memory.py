"""Memory-map rules (M): writes the model's memory map (decoders/*.toml, tables 4.5-4.9) does not allow."""

from __future__ import annotations

from ...protocol.memmap import ModelError, default_registry
from ...protocol.wire import encode_long, encode_read, encode_return, encode_short
from ..params import Measured, said, said_as
from ..registry import example, rule


def _who(ids: tuple) -> tuple[str, int | None]:
    if len(ids) == 1:
        return f"ID {ids[0]}", ids[0]
    return f"IDs {', '.join(map(str, ids))}", None


@rule("M001", "write-read-only", "error", "A write to a read-only register.", f"""
## What it does
Flags a short or long packet whose data covers a register the memory map marks read-only: the model
number, firmware version, temperature limit, and the present_* values (tables 4.5, 4.6, 4.9).

## Why it matters
The servo ignores the write (or, for the temperature limit, the manual says changing it voids the
warranty); a host that thinks it set the value works with a wrong picture of the servo. Most often
the host's register offsets are off by a few bytes.

## Example
{example(encode_short(1, 0, 0x2A, bytes.fromhex("8403")), note="a write to present_position:")}
""", kinds=("write",), column="header")
def write_read_only(lint, rec, plan, ids):
    if plan.read_only:
        who, sid = _who(ids)
        lint.emit("M001", rec, said("writes read-only {registers} of {who}",
                                    {"registers": ", ".join(plan.read_only), "who": who}), sid=sid)


@rule("M002", "write-reserved", "warning", "A write to a reserved or undocumented address.", f"""
## What it does
Flags a packet whose data covers an address the memory map marks reserved (for example 3, 12-13,
16-21, 34, 37-41, 54-59) or an address past the documented map.

## Why it matters
Reserved bytes may hold calibration or firmware state; writing them has undefined effects that can
outlive a power cycle once flashed. The manual's own ccw_angle_limit example is sent to address 0x10
instead of 0x0A, a typo that lands in a reserved area.

## Example
{example(bytes.fromhex("FAAF0100100201 18FC F6".replace(" ", "")), note="the manual's ccw_angle_limit example, sent to 0x10:")}
""", kinds=("write",), column="header")
def write_reserved(lint, rec, plan, ids):
    if plan.reserved:
        who, sid = _who(ids)
        lint.emit("M002", rec, said("writes {registers} of {who}", {"registers": ", ".join(plan.reserved), "who": who}),
                  sid=sid)


def _value_out_of_range_columns(view) -> bool:
    """M003 on a Block: every whole-register value its writes carry within the settable range."""
    for t in view.targets:
        for j, _, lo, hi in t.plan.ranged:
            v = view.written(t, j)
            if ((v < lo) | (v > hi)).any():
                return False
    return True


@rule("M003", "value-out-of-range", "error", "A register written with a value outside its settable range.", f"""
## What it does
Flags a whole-register write whose raw value is outside the settable range of the model's table:
for example servo_id outside 1-127, baud_rate above 9, goal_position beyond +/-150.0 deg, goal_time
above 16383 (163.83 s), max_torque above 100, punch above 10000, torque_enable above 2.

## Why it matters
The servo clamps, ignores or misreads such values, depending on the register: a baud_rate code of 12
flashed into a servo leaves it on a rate no host can talk to, and an out-of-range goal makes the
servo stop somewhere the host did not plan for.

## Example
{example(encode_short(1, 0, 0x23, bytes((120,))), note="max_torque 120 %:")}
""", kinds=("target",), column=_value_out_of_range_columns)
def value_out_of_range(lint, rec, plan, targets):
    for j, name, lo, hi in plan.ranged:
        for sid, raws, _ in targets:
            v = raws[j]
            if lo <= v <= hi:
                continue
            reg = plan.parts[j][0]
            lint.emit("M003", rec, _out_of_range(name, v, reg, sid, lo, hi), sid=sid)


def _out_of_range(name: str, raw: int, reg, sid: int, lo: int, hi: int):
    """M003's message: the value written (measured) against the table's range (the manual's, so named)."""
    params = {"name": name, "raw": Measured(raw), "id": sid, "lo": lo, "hi": hi}
    template = "{name}={raw} (raw) on ID {id} outside {lo}-{hi}"
    value = reg.convert(raw)
    if not isinstance(value, float):
        return said(template, params)
    # A scaled register also shows its value in units, written as str() writes the float (160.0deg),
    # as the reports have always written it.
    return said_as(template + " ({value})", {**params, "value": Measured(value, reg.unit or "")},
                   {"value": f"{value}{reg.unit or ''}"})


@rule("M004", "partial-register-write", "warning", "A write that covers one byte of a 2-byte register.", f"""
## What it does
Flags a packet whose data starts or ends in the middle of a 2-byte register (goal_position, goal_time,
angle limits, punch), so only its low or high byte changes.

## Why it matters
The servo combines the new byte with whatever the other byte held: a goal of 0x0384 whose high byte
alone is written becomes a goal nobody asked for. The usual cause is a Length one short of the data.

## Example
{example(encode_long(0x1E, [(1, bytes.fromhex("84")), (2, bytes.fromhex("84"))]), note="a long packet writing only goal_position's low byte:")}
""", kinds=("write",), column="header")
def partial_register_write(lint, rec, plan, ids):
    if plan.partial:
        who, sid = _who(ids)
        lint.emit("M004", rec, said("writes only {registers} of {who}", {"registers": ", ".join(plan.partial), "who": who}),
                  sid=sid)


def _known_models() -> str:
    try:
        registry = default_registry()
    except ModelError:
        # A broken map (on RS30X_DECODERS, say) is the command's to report, in one line, when it loads
        # the maps: the rules are declared when the package is imported, before any command runs.
        return "the memory maps that load"
    known = [f"0x{n:04X} {m.name}" for n, m in sorted(registry.by_number.items())]
    # A model no source gives a number for (RS405CB, RS406CB) is never learned from the bus: only named.
    named = [m.name for m in registry.models.values() if m.model_number is None]
    if named:
        known.append(f"{', '.join(named)} by --model only")
    return ", ".join(known)


def _unknown_model_number_columns(named, view) -> bool:
    """M005 on a Block: no return of the model number to judge (one sends the Block row by row)."""
    return not (view.is_return & (view.address == 0) & (view.data_len >= 2)).any()


@rule("M005", "unknown-model-number", "info", "A servo reports a model number no memory map knows.", f"""
## What it does
Flags a return of addresses 0-1 (model_number, table 4.5) whose model number none of the memory maps
in decoders/*.toml has ({_known_models()}). Names the number and the map the servo's
registers are decoded with instead: the one `--model` chose for that ID, else the default. Said once
per servo.

## Why it matters
The sniffer picks each servo's memory map from its model number. An unknown one (0x300C is common in
the field) is decoded as another model, so the registers where the models differ, the top speed
(Q007) and the settable ranges (M003) may be wrong for that servo. Pass `--model` for its ID (a model
whose number no source gives, such as the RS405CB, is known this way only), or add a memory map for
the model under decoders/.

## Example
{example(encode_read(1, 0x00, 2), encode_return(1, 0x00, bytes.fromhex("0C30")), note="a servo answers model number 0x300C:")}
""", kinds=("return",), state=set, column=_unknown_model_number_columns)
def unknown_model_number(named, lint, rec, ev):
    # named: servo IDs already named
    if ev.address != 0:
        return
    data = ev.data
    if len(data) < 2:
        return
    number = data[0] | data[1] << 8
    model = rec.model
    if model is None or number == model.model_number or ev.id in named:
        return
    if number in default_registry().by_number:
        return  # a known model (decoded as another only if --model says so)
    named.add(ev.id)
    # The model number names which model the servo is (as a model's name would): it stays in the key.
    lint.emit("M005", rec, said("ID {id} reports model number 0x{number:04X}, which no memory map knows ({known}); "
                                "decoding it with the {model} map instead",
                                {"id": ev.id, "number": number, "known": _known_models(), "model": model.name}))
