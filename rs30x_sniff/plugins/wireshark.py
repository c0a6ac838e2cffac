"""The Wireshark plug-in: a Lua dissector for `convert -o OUT.pcapng` files, generated from the memory maps."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from .maps import lua_string

LUA_FILE = "rs30x.lua"
PROFILE = "RS30x"  # the Wireshark configuration profile the folder ships: colouring rules and columns
PROFILE_DIR = f"profiles/{PROFILE}"

# Colouring rules (Wireshark's colorfilters format: @name@filter@[background][foreground], 16-bit RGB). The
# colours are those of Wireshark's own defaults: an error as "Checksum Errors" and "Bad TCP" (red text on
# black), a warning as "HSRP State Change" (yellow text on black). They key on the expert info's severity, so a
# bad sum, a cut frame and noise (errors) and a servo's fault flags (warnings) stand out; a note (the capture's
# edge) does not.
COLORFILTERS = """\
# Wireshark colouring rules for the rs30x dissector (written by `rs30x-sniff plugin wireshark`).
# A profile of its own (profiles/RS30x), or import this file: View > Coloring Rules > Import.
@RS30x error@rs30x && _ws.expert.severity == error@[4718,10030,11796][63479,34695,34695]
@RS30x warning@rs30x && _ws.expert.severity == warning@[4718,10030,11796][65535,64764,40092]
"""

# The profile's columns: Wireshark's Length counts the whole record (the export tags and rs30x-sniff's header
# too), so the profile shows the bus's bytes instead (rs30x.bytes), and the Source and Destination the dissector
# fills ("host", "servo 3").
PREFERENCES = """\
# Wireshark preferences of the RS30x profile (written by `rs30x-sniff plugin wireshark`): the columns.
gui.column.format:
\t"No.", "%m",
\t"Time", "%t",
\t"Source", "%s",
\t"Destination", "%d",
\t"Protocol", "%p",
\t"Bytes", "%Cus:rs30x.bytes:0:R",
\t"Info", "%i"
"""


def lua_value(data: Any, indent: str = "") -> str:
    """``data`` (dicts, lists, strings, numbers, booleans, None) as a Lua table constructor: every string
    through :func:`lua_string`, numbers through ``repr``; a None value leaves its key out (a list's None is
    ``false``, so the list stays a sequence). Nothing of ``data`` ever becomes an identifier or code."""
    inner = indent + " "
    if data is None:
        return "false"
    if isinstance(data, bool):
        return "true" if data else "false"
    if isinstance(data, int):
        return repr(data)
    if isinstance(data, float):
        if not math.isfinite(data):
            raise ValueError(f"{data!r}: not a finite number")
        return repr(data)
    if isinstance(data, str):
        return lua_string(data)
    if isinstance(data, (list, tuple)):
        if not data:
            return "{}"
        if all(isinstance(x, (int, float, str)) and not isinstance(x, bool) for x in data):
            return "{" + ", ".join(lua_value(x) for x in data) + "}"
        return "{\n" + "".join(f"{inner}{lua_value(x, inner)},\n" for x in data) + indent + "}"
    if isinstance(data, dict):
        items = [(k, v) for k, v in data.items() if v is not None]
        if not items:
            return "{}"
        parts = []
        for k, v in items:
            if isinstance(k, bool) or not isinstance(k, (int, str)):
                raise ValueError(f"{k!r}: a Lua table key here is a string or an integer")
            key = f"[{k!r}]" if isinstance(k, int) else f"[{lua_string(k)}]"
            parts.append(f"{inner}{key} = {lua_value(v, inner)},\n")
        return "{\n" + "".join(parts) + indent + "}"
    raise ValueError(f"{type(data).__name__}: not plain data")


def lua_data(maps: dict[str, Any]) -> dict[str, Any]:
    """What the dissector needs of ``plugin_maps()``: the models (registers by the fields it reads) and the
    wire's constants; Python dicts with integer keys stay integer-keyed Lua tables."""
    keep = ("name", "label", "address", "size", "signed", "scale", "offset", "unit", "enum", "table", "format",
            "description")
    return {
        "generator": maps["generator"],
        "default_model": maps["default_model"],
        # A model without a number (None: left out of its Lua table) is decoded only when the user names it.
        "models": [{"name": m["name"], "also_named": m.get("also_named") or [], "model_number": m["model_number"],
                    "readable_to": m["readable_to"],
                    "registers": [{k: r[k] for k in keep} for r in m["registers"]]} for m in maps["models"]],
        "protocol": {
            **{k: maps["protocol"][k] for k in ("ack", "nack", "flag_reserved", "return_mode_mask",
                                                "return_flags_reserved", "long_packet_id", "broadcast_id")},
            "commands": maps["protocol"]["commands"],
            "return_modes": {int(mode): {"name": m["name"] or "none", "reads": m["range"] is not None}
                             for mode, m in maps["protocol"]["return_modes"].items()},
            "specified_mode": next(int(mode) for mode, m in maps["protocol"]["return_modes"].items()
                                   if m["expect"] is None),
            "ack_mode": next(int(mode) for mode, m in maps["protocol"]["return_modes"].items()
                             if m["expect"] == "ack"),
            "return_flag_bits": {int(b): n for b, n in maps["protocol"]["return_flag_bits"].items()},
        },
    }


def generate(maps: dict[str, Any]) -> dict[str, str]:
    """The plug-in's files: ``rs30x.lua`` (the maps as a data table, then fixed code) and a README."""
    header = (f"-- rs30x.lua: a Wireshark/tshark dissector for the Futaba RS30x servo bus, for the pcapng files of\n"
              f"-- `rs30x-sniff convert INPUT -o OUT.pcapng`. Generated by {maps['generator']} from its memory maps;\n"
              f"-- regenerate it (`rs30x-sniff plugin wireshark -o DIR`) rather than edit it. Lua 5.2, no modules.\n")
    lua = header + "\nlocal DATA = " + lua_value(lua_data(maps)) + "\n" + LUA_CODE
    return {LUA_FILE: lua, "README.md": readme(maps), f"{PROFILE_DIR}/colorfilters": COLORFILTERS,
            f"{PROFILE_DIR}/preferences": PREFERENCES}


def install_hint(out: Path) -> str:
    lua = out / LUA_FILE
    return (f"Wrote {lua}. Install it for Wireshark and tshark (4.0's personal Lua plug-ins folder, see "
            f"`tshark -G folders`):\n"
            f"  mkdir -p ~/.local/lib/wireshark/plugins && cp {lua} ~/.local/lib/wireshark/plugins/\n"
            f"or load it for one run:\n"
            f"  tshark -X lua_script:{lua} -r OUT.pcapng\n"
            f"OUT.pcapng comes from `rs30x-sniff convert CAPTURE -o OUT.pcapng`.\n"
            f"Faults in colour and the bus's bytes as a column: install the profile {PROFILE} and choose it "
            f"(Edit > Configuration Profiles, or `wireshark -C {PROFILE}`):\n"
            f"  mkdir -p ~/.config/wireshark/profiles && cp -r {out / PROFILE_DIR} ~/.config/wireshark/profiles/\n"
            f"or import only its colouring rules: View > Coloring Rules > Import > "
            f"{out / PROFILE_DIR / 'colorfilters'}")


def readme(maps: dict[str, Any]) -> str:
    models = ", ".join(m["name"] for m in maps["models"])
    return f"""# rs30x: a Wireshark dissector for the Futaba RS30x servo bus

Generated by {maps["generator"]} from its memory maps (models: {models}; default {maps["default_model"]}).

1. Make a pcapng of a capture: `rs30x-sniff convert CAPTURE -o OUT.pcapng`
   (one packet per frame and per garbage run; lint findings are packet comments).
2. Install: `mkdir -p ~/.local/lib/wireshark/plugins && cp rs30x.lua ~/.local/lib/wireshark/plugins/`
   (Wireshark 4.0's personal Lua plug-ins folder; `tshark -G folders` shows it), or load it once:
   `tshark -X lua_script:rs30x.lua -r OUT.pcapng`.
3. Filter on engineering values, e.g. `rs30x.id == 3 && rs30x.present_temperature > 40`,
   `rs30x.checksum_status == 0` (bad Sum), `rs30x.kind == "garbage"`.

4. Faults in colour: install the profile `{PROFILE}` (`mkdir -p ~/.config/wireshark/profiles && cp -r
   {PROFILE_DIR} ~/.config/wireshark/profiles/`) and choose it (Edit > Configuration Profiles, or
   `wireshark -C {PROFILE}`). Its colouring rules show an error (a bad sum, a cut frame, noise) in red on black
   and a warning (a servo's fault flags) in yellow on black, as Wireshark's own rules show checksum errors and
   state changes; View > Coloring Rules > Import takes its `colorfilters` into another profile. Its columns
   show the bus's bytes (`rs30x.bytes`) where Length counts the whole record (the export tags and this
   header too). Faults also lead the Info column (`[BAD CHECKSUM] write id 1 ...`), and Source and
   Destination say `host`, `servo N`.

The model a packet is decoded with is the one rs30x-sniff decoded it with (written in the packet), unless the
preference "Model" (Edit > Preferences > Protocols > RS30X, or `tshark -o rs30x.model:RS304MD`) names one.
A reply links to its request (`rs30x.request`; the request to its reply, `rs30x.response`, once Wireshark has
seen both: in tshark, with `-2`).

The file's link type is LINKTYPE_WIRESHARK_UPPER_PDU (252): each packet starts with an exported-PDU tag naming
the dissector "rs30x" (so Wireshark needs no setting to use this one, and shows the name without it), then
rs30x-sniff's header (u8 version 1, u8 kind 1-6: short, long, return, ack, nack, garbage; u8 direction 0-2 as
the packet's flags; u8 reason length; u32 big-endian frame number of the request a reply answers, 0 for none;
u8 model length; the reason and model texts), then the bytes as they were on the wire.
"""


# The dissector's code: fixed text, reading the maps only from DATA (above it). Register names are table keys
# and strings (the field "rs30x." .. name), never identifiers.
LUA_CODE = r"""
local P = DATA.protocol
local rs30x = Proto("rs30x", "Futaba RS30x servo bus")

-- ---- the models -------------------------------------------------------------------------------------
local MODELS, BY_NAME, BY_NUMBER = {}, {}, {}
for i, m in ipairs(DATA.models) do
  local by_address = {}
  for _, reg in ipairs(m.registers) do
    for a = reg.address, reg.address + reg.size - 1 do by_address[a] = reg end
  end
  m.by_address = by_address
  MODELS[i] = m
  if BY_NAME[m.name] == nil then BY_NAME[m.name] = m end
  -- A model with no known model number (nil) is used only when the user or the capture names it.
  if m.model_number ~= nil and BY_NUMBER[m.model_number] == nil then BY_NUMBER[m.model_number] = m end
end
for _, m in ipairs(MODELS) do  -- another name of a map, unless a model of that name has a map of its own
  for _, other in ipairs(m.also_named) do
    if BY_NAME[other] == nil then BY_NAME[other] = m end
  end
end
local DEFAULT = BY_NAME[DATA.default_model] or MODELS[1]

local function register_at(model, a)
  local reg = model.by_address[a]
  if reg == nil then
    reg = {label = "addr_" .. a, address = a, size = 1, signed = false, scale = 1, offset = 0}
    model.by_address[a] = reg
  end
  return reg
end

-- ---- fields -------------------------------------------------------------------------------------------
local KINDS = {[1] = "short", [2] = "long", [3] = "return", [4] = "ack", [5] = "nack", [6] = "garbage"}
local DIRECTIONS = {[0] = "unknown", [1] = "inbound (servo to host)", [2] = "outbound (host to servo)"}
local CHECKSUM_STATUS = {[0] = "Bad", [1] = "Good", [2] = "Unverified", [3] = "Not present"}
local MODE_NAMES = {}
for mode, m in pairs(P.return_modes) do MODE_NAMES[mode] = m.name end

local hf = {
  header = ProtoField.uint16("rs30x.header", "Header", base.HEX),
  id = ProtoField.uint8("rs30x.id", "ID", base.DEC),
  flag = ProtoField.uint8("rs30x.flag", "Flag", base.HEX),
  return_mode = ProtoField.uint8("rs30x.flag.return_mode", "Return mode", base.HEX, MODE_NAMES,
                                 P.return_mode_mask),
  flag_reserved = ProtoField.bool("rs30x.flag.reserved", "Reserved bit", 8, nil, P.flag_reserved),
  return_reserved = ProtoField.uint8("rs30x.return_flag.reserved", "Reserved bits", base.HEX, nil,
                                     P.return_flags_reserved),
  address = ProtoField.uint8("rs30x.address", "Address", base.DEC),
  length = ProtoField.uint8("rs30x.length", "Length", base.DEC),
  count = ProtoField.uint8("rs30x.count", "Count", base.DEC),
  sum = ProtoField.uint8("rs30x.sum", "Sum", base.HEX),
  checksum_status = ProtoField.uint8("rs30x.checksum_status", "Checksum status", base.DEC, CHECKSUM_STATUS),
  direction = ProtoField.uint8("rs30x.direction", "Direction", base.DEC, DIRECTIONS),
  kind = ProtoField.string("rs30x.kind", "Kind"),
  op = ProtoField.string("rs30x.op", "Operation"),
  reason = ProtoField.string("rs30x.reason", "Why the bytes were skipped"),
  model = ProtoField.string("rs30x.model", "Model"),
  vid = ProtoField.uint8("rs30x.vid", "VID", base.DEC),
  record = ProtoField.bytes("rs30x.record", "Servo record"),
  data = ProtoField.bytes("rs30x.data", "Data"),
  garbage = ProtoField.bytes("rs30x.garbage", "Garbage"),
  request = ProtoField.framenum("rs30x.request", "Request in", base.NONE, frametype.REQUEST),
  response = ProtoField.framenum("rs30x.response", "Reply in", base.NONE, frametype.RESPONSE),
  partial = ProtoField.uint8("rs30x.partial", "One byte of a 2-byte register", base.HEX),
  unnamed = ProtoField.uint8("rs30x.unnamed", "Undocumented byte", base.HEX),
  unknown_code = ProtoField.uint32("rs30x.unknown_code", "Code with no value in the register's table", base.DEC),
  -- Wireshark's Length column counts the whole record, export tags and our header too: this is the bus's share.
  bytes = ProtoField.uint32("rs30x.bytes", "Bytes on the bus", base.DEC),
}
-- Names a register may not take as its field (a clash with the fields above): such a register is rs30x.reg_NAME.
local TAKEN = {}
for key, _ in pairs(hf) do TAKEN[key] = true end
TAKEN.return_flag = true

local flag_bits = {}
for _, cb in ipairs(P.commands) do
  local f = ProtoField.bool("rs30x.flag." .. cb[2], cb[2], 8, nil, cb[1])
  flag_bits[#flag_bits + 1] = f
  hf["flag." .. cb[2]] = f
end
local return_bits, bit_list = {}, {}
for b, _ in pairs(P.return_flag_bits) do bit_list[#bit_list + 1] = b end
table.sort(bit_list, function(x, y) return x > y end)
for _, b in ipairs(bit_list) do
  local name = P.return_flag_bits[b]
  local f = ProtoField.bool("rs30x.return_flag." .. name, name, 8, nil, b)
  return_bits[#return_bits + 1] = {bit = b, name = name, field = f}
  hf["return_flag." .. name] = f
end

-- One field per register name over every model: the engineering value as decode shows it (a double in its
-- unit; a whole number as an integer; an enumeration as its raw code with the labels as value strings).
local REG_FIELDS = {}
local function register_field(reg)
  local name = reg.name
  if REG_FIELDS[name] then return end
  local enum, numeric_ok, signed, hex, size = nil, true, false, false, 1
  for _, m in ipairs(MODELS) do
    for _, r in ipairs(m.registers) do
      if r.name == name then
        if r.enum and enum == nil then enum = r.enum end
        if r.table or r.scale ~= 1 or r.offset ~= 0 then numeric_ok = false end
        if r.signed then signed = true end
        if r.format == "hex" then hex = true end
        if r.size > size then size = r.size end
      end
    end
  end
  local abbr = "rs30x." .. (TAKEN[name] and ("reg_" .. name) or name)
  local descr = reg.description ~= "" and reg.description or nil
  local f
  if enum then
    f = (signed and ProtoField.int32 or ProtoField.uint32)(abbr, name, base.DEC, enum, nil, descr)
  elseif numeric_ok and signed then
    f = ProtoField.int32(abbr, name, base.DEC, nil, nil, descr)
  elseif numeric_ok and hex then
    -- As wide as the register, so a model number reads 0x3030 as everywhere else (not 0x00003030).
    local uint = size == 1 and ProtoField.uint8 or (size == 2 and ProtoField.uint16 or ProtoField.uint32)
    f = uint(abbr, name, base.HEX, nil, nil, descr)
  elseif numeric_ok then
    f = ProtoField.uint32(abbr, name, base.DEC, nil, nil, descr)
  else
    f = ProtoField.double(abbr, name, descr)
  end
  REG_FIELDS[name] = {field = f, enum = enum ~= nil, integer = numeric_ok}
  hf["register:" .. name] = f
end
for _, m in ipairs(MODELS) do
  for _, reg in ipairs(m.registers) do
    if reg.name then register_field(reg) end
  end
end

local fields = {}
for _, f in pairs(hf) do fields[#fields + 1] = f end
rs30x.fields = fields

local ef = {
  bad_checksum = ProtoExpert.new("rs30x.checksum_bad", "Bad checksum", expert.group.CHECKSUM, expert.severity.ERROR),
  cut = ProtoExpert.new("rs30x.cut", "Cut frame", expert.group.MALFORMED, expert.severity.ERROR),
  -- The capture's edge is a fact, not a fault of the bus: a note, left uncoloured.
  edge = ProtoExpert.new("rs30x.capture_edge", "Frame cut by the capture's start or end", expert.group.MALFORMED,
                         expert.severity.NOTE),
  noise = ProtoExpert.new("rs30x.noise", "Noise or garbage bytes", expert.group.PROTOCOL, expert.severity.WARN),
  status = ProtoExpert.new("rs30x.status", "The servo reports a fault", expert.group.RESPONSE_CODE,
                           expert.severity.WARN),
  header = ProtoExpert.new("rs30x.bad_header", "Not an rs30x-sniff packet header", expert.group.MALFORMED,
                           expert.severity.ERROR),
}
rs30x.experts = {ef.bad_checksum, ef.cut, ef.edge, ef.noise, ef.status, ef.header}

-- ---- preferences --------------------------------------------------------------------------------------
local MODEL_CHOICES = {{1, "as decoded (recorded in the capture)", 0}}
for i, m in ipairs(MODELS) do MODEL_CHOICES[#MODEL_CHOICES + 1] = {i + 1, m.name, i} end
for i, m in ipairs(MODELS) do  -- another name of a map (RS406CB for RS405CB's) decodes with that map
  for _, other in ipairs(m.also_named) do
    if BY_NAME[other] == m then MODEL_CHOICES[#MODEL_CHOICES + 1] = {#MODEL_CHOICES + 1, other, i} end
  end
end
rs30x.prefs.model = Pref.enum("Model", 0, "The memory map to decode registers with: the one rs30x-sniff " ..
                              "decoded each packet with (its default " .. DEFAULT.name .. "), or this one",
                              MODEL_CHOICES, false)

-- ---- state over a file: who asked what, the model a servo said it is ----------------------------------
local frames, replies, learned = {}, {}, {}
function rs30x.init()
  frames, replies, learned = {}, {}, {}
end

local function model_for(recorded, id)
  local forced = rs30x.prefs.model
  if forced and forced > 0 and MODELS[forced] then return MODELS[forced] end
  local m = BY_NAME[recorded]
  if m then return m end
  if id and learned[id] then return learned[id] end
  return DEFAULT
end

-- A register's engineering value from its raw value (rs30x_sniff.protocol.memmap.Register.convert): an
-- exact decimal step divides (900 / 10, not 900 * 0.1) so values match decode's to the last digit.
local function convert(reg, raw)
  if reg.table then return reg.table[raw] end
  local scale, v = reg.scale, raw
  if scale ~= 1 then
    local inv = 1 / scale
    local div = math.floor(inv + 0.5)
    if scale < 1 and math.abs(inv - div) < 1e-9 then v = raw / div else v = raw * scale end
  end
  if reg.offset ~= 0 then v = v + reg.offset end
  return v
end

local function fmt(v)
  if v == math.floor(v) and math.abs(v) < 1e15 then return string.format("%d", v) end
  return string.format("%.6g", v)
end

-- The fields of ``len`` data bytes at ``tvb(start)`` written to or read from ``address`` (Layout.parts).
local function add_registers(tree, tvb, start, len, address, model, summary)
  local a, stop = address, address + len
  while a < stop do
    local reg = register_at(model, a)
    local pos = start + (a - address)
    if a == reg.address and a + reg.size <= stop then
      local range = tvb(pos, reg.size)
      local raw = reg.size == 1 and range:uint() or range:le_uint()
      if reg.signed then
        local top = 2 ^ (8 * reg.size)
        if raw >= top / 2 then raw = raw - top end
      end
      if reg.name == nil then
        tree:add(hf.unnamed, range, raw):set_text(reg.label .. ": " .. raw)
      else
        local rf = REG_FIELDS[reg.name]
        local unit = reg.unit and (" " .. reg.unit) or ""
        if reg.enum then
          -- The label of this model's map (the field's value strings are those of the first map naming it).
          local label = reg.enum[raw]
          tree:add(rf.field, range, raw):set_text(reg.name .. ": " .. (label or "unknown") .. " (" .. raw .. ")")
          summary[#summary + 1] = reg.name .. "=" .. (label or tostring(raw))
        else
          local v = convert(reg, raw)
          if v == nil then
            tree:add(hf.unknown_code, range, raw):set_text(reg.name .. ": code " .. raw .. " (not in its table)")
            summary[#summary + 1] = reg.name .. "=?"
          elseif reg.format == "hex" then
            -- The one number format for such registers (model_number 0x3030), in the tree and the Info column.
            local text = string.format("0x%0" .. (2 * reg.size) .. "X", v)
            tree:add(rf.field, range, v):set_text(reg.name .. ": " .. text)  -- upper case, as decode writes it
            summary[#summary + 1] = reg.name .. "=" .. text
          else
            local item = tree:add(rf.field, range, v)
            if unit ~= "" then item:append_text(unit) end
            summary[#summary + 1] = reg.name .. "=" .. fmt(v) .. unit
          end
        end
      end
      a = a + reg.size
    else
      local range = tvb(pos, 1)
      local half = a == reg.address and "low" or "high"
      tree:add(hf.partial, range):set_text(reg.label .. " (" .. half .. " byte): 0x" ..
                                           string.format("%02X", range:uint()))
      a = a + 1
    end
  end
end

local function checksum_of(tvb, n)
  local x = 0
  for i = 2, n - 2 do x = bit32.bxor(x, tvb(i, 1):uint()) end
  return x
end

local function request_op(flag, has_data)
  local cmds = {}
  for _, cb in ipairs(P.commands) do
    if bit32.band(flag, cb[1]) ~= 0 then cmds[#cmds + 1] = cb[2] end
  end
  if #cmds > 0 then return table.concat(cmds, "+") end
  local mode = bit32.band(flag, P.return_mode_mask)
  local m = P.return_modes[mode]
  local reads = mode == P.specified_mode or (m ~= nil and m.reads)
  local ack = mode == P.ack_mode
  if has_data then return reads and "write+read" or (ack and "write+ack" or "write") end
  if reads then return "read" end
  return ack and "ping" or "empty"
end

-- ---- the dissector ----------------------------------------------------------------------------------
-- A packet of `convert -o OUT.pcapng`: after Wireshark's exported-PDU tags (which name this dissector), the
-- rs30x header (u8 version 1, u8 kind, u8 direction, u8 reason length, u32 request frame, u8 model length,
-- reason, model), then the bytes of the frame or garbage run as they were on the wire.
function rs30x.dissector(tvb, pinfo, tree)
  local total = tvb:len()
  pinfo.cols.protocol = "RS30x"
  local t = tree:add(rs30x, tvb())
  local off = total >= 10 and tvb(0, 1):uint() == 1 and 9 + tvb(3, 1):uint() + tvb(8, 1):uint() or total
  if off >= total then
    t:add_proto_expert_info(ef.header)
    return total
  end
  local kind = KINDS[tvb(1, 1):uint()] or "garbage"
  local direction = tvb(2, 1):uint()
  local rlen = tvb(3, 1):uint()
  local request_frame = tvb(4, 4):uint()
  local mlen = tvb(8, 1):uint()
  local reason = rlen > 0 and tvb(9, rlen):string() or ""
  local recorded = mlen > 0 and tvb(9 + rlen, mlen):string() or ""
  local wire = tvb(off):tvb()
  local n = wire:len()
  t:add(hf.kind, tvb(1, 1), kind)
  t:add(hf.direction, tvb(2, 1))
  t:add(hf.bytes, n):set_generated()
  if not pinfo.visited then
    frames[pinfo.number] = {kind = kind}
    if request_frame > 0 then replies[request_frame] = pinfo.number end
  end
  local info, src, dst
  local faults = {}  -- what went wrong, said first in the Info column (its end is cut in a narrow window)

  if kind == "garbage" then
    if rlen > 0 then t:add(hf.reason, tvb(9, rlen), reason) end
    local g = t:add(hf.garbage, wire())
    if reason == "truncated" then g:add_proto_expert_info(ef.cut)
    elseif reason == "capture-start" or reason == "capture-end" then g:add_proto_expert_info(ef.edge)
    else g:add_proto_expert_info(ef.noise) end
    info = "garbage (" .. reason .. "), " .. n .. " byte" .. (n == 1 and "" or "s")
  elseif kind == "ack" or kind == "nack" then
    local req = request_frame > 0 and frames[request_frame] or nil
    if req and req.id then t:add(hf.id, req.id):set_generated() end
    if request_frame > 0 then t:add(hf.request, request_frame):set_generated() end
    t:add(hf.checksum_status, 3):set_generated()
    info = string.upper(kind) .. (req and req.id and (" from id " .. req.id) or "")
    src, dst = req and req.id and ("servo " .. req.id) or "servo", "host"
  else
    local id = wire(2, 1):uint()
    local flag = wire(3, 1):uint()
    local address, length, count = wire(4, 1):uint(), wire(5, 1):uint(), wire(6, 1):uint()
    local model = model_for(recorded, id)
    if mlen > 0 and model.name == recorded then t:add(hf.model, tvb(9 + rlen, mlen), model.name)
    else t:add(hf.model, model.name):set_generated() end
    t:add(hf.header, wire(0, 2))
    t:add(hf.id, wire(2, 1))
    local flag_item = t:add(hf.flag, wire(3, 1))
    local summary = {}
    local data_len = n - 8
    if kind == "return" then
      for _, rb in ipairs(return_bits) do flag_item:add(rb.field, wire(3, 1)) end
      flag_item:add(hf.return_reserved, wire(3, 1))
      local set = {}
      for _, rb in ipairs(return_bits) do
        if bit32.band(flag, rb.bit) ~= 0 then set[#set + 1] = rb.name end
      end
      if #set > 0 then
        flag_item:append_text(" (" .. table.concat(set, ", ") .. ")")
        flag_item:add_proto_expert_info(ef.status, "The servo reports: " .. table.concat(set, ", "))
        for _, name in ipairs(set) do faults[#faults + 1] = string.gsub(name, "_", " ") end
      end
    else
      for _, f in ipairs(flag_bits) do flag_item:add(f, wire(3, 1)) end
      if kind == "short" then flag_item:add(hf.return_mode, wire(3, 1)) end
      flag_item:add(hf.flag_reserved, wire(3, 1))
    end
    t:add(hf.address, wire(4, 1))
    t:add(hf.length, wire(5, 1))
    t:add(hf.count, wire(6, 1))
    if data_len > 0 then
      local d = t:add(hf.data, wire(7, data_len))
      if kind == "long" then
        if length > 0 then
          local k = 0
          while k < data_len do
            local size = math.min(length, data_len - k)
            local vid = wire(7 + k, 1):uint()
            local rec = d:add(hf.record, wire(7 + k, size))
            rec:set_text("Servo " .. vid)
            rec:add(hf.vid, wire(7 + k, 1))
            local before = #summary
            if size > 1 then add_registers(rec, wire, 8 + k, size - 1, address, model_for(recorded, vid), summary) end
            if #summary > before then summary[before + 1] = "[" .. vid .. "] " .. summary[before + 1] end
            k = k + length
          end
        end
      else
        add_registers(d, wire, 7, data_len, address, model, summary)
      end
    end
    local sum = wire(n - 1, 1):uint()
    local sum_item = t:add(hf.sum, wire(n - 1, 1))
    local good = checksum_of(wire, n) == sum
    t:add(hf.checksum_status, good and 1 or 0):set_generated()
    if not good then
      sum_item:append_text(string.format(" [should be 0x%02X]", checksum_of(wire, n)))
      sum_item:add_proto_expert_info(ef.bad_checksum)
      table.insert(faults, 1, "BAD CHECKSUM")
    end
    if not pinfo.visited then frames[pinfo.number].id = id end
    local what
    if kind == "return" then
      what = "return"
      src, dst = "servo " .. id, "host"
      if request_frame > 0 then t:add(hf.request, request_frame):set_generated() end
      -- A servo that says its model number: decode its later packets with that model (as decode's tracker).
      if not pinfo.visited and address == 0 and data_len >= 2 then
        local found = BY_NUMBER[wire(7, 2):le_uint()]
        if found then learned[id] = found end
      end
    else
      local op = kind == "long" and "write" or request_op(flag, data_len > 0)
      src = "host"
      if kind == "long" then dst = "servos"
      elseif id == P.broadcast_id then dst = "all servos"
      else dst = "servo " .. id end
      t:add(hf.op, op):set_generated()
      what = (kind == "long" and "long " or "") .. op
      local reply = replies[pinfo.number]
      if reply then t:add(hf.response, reply):set_generated() end
    end
    info = what .. " id " .. id .. " @" .. address .. (#summary > 0 and (": " .. table.concat(summary, " ")) or "")
  end
  if #faults > 0 then info = "[" .. table.concat(faults, ", ") .. "] " .. info end
  t:append_text(", " .. kind)
  pinfo.cols.info = info
  -- Who sent it and to whom, in the Source and Destination columns (garbage: nobody can say).
  if src then pinfo.cols.src = src end
  if dst then pinfo.cols.dst = dst end
  return total
end
"""
