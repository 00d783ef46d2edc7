"""The public front-end: kernels from plain Python functions over multivectors, in any algebra.

    import gagen

    @gagen.kernel(algebra="cga3d", jacobians={"J_d": ("d", "X")})
    def distance(X: "point", C: "circle"):
        ...
        return {"d": ...}

    k = gagen.compile(distance)       # C behind a CPython binding, cached; k.casadi, k.c_source, k.op_count
    d, J_d = k(x, c)

Each argument is declared, by its annotation or by ``inputs={name: declaration}``, as

- a kind of the algebra (``"point"``, ``"motor"``, ``"plane"`` …; see ``gagen.algebra.kinds``): a
  multivector on the kind's blades;
- an explicit blade list (``("e1", "e2")`` or ``gagen.blades("e1", "e2")``);
- ``"scalar"`` (one scalar) or an int n / ``gagen.scalars(n)`` (a list of n scalars, e.g. joint angles);
- ``"algebra"``: no input, but the zero multivector of the path the function runs on, to build
  constants with (``ga.make({"e1": 1})``) and reach ``ga.math`` (sin, sqrt, atan2, …).

The function returns one value, a tuple, or a dict (which names its outputs); each value is a
multivector, a scalar, a list of scalars (a vector) or a list of multivectors (a matrix, one column
each). ``outputs`` names them (a tuple of names) or also fixes their rows (a dict name →
declaration: a kind, blades, ``gagen.matrix(kind, cols)``); otherwise a multivector's rows are the
blades it may have, as the compiler proves them.

``jacobians={"J": ("d", "X")}`` adds ∂d/∂X (rows of d × entries of X) by CasADi AD. A cheaper rule
can replace AD: the function returns an output of that name itself (the robot kernels' Jacobians from
joint lines), or ``rule(inputs) -> {name: casadi.SX}`` gives the compiler's own expressions for any
outputs (e.g. a chain rule through intermediate variables), the function staying their reference.
``(output, input, post)`` declares a transformed Jacobian, column by column ``post(value, ∂value)``
on the interpreter (e.g. the generator Jacobian −2 V~ ∂V). A trailing ``gagen.along("v")`` makes it
directional: one column, (∂output/∂input)·v for another input v of the input's size (a Jacobian-vector
product: a twist J q̇, or J̇ q̇ as the directional derivative of such a column along q̇). Checks hold
every Jacobian the function does not return against differences of the reference (along v for a
directional one; nested differences where its output is itself such a Jacobian).

The same function runs on the reference interpreter (``KernelFunction.reference``): that is the
kernel's reference for ``gagen build --check`` and the tests.
"""

from __future__ import annotations

import ast
import builtins
import difflib
import hashlib
import importlib.util
import inspect
import sys
import traceback
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np
import sympy

from gagen.algebra.kinds import SCALAR, kind_blades
from gagen.algebra.multivector import SparseMultivector
from gagen.algebra.protocol import BladeKey
from gagen.algebra.signature import PRESETS, Algebra
from gagen.codegen.ir import Kernel, ModuleSource, Port, make_kernel
from gagen.interp import MultiVector
from gagen.kinds import ALGEBRA, Declaration
from gagen.limits import over_limit
from gagen.names import MAX_LENGTH, identifier_problem
from gagen.symbolic.backend import Poly
from gagen.symbolic.casadi_backend import CasadiBackend


@dataclass(frozen=True)
class Along:
    """The direction of a directional Jacobian declaration: the input it is taken along."""

    input: str


def along(name: str) -> Along:
    """Mark a Jacobian declaration directional: ``("V_S", "q", post, gagen.along("qd"))`` is the one
    column (∂V_S/∂q)·qd (see the module docstring)."""
    return Along(name)


def split_derivative(declaration: tuple[Any, ...]) -> tuple[str, str, Callable[..., Any] | None, str | None]:
    """(output, input, post or None, direction input or None) of a Jacobian declaration."""
    of, wrt, *rest = declaration
    post = next((r for r in rest if not isinstance(r, Along)), None)
    direction = next((r.input for r in rest if isinstance(r, Along)), None)
    return of, wrt, post, direction


class KernelError(ValueError):
    """A kernel that cannot be compiled as declared: names the kernel, the argument or output, and
    what was expected."""

    def __init__(self, kernel: str, where: str, expected: str) -> None:
        # one line, whatever the user's names and a library's text hold (a name with a newline: quoted)
        where, expected = (" ".join(str(part).split()) for part in (where, expected))
        self.kernel, self.where, self.expected = kernel, where, expected
        plain = isinstance(kernel, str) and kernel.isprintable() and not any(c.isspace() for c in kernel)
        super().__init__(f"kernel {kernel if plain else repr(kernel)}, {where}: {expected}")


# -- declarations --------------------------------------------------------------------------------------

def scalars(n: int, labels: Sequence[str] | None = None) -> Declaration:
    """A list of ``n`` scalars (row labels default to 0 … n−1)."""
    return Declaration("scalars", size=n, labels=tuple(labels) if labels is not None else None)


def blades(*names: str) -> Declaration:
    """A multivector on exactly these blades, in this order."""
    return Declaration("blades", blades=tuple(names))


def matrix(declaration: str | Sequence[str] | Declaration, cols: int) -> tuple[Any, int]:
    """An output that is a list of ``cols`` columns, each of ``declaration`` (a kind, blades, …)."""
    return (declaration, cols)


def _algebra(value: str | Algebra, kernel: str) -> Algebra:
    if isinstance(value, Algebra):
        return value
    if isinstance(value, str) and value in PRESETS:
        return PRESETS[value]()
    raise KernelError(kernel, "algebra", f"expected an Algebra or one of {', '.join(sorted(PRESETS))}, "
                                         f"got {value!r}")


def _declaration(algebra: Algebra, value: Any, kernel: str, where: str) -> Declaration:
    """A declaration from any of its accepted forms, checked against the algebra and within the limit
    on scalars per port (``gagen.limits``: a 10⁶-scalar input would trace for minutes)."""
    declared = _declared(algebra, value, kernel, where)
    problem = over_limit("formula_scalars", (declared.size or len(declared.blades)) * declared.cols)
    if problem:
        raise KernelError(kernel, where, problem)
    return declared


def _declared(algebra: Algebra, value: Any, kernel: str, where: str) -> Declaration:
    if isinstance(value, tuple) and len(value) == 2 and isinstance(value[1], int) \
            and not isinstance(value[1], bool) and not isinstance(value[0], int):
        inner = _declaration(algebra, value[0], kernel, where)  # matrix(kind, cols)
        if value[1] < 1:
            raise KernelError(kernel, where, f"a matrix needs at least one column, got {value[1]}")
        return replace(inner, cols=value[1])
    if isinstance(value, Declaration):
        if value.kind not in ("blades", "scalars", SCALAR, ALGEBRA) and not value.blades:
            return replace(_declaration(algebra, value.kind, kernel, where), cols=value.cols)  # gagen.kinds
        if value.kind == "blades":
            return _declaration(algebra, value.blades, kernel, where)
        if value.kind == "scalars" and (not isinstance(value.size, int) or value.size < 1):
            raise KernelError(kernel, where, f"expected a positive number of scalars, got {value.size!r}")
        if value.labels is not None and len(value.labels) != value.size:
            raise KernelError(kernel, where, f"{len(value.labels)} labels for {value.size} scalars")
        return value
    if isinstance(value, bool):
        raise KernelError(kernel, where, f"expected a kind, blades or a number of scalars, got {value!r}")
    if isinstance(value, int):
        if value < 1:
            raise KernelError(kernel, where, f"expected a positive number of scalars, got {value}")
        return Declaration("scalars", size=value)
    if isinstance(value, str):
        if value == SCALAR:
            return Declaration(SCALAR, size=1, single=True)
        if value == ALGEBRA:
            return Declaration(ALGEBRA)
        try:
            return Declaration(value, blades=kind_blades(algebra, value))
        except KeyError as e:
            raise KernelError(kernel, where, f"unknown kind {value!r}: {e.args[0]}") from None
    if isinstance(value, (list, tuple)) and value and all(isinstance(b, str) for b in value):
        names = tuple(value)
        unknown = [b for b in names if b not in algebra.blade_index]
        if unknown:
            raise KernelError(kernel, where, f"blade {unknown[0]!r} is not in {algebra.name} "
                                             f"(its blades: {', '.join(algebra.blade_index)})")
        if len(set(names)) != len(names):
            raise KernelError(kernel, where, f"a blade is listed twice in {names}")
        return Declaration("blades", blades=names)
    raise KernelError(kernel, where, "expected a kind of the algebra (e.g. 'point'), a list of blades, "
                                     f"'scalar', a number of scalars or 'algebra'; got {value!r}")


def _annotation(fn: Callable[..., Any], text: Any, algebra: Algebra, kernel: str = "",
                where: str = "argument") -> Any:
    """An annotation as written: kind names stay names (also under ``from __future__ import
    annotations``, which quotes them); anything else is evaluated in the function's globals (a bare
    name that is not defined there is taken as a kind, so that an unknown kind is reported as one)."""
    if not isinstance(text, str):
        return text
    if text in (SCALAR, ALGEBRA) or text in _kind_names(algebra):
        return text
    try:
        return ast.literal_eval(text)
    except (ValueError, SyntaxError):
        pass
    try:
        return eval(text, fn.__globals__)  # the user's own annotation, as Python would read it
    except NameError:
        if text.isidentifier():
            return text
        raise KernelError(kernel or fn.__name__, where, f"cannot read its annotation {text!r}") from None
    except Exception as e:
        raise KernelError(kernel or fn.__name__, where,
                          f"cannot read its annotation {text!r} ({e})") from None


def _kind_names(algebra: Algebra) -> set[str]:
    from gagen.algebra.kinds import kinds

    return set(kinds(algebra))


def check_name(name: object, kernel: str, what: str) -> str:
    """``name`` if it can be a C and Python identifier as is (``gagen.names``), else a KernelError."""
    if not isinstance(name, str) or identifier_problem(name, single_underscores=False) is not None:
        raise KernelError(kernel, what, f"{name!r} is not a valid name: expected a letter, then letters, "
                          f"digits or underscores (at most {MAX_LENGTH}), not a C, C++ or Python keyword")
    return name


# -- the two paths: symbolic (compiler) and numeric (interpreter) ---------------------------------------

def _is_scalar(value: Any) -> bool:
    return isinstance(value, (Poly, sympy.Basic, float, int, np.floating, np.integer)) \
        and not isinstance(value, (bool, np.bool_))


def _is_numeric_scalar(value: Any) -> bool:
    return isinstance(value, (float, int, np.floating, np.integer)) \
        and not isinstance(value, (bool, np.bool_))


def _kind_of(value: Any) -> str:
    return type(value).__name__



def _where(fn: Callable[..., Any], error: BaseException) -> str:
    """``file:line: `` of the deepest frame of the error in the file that defines ``fn`` (the user's line
    that failed, not gagen's), or nothing when the error did not pass through that file."""
    filename = getattr(getattr(fn, "__code__", None), "co_filename", None)
    found = ""
    for frame, line in traceback.walk_tb(error.__traceback__):
        if frame.f_code.co_filename == filename:
            found = f"{filename}:{line}: "
    return found


def _suggestion(error: BaseException) -> str:
    """``; did you mean 'sandwich'?`` for a misspelt attribute or name, from what the object (or the
    function's globals and the builtins) has."""
    name = getattr(error, "name", None)
    if not isinstance(name, str):
        return ""
    if isinstance(error, AttributeError) and hasattr(error, "obj"):
        candidates = [a for a in dir(error.obj) if not a.startswith("_")]
    elif isinstance(error, NameError) and error.__traceback__ is not None:
        frame = list(traceback.walk_tb(error.__traceback__))[-1][0]
        candidates = [*frame.f_locals, *frame.f_globals, *dir(builtins)]
    else:
        return ""
    close = difflib.get_close_matches(name, candidates, n=1)
    return f"; did you mean {close[0]!r}?" if close else ""

class KernelFunction:
    """A Python function declared as a kernel. Calling it calls the function; ``trace()`` gives the
    compiler's Kernel, ``reference(*arrays)`` the interpreter's values; ``gagen.compile(k)`` compiles it."""

    def __init__(self, fn: Callable[..., Any], *, algebra: str | Algebra = "cga3d",
                 inputs: Mapping[str, Any] | None = None,
                 outputs: Sequence[str] | Mapping[str, Any] | None = None,
                 jacobians: Mapping[str, tuple[Any, ...]] | Iterable[tuple[str, str]] | None = None,
                 name: str | None = None, doc: str | None = None,
                 sample: Callable[[np.random.Generator], list[np.ndarray]] | None = None,
                 rule: Callable[[dict[str, ca.SX]], Mapping[str, ca.SX]] | None = None) -> None:
        if not callable(fn):
            raise TypeError(f"gagen.kernel needs a function, got {type(fn).__name__}")
        self.fn = fn
        self.name = check_name(name if name is not None else getattr(fn, "__name__", None),
                               str(name or getattr(fn, "__name__", "?")), "name")
        self.algebra = _algebra(algebra, self.name)
        self.doc = doc if doc is not None else (inspect.getdoc(fn) or self.name).strip().splitlines()[0]
        self.params = self._params(inputs or {})
        self.output_names, self.output_declarations = self._outputs(outputs)
        self.jacobians = self._jacobians(jacobians)
        self._sample = sample
        self.rule = rule
        self._traced: Kernel | None = None
        self.__doc__, self.__name__, self.__wrapped__ = fn.__doc__, self.name, fn

    def _error(self, where: str, expected: str) -> KernelError:
        return KernelError(self.name, where, expected)

    def __repr__(self) -> str:
        args = ", ".join(f"{n}: {d.kind}" for n, d in self.params)
        return f"<gagen kernel {self.name}({args}) over {self.algebra.name}>"

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self.fn(*args, **kwargs)

    # -- declarations ---------------------------------------------------------------------------------
    def _params(self, inputs: Mapping[str, Any]) -> list[tuple[str, Declaration]]:
        try:
            signature = inspect.signature(self.fn)
        except (TypeError, ValueError) as e:
            raise self._error("arguments", f"cannot read the function's signature ({e})") from None
        annotations = inspect.get_annotations(self.fn) if inspect.isfunction(self.fn) else {}
        unknown = sorted(set(inputs) - set(signature.parameters))
        if unknown:
            raise self._error(f"argument {unknown[0]}", "declared in inputs= but not an argument "
                                                                  "of the function")
        params = []
        for arg, parameter in signature.parameters.items():
            where = f"argument {arg}"
            if parameter.kind in (parameter.VAR_POSITIONAL, parameter.VAR_KEYWORD):
                raise self._error(where, "expected a plain argument (no *args or **kwargs)")
            if arg in inputs:
                declared = inputs[arg]
            elif arg in annotations:
                declared = _annotation(self.fn, annotations[arg], self.algebra, self.name, where)
            else:
                raise self._error(where, "undeclared: annotate it (a kind such as 'point', blades, "
                                                    "'scalar', a number of scalars) or pass inputs={...}")
            declaration = _declaration(self.algebra, declared, self.name, where)
            if declaration.cols != 1:
                raise self._error(where, "inputs are multivectors or scalar vectors, not matrices")
            if declaration.kind != ALGEBRA:
                check_name(arg, self.name, where)
            params.append((arg, declaration))
        if not any(d.kind != ALGEBRA for _, d in params):
            raise self._error("arguments", "a kernel needs at least one input")
        return params

    def _outputs(self, outputs: Any) -> tuple[tuple[str, ...] | None, dict[str, Declaration]]:
        if outputs is None:
            return None, {}
        if isinstance(outputs, str):
            outputs = (outputs,)
        if isinstance(outputs, Mapping):
            names = tuple(outputs)
            declared = {n: _declaration(self.algebra, d, self.name, f"output {n}")
                        for n, d in outputs.items() if d is not None}
        else:
            names, declared = tuple(outputs), {}
        for n in names:
            check_name(n, self.name, f"output {n!r}")
        if len(set(names)) != len(names):
            raise self._error("outputs", f"an output name is repeated in {names}")
        return names, declared

    def _jacobians(self, jacobians: Any) -> dict[str, tuple[Any, ...]]:
        if jacobians is None:
            return {}
        pairs = jacobians.items() if isinstance(jacobians, Mapping) else \
            [(f"d{o}_d{i}", (o, i)) for o, i in jacobians]
        found = {}
        inputs = {n for n, d in self.params if d.kind != ALGEBRA}
        sizes = {n: d.size for n, d in self.params if d.kind != ALGEBRA}
        for name, pair in pairs:
            check_name(name, self.name, f"Jacobian {name!r}")
            rest = pair[2:] if isinstance(pair, tuple) else ()
            well_formed = isinstance(pair, tuple) and 2 <= len(pair) <= 4 and (
                [type(r) for r in rest] in ([], [Along]) or (callable(rest[0]) and not isinstance(
                    rest[0], Along) and (len(rest) == 1 or isinstance(rest[1], Along))))
            if not well_formed:
                raise self._error(f"Jacobian {name}", "expected (output, input) or (output, input, post), "
                                                      f"optionally ending in along(input); got {pair!r}")
            if name in inputs:
                raise self._error(f"Jacobian {name}", "has the name of an input")
            if pair[1] not in inputs:
                raise self._error(f"Jacobian {name}", f"{pair[1]!r} is not an input "
                                                                 f"(inputs: {', '.join(sorted(inputs))})")
            direction = split_derivative(pair)[3]
            if direction is not None and (direction not in inputs or sizes[direction] != sizes[pair[1]]):
                raise self._error(f"Jacobian {name}", f"along {direction!r}: expected an input of "
                                                      f"{sizes[pair[1]]} entries, like {pair[1]!r}")
            found[name] = pair
        return found

    # -- the compiler's path ---------------------------------------------------------------------------
    def trace(self) -> Kernel:
        """The kernel as the compiler sees it (traced once, then kept)."""
        if self._traced is None:
            self._traced = self._trace()
        return self._traced

    def _trace(self) -> Kernel:
        backend = CasadiBackend()
        args: list[Any] = []
        ports: list[tuple[Port, ca.SX]] = []
        for arg, d in self.params:
            if d.kind == ALGEBRA:
                args.append(SparseMultivector(self.algebra, backend, {}))
                continue
            if d.is_multivector:
                sx = ca.SX.sym(arg, len(d.blades))
                args.append(SparseMultivector(self.algebra, backend, {
                    self.algebra.blade(b): backend.lift(sx[i]) for i, b in enumerate(d.blades)}))
                rows = d.blades
            else:
                sx = ca.SX.sym(arg, d.size)
                values = [backend.lift(sx[i]) for i in range(d.size)]
                args.append(values[0] if d.single else values)
                rows = d.labels or ((arg,) if d.single else tuple(str(i) for i in range(d.size)))
            ports.append((Port(arg, tuple(rows)), sx))
        overrides = dict(self.rule({p.name: sx for p, sx in ports})) if self.rule is not None else {}
        declared = self.output_declarations
        own = [n for n in self.output_names or () if n not in self.jacobians]
        if declared and own and all(n in overrides for n in own):
            # the rule gives every output and the declaration every row: the function is the reference only
            outputs: list[tuple[Port, ca.SX | None]] = [(self._declared_port(n, declared[n]), None)
                                                        for n in own]
        else:
            results = self._named_results(self._run(args, "compiler"))
            outputs = [(Port(*self._shape(n, v)), self._column_sx(n, v, backend)) for n, v in results]
        by_name = {p.name: i for i, (p, _) in enumerate(outputs)}
        derivatives = {}
        for name, declaration in self.jacobians.items():
            of, wrt, post, direction = split_derivative(declaration)
            hidden = of not in by_name and name in declared and name in overrides
            if of not in by_name and not hidden:  # (a hidden value: returned for the checks, not an output)
                raise self._error(f"Jacobian {name}", f"{of!r} is not an output "
                                                                 f"(outputs: {', '.join(by_name)})")
            port = self._declared_port(name, declared[name]) if hidden else outputs[by_name[of]][0]
            if port.cols != 1 and not hidden:
                raise self._error(f"Jacobian {name}", f"output {of} is a matrix; Jacobians are "
                                                                 "of multivectors, scalars and vectors")
            in_port = next(p for p, _ in ports if p.name == wrt)
            derivatives[name] = declaration
            columns = 1 if direction is not None else in_port.size
            shape = (len(port.rows), columns)
            if hidden:
                by_name[name] = len(outputs)
                outputs.append((port, None))
                if port.cols != columns:
                    raise self._error(f"output {name}", f"as d{of}/d{wrt} it needs {columns} "
                                                                   f"columns, got {port.cols}")
                continue
            if name in by_name or name in declared:  # the function's own rule, or declared rows: check
                given = outputs[by_name[name]][0] if name in by_name else \
                    self._declared_port(name, declared[name])
                shape = (len(given.rows) if post else shape[0], shape[1])
                if given.shape != shape:
                    raise self._error(f"output {name}", f"as d{of}/d{wrt} it must be {shape[0]} x "
                                      f"{shape[1]}, got {given.shape[0]} x {given.shape[1]}")
                if name in by_name:
                    continue
            if post and name not in overrides:
                raise self._error(f"Jacobian {name}", "a transformed Jacobian needs a rule")
            by_name[name] = len(outputs)
            outputs.append((given if name in declared else Port(name, port.rows, columns), None))
        for name, expression in overrides.items():
            if name not in by_name:
                raise self._error(f"rule output {name}", "is neither an output nor a declared Jacobian")
            port = outputs[by_name[name]][0]
            if not isinstance(expression, ca.SX) or expression.shape != port.shape:
                got = expression.shape if isinstance(expression, ca.SX) else type(expression).__name__
                raise self._error(f"rule output {name}", f"expected a casadi.SX of shape {port.shape}, "
                                                                    f"got {got}")
            outputs[by_name[name]] = (port, expression)
        symbols = {p.name: sx for p, sx in ports}
        for name, declaration in derivatives.items():  # AD for the Jacobians nobody supplied
            of, wrt, _, direction = split_derivative(declaration)
            i = by_name[name]
            if outputs[i][1] is None:
                value = outputs[by_name[of]][1]
                assert value is not None  # (every output has its expression by now)
                outputs[i] = (outputs[i][0], ca.jacobian(value, symbols[wrt]) if direction is None
                              else ca.jtimes(value, symbols[wrt], symbols[direction]))
        if self.output_names:  # the declared order (Jacobians may be listed among the outputs)
            rank = {n: i for i, n in enumerate(self.output_names)}
            outputs.sort(key=lambda o: rank.get(o[0].name, len(rank)))
        expressions = [(p, e) for p, e in outputs if e is not None]
        assert len(expressions) == len(outputs)  # (the rule, the function or AD gave each its expression)
        return make_kernel(self.name, self.doc, ports, expressions, backend, reference=self.reference,
                           derivatives=derivatives, sample=self.sample)

    def _run(self, args: list[Any], path: str) -> Any:
        try:
            return self.fn(*args)
        except (KernelError, TimeoutError):  # (a caller's deadline is not the function's error)
            raise
        except Exception as e:
            raise self._error(f"on the {path}",
                              f"{_where(self.fn, e)}the function raised {type(e).__name__}: {e}"
                              f"{_suggestion(e)}") from e

    def _named_results(self, result: Any) -> list[tuple[str, Any]]:
        if isinstance(result, Mapping | tuple | list) and not result:
            raise self._error("outputs", f"the function returned no output ({result!r}); return a dict "
                                         "of named outputs, e.g. {'Y': ...}")
        if isinstance(result, Mapping):
            items = list(result.items())
            for n, _ in items:
                check_name(n, self.name, f"output {n!r}")
            # (only when the outputs are declared: without outputs=, every returned value is an output)
            sources = {of for of, *_ in self.jacobians.values()} - set(self.output_names) \
                if self.output_names is not None else set()
            items = [(n, v) for n, v in items if n not in sources]  # values kept for the checks only
            returned = tuple(n for n, _ in items if n not in self.jacobians)
            expected = tuple(n for n in self.output_names or returned if n not in self.jacobians)
            if returned != expected:
                raise self._error("outputs", f"declared {expected}, the function returned {returned}")
            self._no_input_names(n for n, _ in items)
            return items
        values = list(result) if isinstance(result, tuple) else [result]
        names = self.output_names or (("out",) if len(values) == 1 else
                                      tuple(f"out{i}" for i in range(len(values))))
        if len(names) != len(values):  # the Jacobians listed among the outputs are not returned
            names = tuple(n for n in names if n not in self.jacobians)
        if len(names) != len(values):
            raise self._error("outputs", f"declared {len(names)} ({', '.join(names)}), the "
                                                    f"function returned {len(values)}")
        self._no_input_names(names)
        return list(zip(names, values, strict=True))

    def _no_input_names(self, names: Iterable[str]) -> None:
        taken = {n for n, _ in self.params}
        clash = [n for n in names if n in taken]
        if clash:
            raise self._error(f"output {clash[0]}", "has the name of an input")

    def _declared_port(self, name: str, d: Declaration) -> Port:
        if d.is_multivector:
            return Port(name, d.blades, d.cols)
        if d.single:
            return Port(name, (name,), d.cols)
        return Port(name, d.labels or tuple(str(i) for i in range(d.size)), d.cols)

    def _columns(self, name: str, value: Any) -> tuple[list[Any], bool]:
        """The columns of an output (one for a vector or multivector) and whether it is a matrix."""
        if isinstance(value, list) and value and all(isinstance(v, (SparseMultivector, MultiVector))
                                                     for v in value):
            return value, True
        if isinstance(value, list) and value and all(isinstance(v, list) for v in value):
            return value, True
        return [value], False

    def _shape(self, name: str, value: Any) -> tuple[str, tuple[str, ...], int]:
        declared = self.output_declarations.get(name)
        columns, is_matrix = self._columns(name, value)
        first = columns[0]
        if isinstance(first, SparseMultivector):
            if declared is not None and declared.is_multivector:
                rows = declared.blades
            else:
                masks = sorted({m for c in columns for m in c.support})
                rows = tuple(self.algebra.blade_name(m) for m in masks) or ("1",)
            for c in columns:
                if not isinstance(c, SparseMultivector) or c.algebra != self.algebra:
                    raise self._error(f"output {name}", f"expected multivectors of {self.algebra.name}")
                outside = [b for b in map(self.algebra.blade_name, c.support) if b not in rows]
                if outside:
                    raise self._error(f"output {name}", f"has blade {outside[0]} outside its declared "
                                                                   f"rows {rows}")
        elif isinstance(first, list):
            if not first or not all(_is_scalar(v) or isinstance(v, ca.SX) for c in columns for v in c) \
                    or len({len(c) for c in columns}) != 1:
                raise self._error(f"output {name}", "expected a list of scalars (all columns of "
                                                               "one length)")
            rows = declared.labels if declared is not None and declared.labels else \
                tuple(str(i) for i in range(len(first)))
        elif _is_scalar(first) or isinstance(first, ca.SX):
            rows = (name,)
        else:
            raise self._error(f"output {name}", "expected a multivector, a scalar, or a list of "
                                                           f"them; got {_kind_of(first)}")
        if declared is not None and declared.cols != 1 and declared.cols != len(columns):
            raise self._error(f"output {name}", f"declared {declared.cols} columns, got {len(columns)}")
        return name, tuple(rows), len(columns) if is_matrix else 1

    def _column_sx(self, name: str, value: Any, backend: CasadiBackend) -> ca.SX:
        _, rows, _ = self._shape(name, value)
        columns, _ = self._columns(name, value)

        def native(v: Any) -> ca.SX:
            try:
                return v if isinstance(v, ca.SX) else backend.native(backend.lift(v))
            except (ValueError, OverflowError) as e:  # a non-finite constant, as NaN is refused
                raise self._error(f"output {name}", f"{e}; outputs must be finite") from None

        out = []
        for c in columns:
            if isinstance(c, SparseMultivector):
                out.append(ca.vertcat(*[native(c[b]) for b in rows]))
            elif isinstance(c, list):
                out.append(ca.vertcat(*[native(v) for v in c]))
            else:
                out.append(native(c))
        return ca.horzcat(*out)

    # -- the interpreter's path ------------------------------------------------------------------------
    def reference(self, *arrays: Any, ports: tuple[Sequence[Any], Sequence[Any]] | None = None
                  ) -> list[np.ndarray | None]:
        """The function on the reference interpreter, laid out like the kernel's outputs ((rows, cols)
        each; None for the Jacobians the compiler takes by AD or by a rule, which a check compares with
        differences). ``ports`` (inputs, outputs: objects with name, rows, cols, e.g. from a manifest)
        spare the trace."""
        in_ports, out_ports = ports if ports is not None else (self.trace().inputs, self.trace().outputs)
        if len(arrays) == 1 and isinstance(arrays[0], list) and len(in_ports) != 1:
            arrays = tuple(arrays[0])
        return self.layout(self.values(arrays, in_ports), out_ports)

    def values(self, arrays: Sequence[Any], in_ports: Sequence[Any]) -> dict[str, Any]:
        """Everything the function returns on the interpreter (also the values it returns for the checks
        only), by name: MultiVectors, floats, lists."""
        inputs = iter(zip(in_ports, arrays, strict=True))
        args: list[Any] = []
        for _, d in self.params:
            if d.kind == ALGEBRA:
                args.append(MultiVector.zero(self.algebra))
                continue
            port, values = next(inputs)
            flat = np.asarray(values, dtype=float).reshape(len(port.rows))
            if d.is_multivector:
                args.append(MultiVector.from_blades(self.algebra, dict(zip(port.rows, flat, strict=True))))
            else:
                args.append(float(flat[0]) if d.single else [float(v) for v in flat])
        result = self._run(args, "interpreter")
        if isinstance(result, Mapping):
            return dict(result)
        return dict(self._named_results(result))

    def returned(self, values: Mapping[str, Any]) -> set[str]:
        """The outputs the function gives itself (the others are Jacobians left to the compiler)."""
        return set(values)

    def layout(self, values: Mapping[str, Any], out_ports: Sequence[Any]) -> list[np.ndarray | None]:
        """The function's values as the kernel's outputs ((rows, cols) each; None where it gives none)."""
        out: list[np.ndarray | None] = []
        for port in out_ports:
            if port.name not in values:
                out.append(None)
                continue
            columns, _ = self._columns(port.name, values[port.name])
            matrix = np.empty((len(port.rows), port.cols))
            for j, c in enumerate(columns):
                if isinstance(c, MultiVector):
                    matrix[:, j] = [c[b] for b in port.rows]
                elif isinstance(c, list):
                    matrix[:, j] = [float(v) for v in c]
                elif _is_numeric_scalar(c):
                    matrix[:, j] = float(c)
                else:
                    raise self._error(f"output {port.name}", "expected a multivector, a scalar "
                                                             f"or a list of them; got {_kind_of(c)}")
            out.append(matrix)
        return out

    # -- inputs for checks -------------------------------------------------------------------------------
    def sample(self, rng: np.random.Generator) -> list[np.ndarray]:
        """Random valid inputs: normalised points, unit versors of the declared kinds, N(0, 1)
        coefficients otherwise, scalars in [−1, 1] (or the kernel's own ``sample``)."""
        if self._sample is not None:
            return [np.asarray(a, dtype=float) for a in self._sample(rng)]
        return [_sample_input(self.algebra, d, rng) for _, d in self.params if d.kind != ALGEBRA]


def _sample_input(algebra: Algebra, d: Declaration, rng: np.random.Generator) -> np.ndarray:
    if not d.is_multivector:
        return rng.uniform(-1.0, 1.0, d.size)
    coefficients: dict[BladeKey, float] = dict(zip(d.blades, rng.normal(size=len(d.blades)), strict=True))
    x = MultiVector.from_blades(algebra, coefficients)
    shape = _SAMPLERS.get((algebra.name, d.kind))
    if shape is not None:
        x = shape(algebra, rng)
    return np.array([x[b] for b in d.blades])


def _conformal_point(algebra: Algebra, rng: np.random.Generator) -> MultiVector:
    euclid = [f"e{label}" for label in algebra.vector_labels[1:-1]]
    v = rng.normal(size=len(euclid))
    return MultiVector.from_blades(algebra, {"e0": 1.0, **dict(zip(euclid, v, strict=True)),
                                             "einf": 0.5 * float(v @ v)})


def _rotor(algebra: Algebra, rng: np.random.Generator) -> MultiVector:
    """exp of a random rotation bivector (a simple one in 3D), through its closed form."""
    planes = [b for b in kind_blades(algebra, "rotor") if b != "1"]
    b = rng.normal(size=len(planes))
    angle = float(np.linalg.norm(b))
    return MultiVector.from_blades(algebra, {"1": np.cos(angle / 2), **{
        p: -np.sin(angle / 2) * c / angle for p, c in zip(planes, b, strict=True)}})


def _translator(algebra: Algebra, rng: np.random.Generator) -> MultiVector:
    moves = [b for b in kind_blades(algebra, "translator") if b != "1"]
    return MultiVector.from_blades(algebra, {"1": 1.0, **dict(zip(moves, 0.5 * rng.normal(size=len(moves)),
                                                                  strict=True))})


def _motor(algebra: Algebra, rng: np.random.Generator) -> MultiVector:
    return _translator(algebra, rng) * _rotor(algebra, rng)


def _dilator(algebra: Algebra, rng: np.random.Generator) -> MultiVector:
    half = 0.25 * rng.normal()
    return MultiVector.from_blades(algebra, {"1": np.cosh(half), "e0inf": np.sinh(half)})


def _similarity(algebra: Algebra, rng: np.random.Generator) -> MultiVector:
    return _motor(algebra, rng) * _dilator(algebra, rng)


_SAMPLERS: dict[tuple[str, str], Callable[[Algebra, np.random.Generator], MultiVector]] = {
    **{(a, "point"): _conformal_point for a in ("cga3d", "cga2d")},
    **{(a, k): f for a in ("cga3d", "cga2d", "pga3d", "ga3d") for k, f in
       (("rotor", _rotor), ("translator", _translator), ("motor", _motor))},
    **{(a, k): f for a in ("cga3d", "cga2d")
       for k, f in (("dilator", _dilator), ("similarity", _similarity))},
    ("pga3d", "point"): lambda a, rng: MultiVector.from_blades(a, {"e123": 1.0, **dict(zip(
        ("e012", "e013", "e023"), rng.normal(size=3), strict=True))}),
}


# -- the decorator, modules and compile --------------------------------------------------------------

def kernel(fn: Callable[..., Any] | None = None, **declaration: Any) -> Any:
    """Declare a function as a kernel: ``@gagen.kernel`` or ``@gagen.kernel(algebra=..., inputs=...,
    outputs=..., jacobians=..., name=..., doc=..., sample=...)`` (see the module docstring)."""
    if fn is None:
        return lambda f: KernelFunction(f, **declaration)
    return KernelFunction(fn, **declaration)


def as_kernel(fn: Any, declaration: Mapping[str, Any]) -> KernelFunction:
    """``fn`` if it is a declared kernel already (and no declaration is given), else ``fn`` declared."""
    if isinstance(fn, KernelFunction):
        if declaration:
            raise TypeError(f"{fn.name} is declared already; pass the declaration to gagen.kernel only")
        return fn
    return KernelFunction(fn, **declaration)


def source_of(kernels: Sequence[KernelFunction], name: str, source_name: str = "<python>",
              source_text: bytes = b"", rebuild: str = "") -> ModuleSource:
    """The ModuleSource of these kernels (traced here), keyed by what they compile to."""
    check_name(name, name, "module name")
    traced: dict[str, Kernel] = {}
    for k in kernels:
        if k.name in traced:
            raise KernelError(k.name, "name", f"two kernels of module {name} have this name")
        traced[k.name] = k.trace()
    key = hashlib.sha256()
    for t in traced.values():
        key.update(repr((t.name, t.doc, t.inputs, t.outputs)).encode())
        key.update(t.function.serialize().encode())
    algebras = sorted({k.algebra.name for k in kernels})
    return ModuleSource(name, f"user kernels over {', '.join(algebras)}", traced, source_name,
                        hashlib.sha256(source_text).hexdigest(),
                        {"algebras": algebras, "kind": "kernels"}, key.hexdigest(), rebuild,
                        {k.name: k for k in kernels})


def module_from_file(path: str | Path, name: str | None = None) -> ModuleSource:
    """Every ``@gagen.kernel`` of a Python file (in definition order) as one module, named after the file."""
    path = Path(path)
    stem = name or path.stem
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    spec = importlib.util.spec_from_file_location(f"_gagen_user_{abs(hash(path.resolve()))}", path)
    if spec is None or spec.loader is None:
        raise KernelError(stem, str(path), "cannot be imported as a Python file")
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(path.parent))  # its own helper modules beside it
    try:
        spec.loader.exec_module(module)
    except KernelError:
        raise
    except Exception as e:
        raise KernelError(stem, str(path), f"importing it raised {type(e).__name__}: {e}") from e
    finally:
        sys.path.remove(str(path.parent))
    found = [v for v in vars(module).values() if isinstance(v, KernelFunction)]
    if not found:
        raise KernelError(stem, str(path), "no @gagen.kernel function in it")
    return source_of(found, stem, path.name, path.read_bytes(), f"gagen build {path.name}")
