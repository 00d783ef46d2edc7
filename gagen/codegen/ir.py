"""What the backends take: kernels (a CasADi SX Function with named, labelled ports) and a module of them.

Every road to code ends here: the public front-end (``gagen.kernel``) traces a user's function into a
:class:`Kernel`, applications (the cooperative catalogue, …) do the same for their formulas, and a
:class:`ModuleSource` groups the kernels of one generated module. The backends
(``gagen.codegen.backends``) turn a ModuleSource into files; nothing else reaches them. A kernel's
ports are :class:`~gagen.symbolic.flatten.Port`, the one port of gagen, exported here too.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import casadi as ca
import numpy as np

from gagen.symbolic import passes
from gagen.symbolic.backend import ScalarBackend
from gagen.symbolic.flatten import OpCount, Port, casadi_op_count, identifier

__all__ = ["Kernel", "ModuleSource", "Port", "Reference", "Sampler", "make_kernel"]

# a kernel's reference: numpy inputs (one flat array per input port) -> one array per output port,
# shaped (rows, cols); None for an output it cannot give (checked by differences instead)
Reference = Callable[[Sequence[np.ndarray]], list[np.ndarray | None]]
Sampler = Callable[[np.random.Generator], list[np.ndarray]]


@dataclass
class Kernel:
    """One generated computation: a CasADi SX Function and the meaning of its ports.

    ``reference`` evaluates the same formula independently (the reference interpreter);
    ``derivatives`` names, for each output that is a Jacobian, the (output, input) pair it is the
    derivative of, so that a check compares it with differences of the reference; ``sample`` draws
    valid random inputs (unit versors, normalised points, …) for such checks."""

    name: str
    doc: str
    inputs: tuple[Port, ...]
    outputs: tuple[Port, ...]
    function: ca.Function
    reference: Reference | None = None
    derivatives: Mapping[str, tuple[str, str]] = field(default_factory=dict)
    sample: Sampler | None = None
    passes: Mapping[str, int] = field(default_factory=dict)  # what each pass removed (symbolic.passes)

    @cached_property
    def op_count(self) -> OpCount:
        return casadi_op_count(self.function)


def make_kernel(name: str, doc: str, inputs: Sequence[tuple[Port, ca.SX]],
                outputs: Sequence[tuple[Port, ca.SX]], backend: ScalarBackend | None = None,
                **extra: Any) -> Kernel:
    """A Kernel over the given symbolic inputs and outputs: one CSE over all its outputs together
    (they share most of their graph), each output shaped (rows, cols). ``backend``: the scalar
    backend the outputs were built on, whose pass counts the kernel reports."""
    raw = [value for _, value in outputs]
    values = ca.cse(raw)
    names = ([p.name for p, _ in inputs], [p.name for p, _ in outputs])
    symbols = [s for _, s in inputs]
    function = ca.Function(identifier(name), symbols, values, *names)
    before = casadi_op_count(ca.Function("before_cse", symbols, raw, *names))
    return Kernel(identifier(name), doc, tuple(p for p, _ in inputs), tuple(p for p, _ in outputs), function,
                  passes=passes.report(backend, before, casadi_op_count(function)), **extra)


@dataclass
class ModuleSource:
    """The kernels of one generated module and what its files say about where they came from.

    ``title`` is one line for the headers ("kernels of the cooperative system …"); ``source_name`` and
    ``source_hash`` name the spec or Python file built; ``meta`` goes into the manifest as is
    (JSON-able); ``key`` is everything else the source read that decides the output (for the build cache;
    empty: the kernels' own content is the key), and ``code`` the gagen modules that made the kernels:
    the build's key covers their sources and those of every gagen module they import
    (``gagen.code_digest``)."""

    name: str
    title: str
    kernels: Mapping[str, Kernel]  # a dict, or a catalogue built on first use
    source_name: str
    source_hash: str
    meta: dict[str, Any] = field(default_factory=dict)
    key: str = ""
    rebuild: str = ""  # the command that regenerates the module, for the "do not edit" lines
    functions: dict[str, Any] = field(default_factory=dict)  # the front-end kernels, for --check
    code: tuple[str, ...] = ()
