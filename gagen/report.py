"""Plain-text tables of a kernel catalogue: shapes and op counts per kernel (``gagen kernels``)."""

from __future__ import annotations

from collections.abc import Iterable

from gagen.codegen.ir import Kernel, Port


def _shape(port: Port) -> str:
    rows, cols = port.shape
    return f"{port.name}[{rows}]" if cols == 1 else f"{port.name}[{rows}×{cols}]"


def op_count_table(kernels: Iterable[Kernel]) -> str:
    """One row per kernel: its ports and its scalar operations (flops = mul + add + neg + div)."""
    header = ("kernel", "inputs → outputs", "mul", "add", "neg", "div", "flops", "calls")
    rows = []
    for k in kernels:
        ops = k.op_count
        calls = " ".join(f"{name}={n}" for name, n in sorted(ops.calls.items()))
        ports = ", ".join(map(_shape, k.inputs)) + " → " + ", ".join(map(_shape, k.outputs))
        rows.append((k.name, ports, str(ops.mul), str(ops.add), str(ops.neg), str(ops.div), str(ops.flops),
                     calls))
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    numeric = {2, 3, 4, 5, 6}

    def line(r: tuple[str, ...]) -> str:
        cells = [c.rjust(w) if i in numeric else c.ljust(w) for i, (c, w) in enumerate(zip(r, widths,
                                                                                          strict=True))]
        return "| " + " | ".join(cells) + " |"

    rule = "|" + "|".join("-" * (w + 1) + (":" if i in numeric else "-") for i, w in enumerate(widths)) + "|"
    return "\n".join([line(header), rule, *map(line, rows)])
