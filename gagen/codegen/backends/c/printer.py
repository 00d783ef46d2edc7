"""Our C emitter over the flat graph: one C statement per instruction of a CasADi SX Function.

The instruction list is walked in CasADi's order, and each work-vector slot becomes a C local
(``w12``), so the C program performs exactly the operations CasADi's virtual machine performs, in
the same order, with libm for the transcendental calls: the C kernels and the CasADi Functions give
the same doubles (compile without FMA contraction to keep it so). Outputs are dense column-major
arrays; structural zeros of an output's sparsity are written as 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca

_OPS = {getattr(ca, a): a[3:] for a in dir(ca) if a.startswith("OP_")}

_BINARY = {"ADD": "{0} + {1}", "SUB": "{0} - {1}", "MUL": "{0} * {1}", "DIV": "{0} / {1}",
           "LT": "{0} < {1}", "LE": "{0} <= {1}", "EQ": "{0} == {1}", "NE": "{0} != {1}",
           "AND": "{0} && {1}", "OR": "{0} || {1}", "IF_ELSE_ZERO": "{0} ? {1} : 0.0",
           "ATAN2": "atan2({0}, {1})", "POW": "pow({0}, {1})", "CONSTPOW": "pow({0}, {1})",
           "FMIN": "fmin({0}, {1})", "FMAX": "fmax({0}, {1})", "COPYSIGN": "copysign({0}, {1})",
           "FMOD": "fmod({0}, {1})", "HYPOT": "hypot({0}, {1})"}
_UNARY = {"NEG": "-{0}", "SQ": "{0} * {0}", "TWICE": "{0} + {0}", "INV": "1.0 / {0}", "NOT": "!{0}",
          "SIGN": "gagen_sign({0})", "FABS": "fabs({0})"}
_LIBM = ("SQRT", "SIN", "COS", "TAN", "ASIN", "ACOS", "ATAN", "SINH", "COSH", "TANH", "ASINH", "ACOSH",
         "ATANH", "EXP", "LOG", "FLOOR", "CEIL", "ERF", "LOG1P", "EXPM1")


class UnsupportedOperation(ValueError):
    """The graph holds an operation the emitter has no C form for."""


@dataclass(frozen=True)
class CBody:
    """The statements of one kernel body and the locals they use."""

    locals: tuple[str, ...]
    statements: tuple[str, ...]


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
              vector: bool = False) -> CBody:
    """C statements evaluating ``function`` from arrays ``input_names`` into ``output_names``.

    ``vector=True`` emits the same instructions on vectors of W samples (the template's ``gagen_v``
    type): inputs are gathered from and outputs scattered to W consecutive samples of the batched
    arrays; operations without a vector form run lane by lane (``GAGEN_V1``/``GAGEN_V2``).
    """
    in_positions = [_dense_positions(function.sparsity_in(i)) for i in range(function.n_in())]
    out_positions = [_dense_positions(function.sparsity_out(i)) for i in range(function.n_out())]
    in_sizes = [function.numel_in(i) for i in range(function.n_in())]
    out_sizes = [function.numel_out(i) for i in range(function.n_out())]

    def store(o: int, k: int, value: str) -> str:
        if vector:
            return f"GAGEN_SCATTER({output_names[o]}, {out_sizes[o]}, {k}, {value});"
        return f"{output_names[o]}[{k}] = {value};"

    statements: list[str] = []
    for o in range(len(output_names)):  # structural zeros first, then the computed entries
        written = set(out_positions[o])
        zero = "gagen_v_splat(0.0)" if vector else "0.0"
        statements += [store(o, k, zero) for k in range(out_sizes[o]) if k not in written]
    binary, unary = (_VECTOR_BINARY, _VECTOR_UNARY) if vector else (_BINARY, _UNARY)
    used: set[int] = set()
    for k in range(function.n_instructions()):
        op = _OPS.get(function.instruction_id(k), "?")
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
                    else f"{input_names[i]}[{nz}]")
        elif op == "CONST":
            literal = c_literal(function.instruction_constant(k))
            expr = f"gagen_v_splat({literal})" if vector else literal
        elif op in ("ASSIGN", "PARAMETER"):
            expr = w[0]
        elif op in binary:
            expr = binary[op].format(*w)
        elif op in unary:
            expr = unary[op].format(*w)
        elif vector and (op in _LIBM or op == "SIGN"):
            expr = f"GAGEN_V1({'gagen_sign' if op == 'SIGN' else op.lower()}, {w[0]})"
        elif vector and op in _BINARY and _BINARY[op].endswith(")"):  # atan2, pow, fmin, ...
            expr = f"GAGEN_V2({_BINARY[op].split('(')[0]}, {w[0]}, {w[1]})"
        elif op in _LIBM:
            expr = f"{op.lower()}({w[0]})"
        else:
            raise UnsupportedOperation(f"{function.name()}: no C form for CasADi operation {op}")
        statements.append(f"{target} = {expr};")
    return CBody(tuple(f"w{i}" for i in sorted(used)), tuple(statements))
