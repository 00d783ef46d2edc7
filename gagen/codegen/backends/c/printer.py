"""Our C emitter over the flat graph: one C statement per instruction of a CasADi SX Function.

The instruction list is walked in CasADi's order, and each work-vector slot becomes a C local
(``w12``), so the C program performs exactly the operations CasADi's virtual machine performs, in
the same order, with libm for the transcendental calls: the C kernels and the CasADi Functions give
the same doubles (compile without FMA contraction to keep it so). Outputs are dense column-major
arrays; structural zeros of an output's sparsity are written as 0.

One exception, for speed [issue 19, item 2]: the sines and cosines whose angles do not depend on
another sine or cosine (the joint angles, or their halves in a motor) are evaluated together, up
front, by one vector call per 8 angles (``gagen_sincos`` of the template: glibc's libmvec where the
build has it, within 4 ulp of libm's; libm's own ``sin``/``cos`` otherwise or with
``-DGAGEN_SCALAR_TRIG``, which gives CasADi's doubles again). The angles are recomputed for that
prologue from the same instructions, so they are the same doubles the body would have passed to libm.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import casadi as ca

from gagen.symbolic.flatten import OPCODES

_BINARY = {"ADD": "{0} + {1}", "SUB": "{0} - {1}", "MUL": "{0} * {1}", "DIV": "{0} / {1}",
           "LT": "{0} < {1}", "LE": "{0} <= {1}", "EQ": "{0} == {1}", "NE": "{0} != {1}",
           "AND": "{0} && {1}", "OR": "{0} || {1}", "IF_ELSE_ZERO": "{0} ? {1} : {zero}",
           "ATAN2": "atan2({0}, {1})", "POW": "pow({0}, {1})", "CONSTPOW": "pow({0}, {1})",
           "FMIN": "fmin({0}, {1})", "FMAX": "fmax({0}, {1})", "COPYSIGN": "copysign({0}, {1})",
           "FMOD": "fmod({0}, {1})", "HYPOT": "hypot({0}, {1})"}
_UNARY = {"NEG": "-{0}", "SQ": "{0} * {0}", "TWICE": "{0} + {0}", "INV": "{one} / {0}", "NOT": "!{0}",
          "SIGN": "gagen_sign({0})", "FABS": "fabs({0})"}
_LIBM = ("SQRT", "SIN", "COS", "TAN", "ASIN", "ACOS", "ATAN", "SINH", "COSH", "TANH", "ASINH", "ACOSH",
         "ATANH", "EXP", "LOG", "FLOOR", "CEIL", "ERF", "LOG1P", "EXPM1")


class UnsupportedOperation(ValueError):
    """The graph holds an operation the emitter has no C form for."""


@dataclass(frozen=True)
class Dialect:
    """How the scalar statements spell what differs between C and another C-like target (the CUDA
    backend's type-generic bodies): the type of the locals, a constant (C: the shortest decimal that
    reads back as the double), and an element ``k`` of a port's array ``name``."""

    real: str = "double"
    constant: Callable[[float], str] | None = None  # None: c_literal
    element: Callable[[str, int], str] | None = None  # None: name[k]

    def literal(self, value: float) -> str:
        return self.constant(value) if self.constant else c_literal(value)

    def at(self, name: str, k: int) -> str:
        return self.element(name, k) if self.element else f"{name}[{k}]"


C = Dialect()


@dataclass(frozen=True)
class CBody:
    """The statements of one kernel body and the locals they use; ``trig``: the statements of the
    vector-trig prologue (empty when the kernel has fewer than two angles to batch)."""

    locals: tuple[str, ...]
    statements: tuple[str, ...]
    trig: tuple[str, ...] = field(default=())


# Angles per vector block of the trig prologue (the widest libmvec variant, AVX-512, has 8 lanes).
TRIG_LANES = 8
_TRIG = ("SIN", "COS")


@dataclass(frozen=True)
class _TrigPlan:
    """Which instructions the prologue replaces: instruction index -> (SIN or COS, lane)."""

    lanes: dict[int, tuple[str, int]]
    prologue: tuple[str, ...]


def _trig_plan(function: ca.Function, input_names: list[str],
               in_positions: list[list[int]], dialect: Dialect = C) -> _TrigPlan | None:
    """The vector-trig prologue of ``function`` (see the module docstring), or None when fewer than two
    distinct angles qualify.

    The instruction list reuses work-vector slots, so it is read as SSA first: each instruction's
    arguments are the instructions that last wrote their slots. An angle qualifies when nothing it
    depends on is a sine or cosine; the prologue replays just the instructions it depends on, as
    ``gagen_a<k>`` constants (inputs and literals inline), into ``gagen_x``."""
    writer: dict[int, int] = {}  # slot -> the instruction that last wrote it
    ops: list[str] = []
    deps: list[tuple[int, ...]] = []
    tainted: list[bool] = []  # depends on a sine or cosine
    angles: dict[int, int] = {}  # angle instruction -> lane
    lanes: dict[int, tuple[str, int]] = {}
    for k in range(function.n_instructions()):
        op = OPCODES.get(function.instruction_id(k), "?")
        args, res = function.instruction_input(k), function.instruction_output(k)
        d = () if op in ("INPUT", "CONST") else tuple(writer[a] for a in args)
        ops.append(op)
        deps.append(d)
        tainted.append(op in _TRIG or any(tainted[j] for j in d))
        if op in _TRIG and not tainted[d[0]]:
            lane = angles.setdefault(d[0], len(angles))
            lanes[k] = (op, lane)
        if op != "OUTPUT":
            writer[res[0]] = k
    if len(angles) < 2:
        return None
    needed: set[int] = set()
    stack = list(angles)
    while stack:
        k = stack.pop()
        if k not in needed:
            needed.add(k)
            stack.extend(deps[k])
    text: dict[int, str] = {}
    prologue: list[str] = []
    for k in sorted(needed):
        op, w = ops[k], [text[j] for j in deps[k]]
        if op == "INPUT":
            i, nz = function.instruction_input(k)
            text[k] = dialect.at(input_names[i], in_positions[i][nz])
            continue
        if op == "CONST":
            text[k] = dialect.literal(function.instruction_constant(k))
            continue
        if op in ("ASSIGN", "PARAMETER"):
            text[k] = w[0]
            continue
        words = {"zero": dialect.literal(0.0), "one": dialect.literal(1.0)}
        if op in _BINARY:
            expr = _BINARY[op].format(*w, **words)
        elif op in _UNARY:
            expr = _UNARY[op].format(*w, **words)
        elif op in _LIBM:
            expr = f"{op.lower()}({w[0]})"
        else:
            return None  # the body's emitter names the operation
        prologue.append(f"const {dialect.real} gagen_a{k} = {expr};")
        text[k] = f"gagen_a{k}"
    size = -(-len(angles) // TRIG_LANES) * TRIG_LANES
    values = [text[k] for k in angles] + [dialect.literal(0.0)] * (size - len(angles))
    real = dialect.real
    prologue.append(f"{real} gagen_x[{size}] = {{{', '.join(values)}}}, gagen_s[{size}], gagen_c[{size}];")
    prologue.append(f"gagen_sincos({len(angles)}, gagen_x, gagen_s, gagen_c);")
    return _TrigPlan(lanes, tuple(prologue))


def c_literal(value: float) -> str:
    """The shortest decimal that reads back as exactly ``value``."""
    if math.isnan(value):
        return "NAN"
    if math.isinf(value):
        return "INFINITY" if value > 0 else "(-INFINITY)"
    text = repr(float(value))
    return f"({text})" if text.startswith("-") else text


def _dense_positions(sparsity: ca.Sparsity) -> list[int]:
    """Column-major dense index of each structural nonzero."""
    return [int(i) for i in sparsity.find()]


# The vector dialect: GCC/Clang vector extensions over W samples at once (the SIMD batch). Arithmetic
# keeps its C syntax; the rest goes through the gagen_v_* helpers of the template.
_VECTOR_BINARY = {**{k: v for k, v in _BINARY.items() if k in ("ADD", "SUB", "MUL", "DIV")},
                  **{k: f"gagen_v_{k.lower()}({{0}}, {{1}})" for k in ("LT", "LE", "EQ", "NE", "AND", "OR")},
                  "IF_ELSE_ZERO": "gagen_v_if_else_zero({0}, {1})", "ATAN2": "gagen_v_atan2({0}, {1})"}
_VECTOR_UNARY = {"NEG": "-{0}", "SQ": "{0} * {0}", "TWICE": "{0} + {0}", "INV": "1.0 / {0}",
                 "NOT": "gagen_v_not({0})", "FABS": "gagen_v_fabs({0})", "SIN": "gagen_v_sin({0})",
                 "COS": "gagen_v_cos({0})", "SQRT": "gagen_v_sqrt({0})"}


def emit_body(function: ca.Function, input_names: list[str], output_names: list[str], *,
              vector: bool = False, dialect: Dialect = C) -> CBody:
    """C statements evaluating ``function`` from arrays ``input_names`` into ``output_names``, with
    the vector-trig prologue (``CBody.trig``) in the scalar form.

    ``vector=True`` emits the same instructions on vectors of W samples (the template's ``gagen_v``
    type): inputs are gathered from and outputs scattered to W consecutive samples of the batched
    arrays; operations without a vector form run lane by lane (``GAGEN_V1``/``GAGEN_V2``).
    ``dialect`` spells the scalar form's types, literals and array elements (C by default).
    """
    in_positions = [_dense_positions(function.sparsity_in(i)) for i in range(function.n_in())]
    out_positions = [_dense_positions(function.sparsity_out(i)) for i in range(function.n_out())]
    in_sizes = [function.numel_in(i) for i in range(function.n_in())]
    out_sizes = [function.numel_out(i) for i in range(function.n_out())]

    def store(o: int, k: int, value: str) -> str:
        if vector:
            return f"GAGEN_SCATTER({output_names[o]}, {out_sizes[o]}, {k}, {value});"
        return f"{dialect.at(output_names[o], k)} = {value};"

    statements: list[str] = []
    for o in range(len(output_names)):  # structural zeros first, then the computed entries
        written = set(out_positions[o])
        zero = "gagen_v_splat(0.0)" if vector else dialect.literal(0.0)
        statements += [store(o, k, zero) for k in range(out_sizes[o]) if k not in written]
    binary, unary = (_VECTOR_BINARY, _VECTOR_UNARY) if vector else (_BINARY, _UNARY)
    plan = None if vector else _trig_plan(function, input_names, in_positions, dialect)
    words = ({"zero": "gagen_v_splat(0.0)", "one": "1.0"} if vector
             else {"zero": dialect.literal(0.0), "one": dialect.literal(1.0)})
    used: set[int] = set()
    for k in range(function.n_instructions()):
        op = OPCODES.get(function.instruction_id(k), "?")
        args, res = function.instruction_input(k), function.instruction_output(k)
        w = [f"w{i}" for i in args]
        if op == "OUTPUT":
            statements.append(store(res[0], out_positions[res[0]][res[1]], w[0]))
            continue
        target = f"w{res[0]}"
        used.add(res[0])
        if op == "INPUT":
            i, nz = args[0], in_positions[args[0]][args[1]]
            expr = (f"GAGEN_GATHER({input_names[i]}, {in_sizes[i]}, {nz})" if vector
                    else dialect.at(input_names[i], nz))
        elif op == "CONST":
            value = function.instruction_constant(k)
            expr = f"gagen_v_splat({c_literal(value)})" if vector else dialect.literal(value)
        elif op in ("ASSIGN", "PARAMETER"):
            expr = w[0]
        elif plan and k in plan.lanes:
            kind, lane = plan.lanes[k]
            expr = f"gagen_{kind[0].lower()}[{lane}]"
        elif op in binary:
            expr = binary[op].format(*w, **words)
        elif op in unary:
            expr = unary[op].format(*w, **words)
        elif vector and (op in _LIBM or op == "SIGN"):
            expr = f"GAGEN_V1({'gagen_sign' if op == 'SIGN' else op.lower()}, {w[0]})"
        elif vector and op in _BINARY and _BINARY[op].endswith(")"):  # atan2, pow, fmin, ...
            expr = f"GAGEN_V2({_BINARY[op].split('(')[0]}, {w[0]}, {w[1]})"
        elif op in _LIBM:
            expr = f"{op.lower()}({w[0]})"
        else:
            raise UnsupportedOperation(f"{function.name()}: no C form for CasADi operation {op}")
        statements.append(f"{target} = {expr};")
    return CBody(tuple(f"w{i}" for i in sorted(used)), tuple(statements), plan.prologue if plan else ())
