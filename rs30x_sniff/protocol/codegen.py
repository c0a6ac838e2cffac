"""Generated code: the one module of rs30x_sniff that turns source text into functions.

Why. A saturated bus carries hundreds of thousands of frames a second, and a file is decoded faster
still; per frame the package turns the data bytes into engineering values, writes a text line or a JSON
line, and the linter follows a few registers. Interpreting the memory map for every frame (a loop over
the parts, a branch per scale, enum and table) costs several times what one generated expression does,
so for each shape met (a layout of a model, a packet's header) the few functions below are written
once as Python source and compiled: a tuple of conversions after one ``struct.unpack``, one ``%`` or one
f-string per line. Nothing else in the package calls ``eval``, ``exec`` or ``compile``
(tests/protocol/test_codegen.py ``test_only_codegen_compiles_code`` holds it so).

What makes it safe. The callers hand this module plans made of data (registers, tables, indexes,
texts), never source; every piece of source is written here, from:

- identifiers this module makes itself (``r``, ``x``, ``V0``, ``M3``, ...) and attribute names checked
  with :func:`identifier` (``str.isidentifier``, not a keyword);
- integers checked to be ``int`` (indexes, slice bounds, divisors);
- numbers and texts of the memory map (a scale, an offset) through :func:`literal`: ``repr`` of an int,
  float, str, bool or None, which reads back as that value and nothing else;
- format specs matching :data:`FORMAT_SPEC` (alignment, width, precision, a type letter);
- literal text of a line through ``repr`` (a string literal; never an f-string of its own).

Register names, units and enum labels never become identifiers: they reach the generated code as
string literals or as values of its namespace (a table by raw value, a ``%`` format). Nothing of the
input bytes is ever in source: the bytes are the generated functions' arguments. A memory map is
checked when it loads (memmap.parse_model: addresses, sizes, numeric scales, integer enum and table
keys) and a generated function is made only from a loaded map.

What is generated, its reference (the plain form it must equal) and the tests that hold them equal:

- :func:`values_function` (``Layout.values``: the engineering values of a layout's bytes). Reference:
  ``Register.value_of`` of each part's raw value (``Register.convert`` for a whole named register).
  Tests: tests/protocol/test_codegen.py ``test_layout_values_are_the_reference`` (hypothesis: every
  layout of the shipped maps and of a map with every kind of conversion, random bytes),
  tests/protocol/test_memmap.py ``test_engineering_values``.
- :func:`percent_function` (render.layout_json: a layout's fields as JSON text, one ``%``). Reference:
  ``json.dumps`` of ``render.records.field_json`` of ``Layout.fields``. Tests: tests/protocol/test_codegen.py
  ``test_fields_json_is_json_dumps_of_field_json`` (hypothesis), tests/render/test_json_text.py (every
  scenario, partial registers, enums, mixed models), tests/render/test_block_json.py (whole lines).
- :func:`line_function` (render.block_text: a shape's text line, one f-string). Reference:
  ``render.records.text_line``. Each compiled shape is also checked against text_line on its first row
  when it is made (a mismatch sends its rows through Records). Tests: tests/render/test_block_text.py
  (hexapod, every scenario, random traffic, arbitrary frames by hypothesis, odd shapes: Blocks and
  single Records), tests/protocol/test_codegen.py ``test_line_function_writes_its_pieces``.
- :func:`attribute_setter` (lint.state ``Plan.apply``: the tracked registers into a servo's Shadow).
  Reference: ``setattr`` of each ``(attribute, index)`` of ``Plan.tracked``. Test:
  tests/protocol/test_codegen.py ``test_plan_apply_sets_the_tracked_attributes`` (hypothesis).
"""

from __future__ import annotations

import keyword
import math
import re
from typing import Any
from collections.abc import Callable, Iterable, Sequence

__all__ = ["FORMAT_SPEC", "LINE_ARGS", "SERVO", "attribute_setter", "compile_function", "conversion", "identifier",
           "index", "line_function", "literal", "percent_function", "run_definitions", "values_function"]

# A format spec allowed in a generated f-string's replacement field: [align][sign][width][.precision][type].
FORMAT_SPEC = re.compile(r"[<>^=]?[+\- ]?\d*(?:\.\d+)?[dfgs%]?")


# ---- the checks every piece of source passes ----------------------------------------------------
def identifier(name: str) -> str:
    """``name`` if it is a Python identifier and not a keyword; ValueError otherwise."""
    if not (type(name) is str and name.isidentifier() and not keyword.iskeyword(name)):
        raise ValueError(f"not an identifier for generated code: {name!r}")
    return name


def index(k: int) -> str:
    """The source of an integer ``k`` (an index, a bound, a divisor); ValueError for anything else."""
    if type(k) is not int:
        raise ValueError(f"not an integer for generated code: {k!r}")
    return repr(k)


def literal(x: Any) -> str:
    """Source that evaluates to ``x``: ``repr`` of an int, float, str, bool or None (a non-finite float
    as ``float('inf')``); TypeError for any other type."""
    t = type(x)
    if t is float and not math.isfinite(x):
        return f"float({str(x)!r})"
    if t in (int, float, str, bool) or x is None:
        return repr(x)
    raise TypeError(f"no literal for generated code: {x!r} ({t.__name__})")


def _spec(spec: str) -> str:
    if type(spec) is not str or not FORMAT_SPEC.fullmatch(spec):
        raise ValueError(f"not a format spec for generated code: {spec!r}")
    return spec


# ---- compiling ----------------------------------------------------------------------------------
def compile_function(params: Sequence[str], body: str, env: dict[str, Any], what: str) -> Callable:
    """``lambda params: (body)`` compiled with ``env`` as its globals; ``what`` names it in tracebacks.
    ``body`` is source written by this module's builders."""
    head = ", ".join(identifier(p) for p in params)
    code = compile(f"lambda {head}: ({body})", f"<generated: {what}>", "eval")
    return eval(code, env)  # noqa: S307 - source written by this module's builders from checked pieces


def run_definitions(src: str, env: dict[str, Any], what: str) -> dict[str, Any]:
    """Run ``src`` (``def`` statements written by this module's builders) in ``env``; returns ``env``."""
    code = compile(src, f"<generated: {what}>", "exec")
    exec(code, env)  # noqa: S102 - source written by this module's builders from checked pieces
    return env


# ---- a layout's engineering values --------------------------------------------------------------
def conversion(reg: Any, partial: str | None, ref: str, env: dict[str, Any], j: int) -> str:
    """A Python expression turning the raw value ``ref`` (source this module wrote) into the engineering
    value of part ``j`` (``reg``, ``partial``): ``Register.value_of`` as an expression. An enum or table
    goes into ``env`` as ``E<j>`` / ``T<j>``."""
    if partial or reg.name is None:
        return ref
    if reg.enum is not None:
        name = f"E{index(j)}"
        env[name] = reg.enum
        return f"{name}.get({ref}, {ref})"
    if reg.table is not None:
        name = f"T{index(j)}"
        env[name] = reg.table
        return f"{name}.get({ref})"
    scale, offset = reg.scale, reg.offset
    if scale == 1:
        expr = ref
    elif (divisor := reg.divisor) is not None:
        expr = f"{ref} / {index(divisor)}"
    else:
        expr = f"{ref} * {literal(scale)}"
    return f"({literal(offset)} + {expr})" if offset else expr


def values_function(parts: Sequence[tuple[Any, str | None]], records: int, unpack: Callable) -> Callable:
    """``values(data)``: the engineering value of each part (``(register, partial)``) of ``data``, from
    ``unpack`` (the layout's struct, giving one raw integer per part, with ``records`` > 0 each record's
    VID before its parts; the VIDs are left out). ``unpack`` itself when no part needs converting."""
    exprs: list[str] = []
    env: dict[str, Any] = {}
    k = 0
    for _ in range(max(records, 1)):
        if records:
            k += 1  # the VID
        for j, (reg, partial) in enumerate(parts):
            exprs.append(conversion(reg, partial, f"r[{index(k)}]", env, j))
            k += 1
    if all(e == f"r[{i}]" for i, e in enumerate(exprs)):
        return unpack
    env["unpack"] = unpack
    return compile_function(("data",), f"(lambda r: ({', '.join(exprs)},))(unpack(data))", env, "Layout.values")


# ---- a ``%`` format filled from a frame's data --------------------------------------------------
SERVO = ("servo",)  # percent_function's item: the servo ID text ``s``


def percent_function(fmt: str, items: Iterable[tuple]) -> Callable[[bytes, str, tuple, str], str]:
    """``fill(d, h, r, s)``: ``fmt % (item, ...)`` for data bytes ``d``, their hex ``h``, their raw
    integers ``r`` (Layout.unpack_raw) and the servo ID's text ``s``. Each item is one of
    :data:`SERVO` (``s``), ``("hex", a, b)`` (``h[a:b]``), ``("byte", k)`` (``str(d[k])``: a long
    packet's VID) or ``("text", table, k)`` (``table[r[k]]``: a text by raw value)."""
    env: dict[str, Any] = {"F": fmt}
    args = []
    for item in items:
        what = item[0]
        if item == SERVO:
            args.append("s")
        elif what == "hex":
            args.append(f"h[{index(item[1])}:{index(item[2])}]")
        elif what == "byte":
            args.append(f"str(d[{index(item[1])}])")
        elif what == "text":
            name = f"V{len(env) - 1}"
            env[name] = item[1]
            args.append(f"{name}[r[{index(item[2])}]]")
        else:
            raise ValueError(f"percent_function: unknown item {item!r}")
    if not args:
        return lambda d, h, r, s: ""
    return compile_function(("d", "h", "r", "s"), f"F % ({', '.join(args)},)", env, "fields JSON")


# ---- a text line as one f-string ----------------------------------------------------------------
LINE_ARGS = ("t", "o", "r", "l", "q")  # line_function's parameters


def line_function(pieces: Iterable[Any]) -> Callable[[Any, int, tuple | None, Any, Any], str]:
    """``line(t, o, r, l, q)``: the pieces joined, as one f-string (one BUILD_STRING). A piece is a str
    (literal text), ``("arg", name, spec)`` or ``("arg", name, spec, factor)`` (``format(name * factor,
    spec)`` of one of the parameters ``t`` time, ``o`` offset, ``l`` latency, ``q`` request offset),
    ``("text", table, k)`` (``table[r[k]]``) or ``("join", fn, prefix, ((table, k), ...))``
    (``fn(prefix, (table[r[k]], ...))``), ``r`` being the raw integers of the frame's data."""
    env: dict[str, Any] = {}
    src = []

    def name(prefix: str, value: Any) -> str:
        n = f"{prefix}{len(env)}"
        env[n] = value
        return n

    def text(table: Any, k: int) -> str:
        return f"{name('M', table)}[r[{index(k)}]]"

    for piece in pieces:
        if type(piece) is str:
            src.append(repr(piece))  # a string literal: nothing in a label or unit is read as code
            continue
        what = piece[0]
        if what == "arg":
            arg, spec = piece[1], _spec(piece[2])
            if arg not in LINE_ARGS or arg == "r":
                raise ValueError(f"line_function: no argument {arg!r}")
            expr = arg if len(piece) < 4 else f"{arg} * {literal(piece[3])}"
            field = f"{expr}:{spec}" if spec else expr
        elif what == "text":
            field = text(piece[1], piece[2])
        elif what == "join":
            fn, prefix = name("G", piece[1]), name("P", piece[2])
            field = f"{fn}({prefix}, ({', '.join(text(table, k) for table, k in piece[3])},))"
        else:
            raise ValueError(f"line_function: unknown piece {piece!r}")
        src.append("f'{" + field + "}'")
    # Adjacent literals, plain and f-strings, are one string at compile time.
    return compile_function(LINE_ARGS, " ".join(src) or "''", env, "text line")


# ---- attributes set from raw values -------------------------------------------------------------
def attribute_setter(pairs: Iterable[tuple[str, int]]) -> Callable[[Any, tuple], None]:
    """``apply(s, r)``: ``s.attr = r[k]`` for each ``(attr, k)`` of ``pairs``, in order."""
    body = [f"s.{identifier(attr)} = r[{index(k)}]" for attr, k in pairs]
    src = "def apply(s, r):\n    " + ("\n    ".join(body) or "pass") + "\n"
    return run_definitions(src, {}, "attribute setter")["apply"]
