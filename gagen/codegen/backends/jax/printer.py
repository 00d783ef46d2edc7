"""The JAX backend's printer: kernels as pure ``jax.numpy`` functions, emitted from the same flat graph
as the C [issue 19, item 1].

``jax_source(function)`` walks a CasADi SX Function's instructions in CasADi's order, as the C printer
does (``gagen.codegen.backends.c.printer``), and writes one Python assignment per instruction on
``jax.numpy``: the same operations in the same order, so the JAX kernel computes what the C kernel
computes (to rounding: XLA may contract or reorder). Comparisons and the guards' selects become
``jnp.where`` on 0/1 doubles, as CasADi evaluates them, so the functions trace, ``jit``, ``vmap`` and
differentiate (``jax.grad``, ``jacfwd``) like any jnp code.

The ``jax`` backend (``gagen.codegen.backends.jax``) writes these statements into a module's committed
``<name>_jax.py`` (``module.jax.<kernel>``: the C kernels' calling convention, no CasADi at load
time). ``jax_kernel(module, name)`` is the raw form, emitted from a module's serialised CasADi
Function when called (any module with the ``casadi`` backend): inputs flat arrays (one per port, the C
kernel's layout), outputs always a tuple of (rows, cols) arrays. JAX must run in float64
(``jax.config.update("jax_enable_x64", True)``; ``jax_kernel`` does it). Emitting needs only CasADi.
"""

from __future__ import annotations

import keyword
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import casadi as ca

from gagen.codegen.backends.c.printer import UnsupportedOperation, c_literal
from gagen.symbolic.flatten import OPCODES

_BINARY = {"ADD": "{0} + {1}", "SUB": "{0} - {1}", "MUL": "{0} * {1}", "DIV": "{0} / {1}",
           "LT": "jnp.where({0} < {1}, 1.0, 0.0)", "LE": "jnp.where({0} <= {1}, 1.0, 0.0)",
           "EQ": "jnp.where({0} == {1}, 1.0, 0.0)", "NE": "jnp.where({0} != {1}, 1.0, 0.0)",
           "AND": "jnp.where(({0} != 0) & ({1} != 0), 1.0, 0.0)",
           "OR": "jnp.where(({0} != 0) | ({1} != 0), 1.0, 0.0)",
           "IF_ELSE_ZERO": "jnp.where({0} != 0, {1}, 0.0)", "ATAN2": "jnp.arctan2({0}, {1})",
           "POW": "jnp.power({0}, {1})", "CONSTPOW": "jnp.power({0}, {1})",
           "FMIN": "jnp.fmin({0}, {1})", "FMAX": "jnp.fmax({0}, {1})",
           "COPYSIGN": "jnp.copysign({0}, {1})", "FMOD": "jnp.fmod({0}, {1})", "HYPOT": "jnp.hypot({0}, {1})"}
_UNARY = {"NEG": "-{0}", "SQ": "{0} * {0}", "TWICE": "{0} + {0}", "INV": "1.0 / {0}",
          "NOT": "jnp.where({0} == 0, 1.0, 0.0)", "SIGN": "jnp.sign({0})", "FABS": "jnp.abs({0})",
          "SQRT": "jnp.sqrt({0})", "SIN": "jnp.sin({0})", "COS": "jnp.cos({0})", "TAN": "jnp.tan({0})",
          "ASIN": "jnp.arcsin({0})", "ACOS": "jnp.arccos({0})", "ATAN": "jnp.arctan({0})",
          "SINH": "jnp.sinh({0})", "COSH": "jnp.cosh({0})", "TANH": "jnp.tanh({0})",
          "ASINH": "jnp.arcsinh({0})", "ACOSH": "jnp.arccosh({0})", "ATANH": "jnp.arctanh({0})",
          "EXP": "jnp.exp({0})", "LOG": "jnp.log({0})", "FLOOR": "jnp.floor({0})", "CEIL": "jnp.ceil({0})",
          "LOG1P": "jnp.log1p({0})", "EXPM1": "jnp.expm1({0})"}


@dataclass(frozen=True)
class JaxBody:
    """A Function's jax.numpy statements (one assignment each, unindented, reading inputs ``in<i>``:
    flat arrays, CasADi's nonzeros in column-major order) and per output its column-major entries (a
    local ``o<i>_<j>`` or the literal ``0.0`` of a structural zero) and its (rows, cols)."""

    statements: list[str]
    outputs: list[tuple[list[str], int, int]]


def jax_body(function: ca.Function) -> JaxBody:
    """The statements of ``function`` on jax.numpy (see the module docstring), in CasADi's order."""
    n_in, n_out = function.n_in(), function.n_out()
    in_positions = [[int(i) for i in function.sparsity_in(i).find()] for i in range(n_in)]
    out_positions = [[int(i) for i in function.sparsity_out(i).find()] for i in range(n_out)]
    entries: list[list[str]] = [["0.0"] * function.numel_out(o) for o in range(n_out)]
    lines = []
    for k in range(function.n_instructions()):
        op = OPCODES.get(function.instruction_id(k), "?")
        args, res = function.instruction_input(k), function.instruction_output(k)
        w = [f"w{i}" for i in args]
        if op == "OUTPUT":
            # a later OUTPUT of the same slot never happens: each output entry is written once
            lines.append(f"o{res[0]}_{res[1]} = {w[0]}")
            entries[res[0]][out_positions[res[0]][res[1]]] = f"o{res[0]}_{res[1]}"
            continue
        if op == "INPUT":
            expr = f"in{args[0]}[{in_positions[args[0]][args[1]]}]"
        elif op == "CONST":
            value = function.instruction_constant(k)
            expr = "jnp.nan" if value != value else c_literal(value).replace("INFINITY", "jnp.inf")
        elif op in ("ASSIGN", "PARAMETER"):
            expr = w[0]
        elif op in _BINARY:
            expr = _BINARY[op].format(*w)
        elif op in _UNARY:
            expr = _UNARY[op].format(*w)
        else:
            raise UnsupportedOperation(f"{function.name()}: no jax.numpy form for CasADi operation {op}")
        lines.append(f"w{res[0]} = {expr}")
    return JaxBody(lines, [(entries[o], function.size1_out(o), function.size2_out(o)) for o in range(n_out)])


def stacked(entries: list[str], rows: int, cols: int, matrix: bool = True) -> str:
    """The expression of one output from its column-major entries: a (rows, cols) array, or with
    ``matrix=False`` a 1-D (rows * cols,) one."""
    if not entries:
        return f"jnp.zeros(({rows}, {cols}))" if matrix else f"jnp.zeros(({rows * cols},))"
    # a literal zero takes the dtype
    flat = f"jnp.stack([{', '.join(f'jnp.asarray({e}, dtype=jnp.float64)' for e in entries)}])"
    return f"{flat}.reshape({cols}, {rows}).T" if matrix else flat


def jax_source(function: ca.Function, name: str = "kernel") -> str:
    """Python source of ``def <name>(in0, in1, …)`` evaluating ``function`` on jax.numpy (see the
    module docstring); the outputs are returned as a tuple of (rows, cols) arrays. ``name`` must be a
    Python identifier and no keyword: it is written into the source that is executed."""
    if not (isinstance(name, str) and name.isidentifier() and not keyword.iskeyword(name)):
        raise ValueError(f"a JAX kernel's name must be a Python identifier and no keyword, got {name!r}")
    body = jax_body(function)
    lines = [f"def {name}({', '.join(f'in{i}' for i in range(function.n_in()))}):"]
    lines += [f"    {s}" for s in body.statements]
    lines.append(f"    return ({', '.join(stacked(*o) for o in body.outputs)},)")
    return "\n".join(lines) + "\n"


def jax_function(function: ca.Function, name: str = "kernel") -> Callable[..., tuple[Any, ...]]:
    """The emitted function, compiled from its source (float64 JAX)."""
    import jax
    import jax.numpy as jnp

    config: Any = jax.config  # (its update is not annotated)
    config.update("jax_enable_x64", True)
    namespace: dict[str, Any] = {"jnp": jnp}
    exec(compile(jax_source(function, name), f"<gagen jax {name}>", "exec"), namespace)
    emitted: Callable[..., tuple[Any, ...]] = namespace[name]
    return emitted


def jax_kernel(module: Any, name: str) -> Callable[..., tuple[Any, ...]]:
    """A generated module's kernel ``name`` as a jax.numpy function (from its CasADi Function)."""
    return jax_function(getattr(module.casadi, name), name)
