"""The Newton step's linear solve J ΔB = −F, flattened for a linkage's structure [LINK 3.3].

A revolute joint's two rows have ∂/∂(translation) = w·I for each of its bodies (w the points' weight,
1 for unit motors): with a spanning tree of revolute joints grown from the ground and the driven bodies,
each moving body's translation step is an affine function of the bodies' turn steps, one 2 × 2 block
per tree joint (exact, its pivot w² never small). The rows left over (the loop closures, the slots)
then give a dense system in the n turn steps alone: n × n instead of 3n × 3n, the classical reduction
to loop-closure equations, done symbolically so the kernel holds a few hundred flops where CasADi's
symbolic QR of the whole J held thousands (the ten-bar's 24 × 24).

Mechanisms where some body hangs on the rest by slots alone (no revolute path from a placed body) keep
the general solve (``None`` here).
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca

from gagen.apps.linkage.spec import GROUND, Linkage, Revolute

Affine = tuple[ca.SX, dict[int, ca.SX]]  # a step entry as constant + Σ_k coefficient_k · turn_k


def revolute_tree(linkage: Linkage) -> dict[str, tuple[int, str]] | None:
    """Per moving body, the first row of the revolute joint that places it and the body on its other
    side (placed before it), growing from the ground and the driven body; None if a body is not
    reached."""
    rows, row = {}, 0
    for joint in linkage.active_joints:
        rows[joint] = row
        row += joint.rows
    placed, tree = {GROUND, *linkage.driven}, {}
    grown = True
    while grown:
        grown = False
        for joint in linkage.active_joints:
            if not isinstance(joint, Revolute):
                continue
            a, b = joint.a[0], joint.b[0]
            for body, other in ((a, b), (b, a)):
                if body not in placed and other in placed:
                    tree[body] = (rows[joint], other)
                    placed.add(body)
                    grown = True
    return tree if placed >= set(linkage.unknown) else None


def _nonzero(x: ca.SX) -> bool:
    return not x.is_zero()


def _combine(terms: Sequence[tuple[ca.SX, Affine]], constant: ca.SX) -> Affine:
    """constant + Σ coefficient · affine, as an affine of the turns."""
    out: dict[int, ca.SX] = {}
    for coefficient, (value, slope) in terms:
        if _nonzero(value):
            constant = constant + coefficient * value
        for k, c in slope.items():
            out[k] = out[k] + coefficient * c if k in out else coefficient * c
    return constant, out


def structured_solve(linkage: Linkage, F: ca.SX, J: ca.SX) -> ca.SX | None:
    """ΔB = −J⁻¹F (three entries per moving body: turn, then translation) by the revolute tree's
    elimination and a dense solve of the turns; None where no revolute tree reaches every body."""
    tree = revolute_tree(linkage)
    if tree is None:
        return None
    moving = linkage.unknown
    n, m = len(moving), F.shape[0]
    zero = ca.SX(0)
    step: dict[int, Affine] = {3 * i: (zero, {i: ca.SX(1)}) for i in range(n)}  # the turns

    def row_terms(r: int, skip: Sequence[int] = ()) -> list[tuple[ca.SX, Affine]]:
        return [(J[r, c], step[c]) for c in range(3 * n) if c not in skip and _nonzero(J[r, c])]

    used: set[int] = set()
    for body, (r, _) in _tree_order(tree, linkage):
        i = moving.index(body)
        cx, cy = 3 * i + 1, 3 * i + 2
        # the 2 × 2 block of this body's translation in the joint's rows, and the rest of the rows
        a, b, c, d = J[r, cx], J[r, cy], J[r + 1, cx], J[r + 1, cy]
        # block · v = −F_r − Σ_rest J Δ
        rx = _combine([(-j, step_) for j, step_ in row_terms(r, (cx, cy))], -F[r])
        ry = _combine([(-j, step_) for j, step_ in row_terms(r + 1, (cx, cy))], -F[r + 1])
        det = a * d - b * c
        # [vx, vy] = [[a, b], [c, d]]⁻¹ [rx, ry]
        step[cx] = _combine([(d / det, rx), (-b / det, ry)], zero)
        step[cy] = _combine([(-c / det, rx), (a / det, ry)], zero)
        used.update((r, r + 1))
    left = [r for r in range(m) if r not in used]
    if len(left) != n:
        return None
    A = ca.SX(n, n)
    rhs = ca.SX(n, 1)
    for row, r in enumerate(left):
        constant, slope = _combine(row_terms(r), F[r])  # F_r + Σ J Δ = 0: A turns = −constant
        rhs[row] = -constant
        for k, value in slope.items():
            A[row, k] = value
    turns = ca.solve(A, rhs)
    out = []
    for col in range(3 * n):
        constant, slope = step[col]
        value = constant
        for k, coefficient in slope.items():
            value = value + coefficient * turns[k]
        out.append(value)
    return ca.vertcat(*out)


def _tree_order(tree: dict[str, tuple[int, str]], linkage: Linkage) -> list[tuple[str, tuple[int, str]]]:
    """The tree's bodies, each after the body it hangs on."""
    placed = {GROUND, *linkage.driven}
    order: list[tuple[str, tuple[int, str]]] = []
    while len(order) < len(tree):
        for body, (row, parent) in tree.items():
            if body not in placed and parent in placed:
                order.append((body, (row, parent)))
                placed.add(body)
    return order
