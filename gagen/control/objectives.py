"""Mixed objectives over one multi-chain system: weighted cooperative primitives and the outer-product
distance ‖A ∧ B‖² [COOP Eq. 2-5, 9, 28, 40], stacked into one residual with its Jacobian.

A system's chains end in points; an objective states what those points should do, as a sum of
weighted terms, each a residual r_i(q) (the cost is Σ_i w_i ‖r_i(q)‖², the stacked residual
r = (√w_1 r_1, √w_2 r_2, …)):

- ``PrimitiveTarget(chains, kind, target)``: the primitive through the end points of some chains
  (any subset, any kind: the three arms' circle, the line through two of them) reaches the desired
  similarity V_Sd, r = e = log(V_Sc~ V_Sd) [Eq. 28, 40] (7 rows; build V_Sd with
  ``gagen.control.goals``);
- ``Incidence(a, b)``: the outer-product distance of Eq. 9, r = the coefficients of A ∧ B, zero exactly
  when the point A lies on the primitive B [Eq. 3]; A and B are operands (below). For a point x and a
  line through a with unit direction d it is ‖d × (x − a)‖² + det(a, d, x)² (the distance² plus the
  squared moment of x about the line's plane through the origin, so not origin-free); for a plane
  through a with unit normal n it is (n·(x − a))², the squared distance;
- ``Radius(of, radius)``: r = radius(X) − radius, for a round X [Eq. 26];
- ``Normal(of, normal)``: r = unit normal of the circle X − normal (3 rows, oriented like
  (x2 − x1) × (x3 − x1)) [Eq. 25];
- ``DilationForce(chains, kind)``: r = J_Gᵀ e_D (n rows), the dilation row of the geometric similarity
  Jacobian J_G = −2 V_Sc~ ∂V_Sc/∂q of the primitive through those chains [Sec. 3.11]: ‖r‖ = 1/β_D, so
  minimising it maximises the dilation force index of ``gagen.control.force_manipulability``.

A ``PrimitiveTarget(..., hard=True)`` is, for ``solve_ik(..., method="ipopt")``, the equality
constraint e(q) = 0 instead of a cost: "maximise β_D while the circle stays on its target" is
min ‖J_Gᵀ e_D‖² s.t. e(q) = 0 within the joint limits.

Operands: ``Cooperative(kind, chains)`` (the primitive through those chains' end points, Eq. 2;
``end_point(chain)`` is the point kind), a fixed primitive (``line``, ``plane``, ``point``,
``point_pair``, ``circle``, ``sphere``: built from spanning points as ``gagen.control.goals`` builds its
targets), ``Centre(of)`` (the centre of a round, X e∞ X [Eq. 27]) and ``Meet(a, b)`` (the intersection
(A* ∧ B*)* [Eq. 5]: a line and a plane meet in a flat point, returned as its conformal point; two
planes in a line).

Everything is written against the multivector protocol (``gagen.model``) and run once on CasADi SX
symbols: the residual and its Jacobian (CasADi AD) are one Function of q (``Objective.function``).
``solve_ik`` minimises ‖r‖² in joint limits; ``Objective.task`` is the same residual in the shape the
reaching OCP (``gagen.control.ocp.ReachingOCP``) takes as its terminal error. ``load_objectives`` reads
the same terms from a YAML file (``gagen.control.objectives_file``).
"""

from __future__ import annotations

import difflib
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TypeAlias, cast

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.algebra.multivector import SparseMultivector
from gagen.algebra.signature import cga3d
from gagen.control.differential import CONTROLLABLE_DIMENSION, nullspace_projector
from gagen.control.force_manipulability import DILATING
from gagen.control.goals import _frame
from gagen.control.ik import IKResult
from gagen.control.ik import solve_ik as _solve_ik
from gagen.model import kinematics as K
from gagen.model.conformal import SIMILARITY, point, vector
from gagen.model.guarded import safe_reciprocal
from gagen.model.primitives import (
    ROUNDS,
    centre,
    check_kind,
    meet,
    points_needed,
    radius,
    through,
    unit_normal,
)
from gagen.model.similarity import cooperative_similarity
from gagen.model.versors import log_similarity
from gagen.robots.system import System
from gagen.symbolic.casadi_backend import CasadiBackend

MV = SparseMultivector
LM_ROUND = 10  # Levenberg-Marquardt steps between checks of the gradient (solve_ik)
HELD = 1e-9  # rad (m): a joint this close to a limit counts as held there (hard terms' gradient)


# -- operands ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Cooperative:
    """The primitive of ``kind`` through the end points of ``chains`` (in that order) [COOP Eq. 2, 14]."""

    kind: str
    chains: tuple[str, ...]

    def __post_init__(self) -> None:
        check_kind(self.kind)
        object.__setattr__(self, "chains", tuple(self.chains))
        if len(self.chains) != points_needed(self.kind):
            raise ValueError(f"a cooperative {self.kind} is spanned by {points_needed(self.kind)} chains, "
                             f"got {len(self.chains)}: {list(self.chains)}")
        if len(set(self.chains)) != len(self.chains):
            raise ValueError(f"a cooperative {self.kind}: chains must differ, got {list(self.chains)}")


@dataclass(frozen=True)
class Fixed:
    """A fixed primitive of ``kind`` through the given spanning points (3-vectors, as many as the kind
    needs); made by ``point``, ``point_pair``, ``line``, ``plane``, ``circle``, ``sphere``."""

    kind: str
    points: tuple[tuple[float, float, float], ...]

    def __post_init__(self) -> None:
        check_kind(self.kind)
        points = tuple(_xyz(p, f"{self.kind} point") for p in self.points)
        object.__setattr__(self, "points", points)
        if len(points) != points_needed(self.kind):
            raise ValueError(f"a {self.kind} is spanned by {points_needed(self.kind)} points, "
                             f"got {len(points)}")


@dataclass(frozen=True)
class Centre:
    """The centre of a round (point pair, circle, sphere), a normalised point [COOP Eq. 27]."""

    of: Operand

    def __post_init__(self) -> None:
        if kind_of(self.of) not in ROUNDS:
            raise ValueError(f"centre: expected a round ({', '.join(ROUNDS)}), got a {kind_of(self.of)}")


@dataclass(frozen=True)
class Meet:
    """The intersection (A* ∧ B*)* [COOP Eq. 5] of a line and a plane (a point: the flat point's
    conformal point) or of two planes (a line)."""

    a: Operand
    b: Operand

    def __post_init__(self) -> None:
        kinds = sorted((kind_of(self.a), kind_of(self.b)))
        if kinds not in (["line", "plane"], ["plane", "plane"]):
            raise ValueError(f"meet: expected a line and a plane, or two planes; got a {kinds[0]} and a "
                             f"{kinds[1]}")


Operand: TypeAlias = "Cooperative | Fixed | Centre | Meet"


def kind_of(operand: Operand) -> str:
    """The primitive kind an operand stands for."""
    if isinstance(operand, (Cooperative, Fixed)):
        return operand.kind
    if isinstance(operand, Centre):
        return "point"
    if isinstance(operand, Meet):
        return "point" if "line" in (kind_of(operand.a), kind_of(operand.b)) else "line"
    raise ValueError(f"not an operand: {operand!r}; expected Cooperative, Fixed, Centre or Meet")


def end_point(chain: str) -> Cooperative:
    """The end point of one chain."""
    return Cooperative("point", (chain,))


def _xyz(value: ArrayLike, what: str) -> tuple[float, float, float]:
    array = np.asarray(value, dtype=float)
    if array.shape != (3,) or not np.all(np.isfinite(array)):
        raise ValueError(f"{what}: expected 3 finite coordinates, got {np.asarray(value).tolist()}")
    x, y, z = (float(v) for v in array)
    return x, y, z


def _unit(value: ArrayLike, what: str) -> NDArray[np.float64]:
    array = np.array(_xyz(value, what))
    norm = float(np.linalg.norm(array))
    if norm < 1e-12:
        raise ValueError(f"{what}: expected a non-zero direction, got {array.tolist()}")
    return array / norm


def point_at(position: ArrayLike) -> Fixed:
    """The fixed point at ``position``."""
    return Fixed("point", (_xyz(position, "point position"),))


def point_pair(first: ArrayLike, second: ArrayLike) -> Fixed:
    return Fixed("point_pair", (_xyz(first, "point pair first"), _xyz(second, "point pair second")))


def line(point: ArrayLike, direction: ArrayLike) -> Fixed:
    """The line through ``point`` along ``direction`` (made unit, so Eq. 9 reads in metres)."""
    p, d = np.array(_xyz(point, "line point")), _unit(direction, "line direction")
    return Fixed("line", (_xyz(p, ""), _xyz(p + d, "")))


def plane(point: ArrayLike, normal: ArrayLike) -> Fixed:
    """The plane through ``point`` with unit normal along ``normal``."""
    p, n = np.array(_xyz(point, "plane point")), _unit(normal, "plane normal")
    u, v = _frame(n)
    return Fixed("plane", (_xyz(p, ""), _xyz(p + u, ""), _xyz(p + v, "")))


def _positive(value: float, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)) \
            or not math.isfinite(value) or value <= 0:
        raise ValueError(f"{what}: expected a finite number > 0, got {value!r}")
    return float(value)


def circle(centre: ArrayLike, radius: float, normal: ArrayLike) -> Fixed:
    c, n = np.array(_xyz(centre, "circle centre")), _unit(normal, "circle normal")
    r = _positive(radius, "circle radius")
    u, v = _frame(n)
    return Fixed("circle", (_xyz(c + r * u, ""), _xyz(c + r * v, ""), _xyz(c - r * u, "")))


def sphere(centre: ArrayLike, radius: float) -> Fixed:
    c, r = np.array(_xyz(centre, "sphere centre")), _positive(radius, "sphere radius")
    e = np.eye(3)
    return Fixed("sphere", tuple(_xyz(c + r * s * e[k], "") for s, k in ((1, 0), (1, 1), (-1, 0), (1, 2))))


# -- terms ------------------------------------------------------------------------------------------------
def _weight(value: float) -> float:
    return _positive(value, "weight")


def _hard(value: object) -> bool:
    if not isinstance(value, bool):
        raise ValueError(f"hard: expected True or False, got {value!r}")
    return value


@dataclass(frozen=True)
class PrimitiveTarget:
    """The cooperative primitive of ``kind`` through ``chains`` reaches V_Sd = ``target`` (12
    coefficients, ``SIMILARITY`` order): r = log(V_Sc~ V_Sd) [COOP Eq. 40] (7 rows)."""

    chains: tuple[str, ...]
    kind: str
    target: tuple[float, ...]
    weight: float = 1.0
    name: str = ""
    hard: bool = False
    of: Cooperative = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "of", Cooperative(self.kind, tuple(self.chains)))
        object.__setattr__(self, "chains", tuple(self.chains))
        values = np.asarray(self.target, dtype=float).ravel()
        if values.shape != (len(SIMILARITY),) or not np.all(np.isfinite(values)):
            raise ValueError(f"target: expected V_Sd, {len(SIMILARITY)} finite coefficients "
                             f"(gagen.control.goals), got shape {values.shape}")
        object.__setattr__(self, "target", tuple(float(v) for v in values))
        object.__setattr__(self, "weight", _weight(self.weight))
        _hard(self.hard)


@dataclass(frozen=True)
class Incidence:
    """Eq. 9's outer-product distance ‖A ∧ B‖²: r = the coefficients of A ∧ B."""

    a: Operand
    b: Operand
    weight: float = 1.0
    name: str = ""

    def __post_init__(self) -> None:
        kinds = (kind_of(self.a), kind_of(self.b))
        if "point" not in kinds:
            raise ValueError(f"incidence: one operand must be a point (an end point, a centre, a meet of a "
                             f"line and a plane, a fixed point); got a {kinds[0]} and a {kinds[1]}")
        object.__setattr__(self, "weight", _weight(self.weight))


@dataclass(frozen=True)
class Radius:
    """r = radius(X) − ``radius`` for a round X [COOP Eq. 26]."""

    of: Operand
    radius: float
    weight: float = 1.0
    name: str = ""

    def __post_init__(self) -> None:
        if kind_of(self.of) not in ROUNDS:
            raise ValueError(f"radius: expected a round ({', '.join(ROUNDS)}), got a {kind_of(self.of)}")
        object.__setattr__(self, "radius", _positive(self.radius, "radius"))
        object.__setattr__(self, "weight", _weight(self.weight))


@dataclass(frozen=True)
class Normal:
    """r = unit normal of the circle X − ``normal`` (made unit) [COOP Eq. 25]: 3 rows."""

    of: Operand
    normal: tuple[float, float, float]
    weight: float = 1.0
    name: str = ""

    def __post_init__(self) -> None:
        if kind_of(self.of) != "circle":
            raise ValueError(f"normal: expected a circle, got a {kind_of(self.of)}")
        object.__setattr__(self, "normal", _xyz(_unit(self.normal, "normal"), "normal"))
        object.__setattr__(self, "weight", _weight(self.weight))


@dataclass(frozen=True)
class DilationForce:
    """r = J_Gᵀ e_D (n rows, one per joint): the e0∞ row of the geometric similarity Jacobian J_G =
    −2 V_Sc~ ∂V_Sc/∂q of the primitive of ``kind`` through ``chains`` [COOP Sec. 3.11]. ‖r‖ = 1/β_D, the
    reciprocal dilation force index (``force_manipulability.dilation_force_index``), so the cost w/β_D²
    pulls toward configurations that squeeze or stretch the primitive with less joint torque. Only for
    kinds that dilate (point pair, circle, sphere)."""

    chains: tuple[str, ...]
    kind: str
    weight: float = 1.0
    name: str = ""
    of: Cooperative = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if self.kind not in DILATING:
            dilating = ", ".join(sorted(DILATING))
            raise ValueError(f"dilation force: expected a primitive that dilates ({dilating}), "
                             f"got {self.kind!r}")
        object.__setattr__(self, "of", Cooperative(self.kind, tuple(self.chains)))
        object.__setattr__(self, "chains", tuple(self.chains))
        object.__setattr__(self, "weight", _weight(self.weight))


Term: TypeAlias = "PrimitiveTarget | Incidence | Radius | Normal | DilationForce"
TERM_TYPES = (PrimitiveTarget, Incidence, Radius, Normal, DilationForce)


def _operands(term: Term) -> list[Operand]:
    if isinstance(term, PrimitiveTarget):
        return [term.of]
    if isinstance(term, Incidence):
        return [term.a, term.b]
    return [term.of]


def _chains_of(operand: Operand) -> list[str]:
    if isinstance(operand, Cooperative):
        return list(operand.chains)
    if isinstance(operand, Centre):
        return _chains_of(operand.of)
    if isinstance(operand, Meet):
        return _chains_of(operand.a) + _chains_of(operand.b)
    return []


# -- the graph --------------------------------------------------------------------------------------------
class _Builder:
    """The objective's multivectors on CasADi symbols: end points from the chains' kinematics
    (``kinematics.chain_pose``, positions only), primitives through them, the terms' residuals."""

    def __init__(self, system: System, q: ca.SX) -> None:
        self.backend = CasadiBackend()
        self.zero = SparseMultivector(cga3d(), self.backend, {})
        self.system = system
        self.q = q
        self._ends: dict[str, MV] = {}
        self._index = {chain.name: i for i, chain in enumerate(system.chains)}

    def end(self, name: str) -> MV:
        if name not in self._ends:
            i = self._index[name]
            chain, indices = self.system.chains[i], self.system.chain_indices()[i]
            qi = [self.backend.lift(self.q[j]) for j in indices]
            _, _, position = K.chain_pose(self.zero, chain.joints, qi, with_motor=False)
            self._ends[name] = cast(MV, point(position))
        return self._ends[name]

    def operand(self, operand: Operand) -> MV:
        if isinstance(operand, Cooperative):
            return cast(MV, through(operand.kind, [self.end(c) for c in operand.chains]))
        if isinstance(operand, Fixed):
            spanning = [point(vector(self.zero, list(p))) for p in operand.points]
            return cast(MV, through(operand.kind, spanning))
        if isinstance(operand, Centre):
            return cast(MV, centre(self.operand(operand.of)))
        x = cast(MV, meet(self.operand(operand.a), self.operand(operand.b)))
        if kind_of(operand) == "point":  # a flat point α (e0 + x) ∧ e∞: its conformal point P(x)
            weight = safe_reciprocal(x.math, x["e0inf"])
            return cast(MV, point(vector(x, [x[f"e{k}inf"] * weight for k in "123"])))
        return x

    def dilation_row(self, term: DilationForce) -> ca.SX:
        """J_Gᵀ e_D = (−2 V~ ∂V/∂q)[e0∞] as an n-column: the e0∞ coefficient of −2 V~ D is linear in
        D's 12 coefficients, so its gradient with respect to them (a 1 × 12 row in V) times ∂V/∂q (AD)
        gives the row without forming n multivector products."""
        versor = cooperative_similarity(term.kind, self.operand(term.of)).versor
        coefficients = ca.vertcat(*[self.backend.native(versor[b]) for b in SIMILARITY])
        d = ca.SX.sym("d", len(SIMILARITY))
        direction = self.zero.make({b: self.backend.lift(d[i]) for i, b in enumerate(SIMILARITY)})
        dilation = self.backend.native(((~versor) * direction * -2)["e0inf"])
        return (ca.jacobian(dilation, d) @ ca.jacobian(coefficients, self.q)).T

    def column(self, x: MV) -> tuple[ca.SX, list[str]]:
        blades = [x.algebra.blade_name(b) for b in x.support]
        values = [self.backend.native(x[b]) for b in blades]
        return (ca.vertcat(*values) if values else ca.SX(0, 1)), blades

    def residual(self, term: Term) -> tuple[ca.SX, list[str]]:
        if isinstance(term, PrimitiveTarget):
            versor = cooperative_similarity(term.kind, self.operand(term.of)).versor
            desired = self.zero.make(dict(zip(SIMILARITY, term.target, strict=True)))
            error = cast(MV, log_similarity(~versor * desired))
            blades = ["e12", "e13", "e23", "e0inf", "e1inf", "e2inf", "e3inf"]
            return ca.vertcat(*[self.backend.native(error[b]) for b in blades]), blades
        if isinstance(term, Incidence):
            return self.column(self.operand(term.a) ^ self.operand(term.b))
        if isinstance(term, Radius):
            value = self.backend.native(radius(self.operand(term.of))) - term.radius
            return ca.vertcat(value), ["radius"]
        if isinstance(term, DilationForce):
            return self.dilation_row(term), [f"q{j}" for j in range(self.system.dof)]
        n = cast(MV, unit_normal(self.operand(term.of)))
        return ca.vertcat(*[self.backend.native(n[f"e{k}"]) - term.normal[k - 1] for k in (1, 2, 3)]), \
            ["n1", "n2", "n3"]


class Objective:
    """Weighted terms over the joints q of ``system``: the stacked residual r(q) = (√w_i r_i(q)) and its
    Jacobian J = ∂r/∂q, as one CasADi Function (``function``: q → r, J), built once.

    ``labels``: a row label per residual entry (``term:blade``); ``rows``: each term's slice of r;
    ``hard``: the names of the terms stated ``hard=True`` (equality constraints for IPOPT).
    """

    def __init__(self, system: System, terms: Sequence[Term]) -> None:
        if not terms:
            raise ValueError("an objective needs at least one term")
        chains = [c.name for c in system.chains]
        names: list[str] = []
        for i, term in enumerate(terms):
            if not isinstance(term, TERM_TYPES):
                raise ValueError(f"terms[{i}]: not a term: {term!r}; expected PrimitiveTarget, Incidence, "
                                 f"Radius, Normal or DilationForce")
            for chain in (c for operand in _operands(term) for c in _chains_of(operand)):
                if chain not in chains:
                    close = difflib.get_close_matches(chain, chains, n=1)
                    hint = f"did you mean {close[0]!r}?" if close else f"expected one of {', '.join(chains)}"
                    raise ValueError(f"terms[{i}]: unknown chain {chain!r} of system {system.name!r}; {hint}")
            name = term.name or f"{type(term).__name__.lower()}{i}"
            if name in names:
                raise ValueError(f"terms[{i}]: name {name!r} is used twice")
            names.append(name)
        self.system, self.terms, self.names = system, tuple(terms), tuple(names)
        q = ca.SX.sym("q", system.dof)
        builder = _Builder(system, q)
        parts, labels, rows, start = [], [], {}, 0
        for name, term in zip(names, terms, strict=True):
            r, blades = builder.residual(term)
            parts.append(math.sqrt(term.weight) * r)
            labels += [f"{name}:{b}" for b in blades]
            rows[name] = slice(start, start + r.numel())
            start += r.numel()
        residual = ca.vertcat(*parts)
        self._symbol, self._builder = q, builder
        self._values: dict[Operand, ca.Function] = {}
        self._blades: dict[Operand, list[str]] = {}
        self.labels, self.rows, self.size = tuple(labels), rows, start
        self.hard = tuple(n for n, t in zip(names, terms, strict=True) if getattr(t, "hard", False))
        hard = set(self.hard)
        self._hard_rows = np.array([j for n in names if n in hard for j in range(start)[rows[n]]], dtype=int)
        self._soft_rows = np.array([j for n in names if n not in hard for j in range(start)[rows[n]]],
                                   dtype=int)
        self.function = ca.Function("objective", [q], [residual, ca.jacobian(residual, q)], ["q"], ["r", "J"])
        V_Sd = ca.SX.sym("V_Sd", len(SIMILARITY))  # unused: the reaching OCP's task signature
        self.task = ca.Function("objective_task", [q, V_Sd], [residual, ca.jacobian(residual, q)],
                                ["q", "V_Sd"], ["e", "J_Be"])

    def __call__(self, q: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(r, J) at q."""
        r, J = self.function(self._q(q))
        return np.array(r, dtype=float).ravel(), np.array(J, dtype=float)

    def _q(self, q: ArrayLike) -> NDArray[np.float64]:
        values = np.asarray(q, dtype=float).ravel()
        if values.size != self.system.dof or not np.all(np.isfinite(values)):
            raise ValueError(f"q: expected {self.system.dof} finite joint values, got {values.size}")
        return values

    def residual(self, q: ArrayLike) -> NDArray[np.float64]:
        return self(q)[0]

    def cost(self, q: ArrayLike) -> float:
        """Σ_i w_i ‖r_i(q)‖² = ‖r(q)‖²."""
        r = self.residual(q)
        return float(r @ r)

    def term_norms(self, q: ArrayLike) -> dict[str, float]:
        """Each term's unweighted ‖r_i(q)‖, by name."""
        r = self.residual(q)
        return {name: float(np.linalg.norm(r[self.rows[name]])) / math.sqrt(term.weight)
                for name, term in zip(self.names, self.terms, strict=True)}

    def value(self, operand: Operand, q: ArrayLike) -> dict[str, float]:
        """An operand's multivector at q, by blade name (the blades it may have): e.g. a centre's
        ``e1``, ``e2``, ``e3``; for plots and checks. Chains are checked as in the terms."""
        if operand not in self._values:
            chains = [c.name for c in self.system.chains]
            unknown = [c for c in _chains_of(operand) if c not in chains]
            if unknown:
                raise ValueError(f"unknown chain {unknown[0]!r}; expected one of {', '.join(chains)}")
            column, blades = self._builder.column(self._builder.operand(operand))
            self._values[operand] = ca.Function("value", [self._symbol], [column])
            self._blades[operand] = blades
        values = np.array(self._values[operand](self._q(q)), dtype=float).ravel()
        return dict(zip(self._blades[operand], values.tolist(), strict=True))

    def position(self, operand: Operand, q: ArrayLike) -> NDArray[np.float64]:
        """The Euclidean position of a point operand (an end point, a centre, a meet) at q."""
        if kind_of(operand) != "point":
            raise ValueError(f"position: expected a point operand, got a {kind_of(operand)}")
        x = self.value(operand, q)
        weight = x.get("e0", 0.0)  # −P·e∞: the point's weight, its e0 coefficient
        if weight == 0.0:
            raise ValueError("position: the point has weight 0 (a degenerate construction)")
        return np.array([x.get(f"e{k}", 0.0) for k in "123"]) / weight


# -- inverse kinematics -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class ObjectiveResult:
    """``q``: the solution; ``residual``: r(q) and ``cost`` ‖r‖²; ``gradient``: ‖Jᵀr‖ on the joints free
    to move (a joint at a limit pushed outwards counts as held); ``converged``: ‖r‖ <= tol (the terms
    agree) or gradient <= gtol (a weighted compromise: a stationary point of the cost);
    ``iterations``; ``message``; ``ik``: the Levenberg-Marquardt result (method "lm"). With hard terms
    (IPOPT) ``cost`` and ``gradient`` are the soft terms', the gradient projected onto the hard terms'
    nullspace (I − J_h⁺ J_h) Jᵀr, ``constraint`` is ‖r_h‖ (the hard rows) and ``converged`` needs
    ``constraint`` <= tol besides; ``seconds``: the solver's wall time."""

    q: NDArray[np.float64]
    residual: NDArray[np.float64]
    cost: float
    gradient: float
    converged: bool
    iterations: int
    message: str
    ik: IKResult | None = None
    constraint: float = 0.0
    seconds: float = 0.0


def _projected_gradient(J: NDArray[np.float64], r: NDArray[np.float64], q: NDArray[np.float64],
                        bounds: tuple[NDArray[np.float64], NDArray[np.float64]] | None,
                        hard: NDArray[np.int_] | None = None) -> float:
    if hard is not None and hard.size:
        # the soft cost's gradient along the hard terms' nullspace, on the joints off their limits (a
        # joint at a limit, within 1e-9, counts as held whatever the sign: a convergence indicator)
        soft = np.setdiff1d(np.arange(r.size), hard)
        free = np.ones(q.size, dtype=bool) if bounds is None else \
            (q > bounds[0] + HELD) & (q < bounds[1] - HELD)
        g = nullspace_projector(J[np.ix_(hard, free)]) @ (J[np.ix_(soft, free)].T @ r[soft])
        return float(np.linalg.norm(g))
    g = J.T @ r
    if bounds is not None:
        lower, upper = bounds
        g = np.where(((q <= lower) & (g > 0)) | ((q >= upper) & (g < 0)), 0.0, g)
    return float(np.linalg.norm(g))


def _independent_rows(objective: Objective, stacked: ca.SX, q0: NDArray[np.float64]) -> ca.SX:
    """The hard targets' errors as independent equality constraints: e's 7 rows have rank k =
    CONTROLLABLE_DIMENSION[kind] < 7 (a circle cannot turn about its own normal, Table 1), and on a
    redundant equality IPOPT's multipliers diverge (measured: |λ| ~ 1e27, stopping with a KKT residual
    of 8e-4 relative). So each is U_kᵀ e, U_k the top k left singular vectors of ∂e/∂q at q0: range ∂e/∂q
    at e = 0 is the target's tangent space, whatever q on its self-motion manifold, so U_kᵀ e = 0 is
    e = 0 near the target."""
    _, J = objective(q0)
    parts = []
    for name, term in zip(objective.names, objective.terms, strict=True):
        if name in objective.hard:
            rows = objective.rows[name]
            k = min(CONTROLLABLE_DIMENSION[term.kind], objective.system.dof)  # type: ignore[union-attr]
            u = np.linalg.svd(J[rows], full_matrices=False)[0][:, :k]
            parts.append(ca.DM(u.T) @ stacked[rows.start:rows.stop])
    return ca.vertcat(*parts) if parts else ca.SX(0, 1)


def solve_ik(objective: Objective, q0: ArrayLike, *, limits: tuple[ArrayLike, ArrayLike] | None = None,
             method: str = "lm", tol: float = 1e-12, gtol: float = 1e-12,
             max_iterations: int = 200) -> ObjectiveResult:
    """q* = argmin ‖r(q)‖² = Σ_i w_i ‖r_i(q)‖² within ``limits`` (lower, upper), from ``q0``.

    ``method`` "lm": the damped Gauss-Newton (Levenberg-Marquardt) iteration of
    ``gagen.control.ik.solve_ik`` on the stacked residual (limits held by its bounded step); "ipopt":
    IPOPT through ``casadi.nlpsol`` on the cost with the limits as bounds (exact Hessian by AD), which
    converges fast also where the terms cannot all vanish (a weighted compromise); the terms stated
    ``hard=True`` are its equality constraints r_i(q) = 0 (IPOPT only)."""
    q = objective._q(q0)
    hard, soft = objective._hard_rows, objective._soft_rows
    if hard.size and method != "ipopt":
        raise ValueError(f"method: hard terms ({', '.join(objective.hard)}) are equality constraints, which "
                         f"need method 'ipopt'; got {method!r}")
    started = time.perf_counter()
    bounds = None
    if limits is not None:
        lower, upper = (np.broadcast_to(np.asarray(b, dtype=float), q.shape).copy() for b in limits)
        if np.any(lower > upper):
            raise ValueError("limits: expected lower <= upper")
        bounds = (lower, upper)
        q = np.clip(q, lower, upper)
    ik = None
    if method == "lm":
        # in rounds of LM_ROUND steps, stopping once the projected gradient is below gtol: where the terms
        # cannot all vanish (a weighted compromise) ‖r‖ never meets tol, and the steps past the optimum
        # would only shave rounding off ‖r‖² until max_iterations
        iterations, history = 0, list[float]()
        while True:
            ik = _solve_ik(lambda x, _: objective(x), q, np.zeros(1), tol=tol, limits=bounds,
                           max_iterations=min(LM_ROUND, max_iterations - iterations))
            q, iterations = ik.q, iterations + ik.iterations
            history += list(ik.history if not history else ik.history[1:])
            r, J = objective(q)
            if ik.status != "max_iterations" or iterations >= max_iterations \
                    or _projected_gradient(J, r, q, bounds) <= gtol:
                break
        ik = replace(ik, iterations=iterations, history=np.array(history))
        message = f"{ik.status} after {iterations} iterations"
    elif method == "ipopt":
        x = ca.SX.sym("q", q.size)
        stacked = objective.function(x)[0]
        costs, constraints = stacked[soft.tolist()], _independent_rows(objective, stacked, q)
        solver = ca.nlpsol("objective_ik", "ipopt", {"x": x, "f": ca.dot(costs, costs), "g": constraints},
                           {"ipopt.print_level": 0, "ipopt.sb": "yes", "print_time": False,
                            "ipopt.tol": 1e-14, "ipopt.max_iter": max_iterations})
        inf = np.full(q.size, np.inf)
        lbx, ubx = bounds if bounds is not None else (-inf, inf)
        solution = solver(x0=q, lbx=lbx, ubx=ubx, lbg=0.0, ubg=0.0)
        q = np.array(solution["x"], dtype=float).ravel()
        stats = solver.stats()
        iterations, message = int(stats["iter_count"]), f"IPOPT {stats['return_status']}"
    else:
        raise ValueError(f"method: expected 'lm' or 'ipopt', got {method!r}")
    seconds = time.perf_counter() - started
    r, J = objective(q)
    gradient = _projected_gradient(J, r, q, bounds, hard)
    constraint = float(np.linalg.norm(r[hard]))
    cost = float(r[soft] @ r[soft])
    converged = bool(constraint <= tol and (math.sqrt(cost) <= tol or gradient <= gtol))
    return ObjectiveResult(q=q, residual=r, cost=cost, gradient=gradient, converged=converged,
                           iterations=iterations, message=message, ik=ik, constraint=constraint,
                           seconds=seconds)
