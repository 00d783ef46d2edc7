"""The kernel catalogue of every bundled system against the interpreter: values, the similarity
property X_c = V_Sc X_u V_Sc~, and every Jacobian against central differences of the interpreter.

Finite differences perturb one joint at a time, so the interpreter's FK of the chains that do not
contain that joint is memoised (same numbers, computed once): the 34-DOF systems stay affordable.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
from conftest import tiered

from gagen.algebra.signature import cga3d
from gagen.apps.cooperative.bundled import bundled_systems, ready_configuration
from gagen.apps.cooperative.catalogue import build_kernels
from gagen.interp import MultiVector
from gagen.model import kinematics as K
from gagen.model.conformal import SIMILARITY, SIMILARITY_GENERATOR
from gagen.model.fitting import span
from gagen.model.kinematics import TOOL_LINE
from gagen.model.primitives import points_needed, unit_primitive
from gagen.model.similarity import cooperative_similarity
from gagen.model.versors import exp_similarity, log_similarity
from gagen.robots.system import (
    cooperative_jacobian,
    cooperative_primitive,
    similarity_of,
    task_error,
)

ALG = cga3d()
ZERO = MultiVector.zero(ALG)
SYSTEMS = bundled_systems()
CONFIGURATIONS = 20
SYSTEM_CONFIGURATIONS = 8
H = 1e-6


@cache
def _kernels(name):
    return build_kernels(SYSTEMS[name])


def _configurations(name, count, seed=0):
    rng = np.random.default_rng(seed)
    q0 = np.array(ready_configuration(SYSTEMS[name]))
    return [q0 + rng.uniform(-0.4, 0.4, q0.size) for _ in range(count)]


def _desired(seed=1):
    rng = np.random.default_rng(seed)
    b = MultiVector.from_blades(ALG, dict(zip(SIMILARITY_GENERATOR, rng.uniform(-0.5, 0.5, 7), strict=True)))
    return exp_similarity(b)


@cache
def _chain_point(name: str, chain: int, qc: tuple[float, ...]) -> MultiVector:
    return K.end_point(K.forward_kinematics(ZERO, SYSTEMS[name].chains[chain].joints, list(qc)))


def _interp(name, q, desired):
    """The model on the interpreter: X_c = through(kind, end points), as cooperative_primitive (their best
    fit with more chains than the kind needs, its conditioning a factor of V_Sc's)."""
    system = SYSTEMS[name]
    points = [_chain_point(name, i, tuple(qc)) for i, qc in enumerate(system.split(list(q)))]
    spanned = span(system.kind, points)
    xc = spanned.primitive
    v, cond = cooperative_similarity(system.kind, xc)
    cond = cond * spanned.conditioning if spanned.fitted else cond
    return {"X_c": xc, "V_Sc": v, "conditioning": cond, "log_V": log_similarity(v),
            "e": log_similarity(~v * desired)}


def _rows(x: MultiVector, port) -> np.ndarray:
    return np.array([x[b] for b in port.rows])


def _call(kernel, *args) -> dict[str, np.ndarray]:
    values = kernel.function(*args)
    values = values if isinstance(values, (list, tuple)) else [values]
    return {p.name: np.asarray(v, dtype=float).reshape(p.shape) for p, v in zip(kernel.outputs, values,
                                                                               strict=True)}


def _port(kernel, name):
    return next(p for p in kernel.outputs if p.name == name)


SYSTEM_KERNELS = ("primitive", "similarity", "similarity_jacobians", "task")


class _Union:
    """The system kernels' outputs together (each output comes from exactly one kernel)."""

    def __init__(self, name):
        self.kernels = [_kernels(name)[k] for k in SYSTEM_KERNELS]
        self.outputs = tuple(p for k in self.kernels for p in k.outputs)
        assert len({p.name for p in self.outputs}) == len(self.outputs) == 10

    def __call__(self, q, vsd):
        out = {}
        for k in self.kernels:
            out.update(_call(k, *([q] if len(k.inputs) == 1 else [q, vsd])))
        return out


@pytest.mark.parametrize("name", tiered(sorted(SYSTEMS), {"panda_point"}))  # 1-7 s a system
def test_kernel_values_equal_interpreter_and_v_sc_moves_x_u_onto_x_c(name):
    desired = _desired()
    system = SYSTEMS[name]
    q = _configurations(name, 1)[0]  # the model's own entry points agree with the memoised one
    ref = _interp(name, q, desired)
    np.testing.assert_allclose(cooperative_primitive(ZERO, system, list(q)).coeffs, ref["X_c"].coeffs, atol=0)
    np.testing.assert_allclose(similarity_of(ZERO, system, list(q))[0].coeffs, ref["V_Sc"].coeffs, atol=0)
    np.testing.assert_allclose(task_error(ZERO, system, list(q), desired).coeffs, ref["e"].coeffs, atol=0)
    full = _Union(name)
    vsd = [desired[b] for b in SIMILARITY]
    for q in _configurations(name, CONFIGURATIONS):
        out = full(q, vsd)
        ref = _interp(name, q, desired)
        assert ref["conditioning"] > 1e-8  # near the ready pose: well-conditioned (hands: (6 vol)² ~ 1e-6)
        for key in ("X_c", "V_Sc", "log_V", "e"):
            np.testing.assert_allclose(out[key].ravel(), _rows(ref[key], _port(full, key)), atol=1e-10)
        assert abs(out["conditioning"].item() - ref["conditioning"]) < 1e-10
        moved = ref["V_Sc"].sandwich(unit_primitive(system.kind, ZERO)).coeffs
        xc = ref["X_c"].coeffs
        scale = moved @ xc / (xc @ xc)
        np.testing.assert_allclose(moved, scale * xc, atol=1e-10 * np.max(np.abs(xc)))


def _central_differences(name, q, desired):
    cols = {key: [] for key in ("X_c", "V_Sc", "log_V", "e")}
    for i in range(q.size):
        step = np.zeros(q.size)
        step[i] = H
        plus, minus = _interp(name, q + step, desired), _interp(name, q - step, desired)
        for key in cols:
            cols[key].append((plus[key].coeffs - minus[key].coeffs) / (2 * H))
    return {key: np.array(c).T for key, c in cols.items()}


def _blade_rows(dense, port):
    return dense[[ALG.blade(b) for b in port.rows], :]


@pytest.mark.parametrize("name", tiered(sorted(SYSTEMS), {"panda_point"}))
def test_every_system_jacobian_equals_central_differences(name):
    """J_c, J_A,Sc, J_G,Sc, J_B and J_Be against central differences of the interpreter at
    SYSTEM_CONFIGURATIONS configurations (34 DOF take 2 interpreter solves per joint each)."""
    desired = _desired()
    full = _Union(name)
    vsd = [desired[b] for b in SIMILARITY]
    for q in _configurations(name, SYSTEM_CONFIGURATIONS, seed=5):
        out = full(q, vsd)
        fd = _central_differences(name, q, desired)
        v = _interp(name, q, desired)["V_Sc"]
        np.testing.assert_allclose(out["J_c"], _blade_rows(fd["X_c"], _port(full, "J_c")), atol=2e-7)
        np.testing.assert_allclose(out["J_A"], _blade_rows(fd["V_Sc"], _port(full, "J_A")), atol=2e-7)
        j_g = np.array([(~v * MultiVector(ALG, col) * -2).coeffs for col in fd["V_Sc"].T]).T
        np.testing.assert_allclose(out["J_G"], _blade_rows(j_g, _port(full, "J_G")), atol=2e-7)
        np.testing.assert_allclose(out["J_B"], _blade_rows(fd["log_V"], _port(full, "J_B")), atol=2e-7)
        np.testing.assert_allclose(out["J_Be"], _blade_rows(fd["e"], _port(full, "J_Be")), atol=2e-7)


# the systems whose X_c is spanned (a fitted one, with more chains, has no closed form Eq. 15-17)
SPANNED = sorted(n for n, s in SYSTEMS.items() if len(s.chains) == points_needed(s.kind))


@pytest.mark.parametrize("name", tiered(SPANNED, {"panda_point"}))  # alone: builds the kernels
def test_system_jacobian_j_c_equals_the_models_closed_form(name):
    """J_c of the kernel equals the model's Eq. 15-17 on the interpreter (shared joints summed)."""
    full = _Union(name)
    for q in _configurations(name, 3, seed=9):
        out = full(q, [_desired()[b] for b in SIMILARITY])
        columns = cooperative_jacobian(ZERO, SYSTEMS[name], list(q))
        ours = np.array([[c[b] for b in _port(full, "J_c").rows] for c in columns]).T
        np.testing.assert_allclose(out["J_c"], ours, atol=1e-10)


def _chain_fd(joints, qc, *fns):
    """Central differences of each fn(FK motor), the motors at q ± h e_i computed once for all."""
    cols = [[] for _ in fns]
    for i in range(qc.size):
        step = np.zeros(qc.size)
        step[i] = H
        plus = K.forward_kinematics(ZERO, joints, list(qc + step))
        minus = K.forward_kinematics(ZERO, joints, list(qc - step))
        for c, fn in zip(cols, fns, strict=True):
            c.append((fn(plus).coeffs - fn(minus).coeffs) / (2 * H))
    return [np.array(c).T for c in cols]


def _arm(chain) -> tuple:
    """A chain's joints after its base placement: the same arm on another base is the same kernel
    code with other constants."""
    joints = chain.joints
    return tuple(joints[1:] if joints and joints[0].name.endswith("_base") else joints)


@cache
def _first_systems() -> dict[tuple, tuple[str, str]]:
    """Per arm, the (system, chain) where it first appears, in sorted order."""
    first: dict[tuple, tuple[str, str]] = {}
    for name in sorted(SYSTEMS):
        for chain in SYSTEMS[name].chains:
            first.setdefault(_arm(chain), (name, chain.name))
    return first


REPEATED_ARM_CONFIGURATIONS = 3


@pytest.mark.parametrize("name", tiered(sorted(SYSTEMS), {"panda_point"}))
def test_every_chain_kernel_equals_interpreter_and_its_jacobians_central_differences(name):
    """Per chain of every system: M, P, L values against the interpreter; J_A, J_S, J_b, J_P, J_L
    against central differences of the interpreter's FK. An arm is checked at CONFIGURATIONS
    configurations where it first appears and at REPEATED_ARM_CONFIGURATIONS on every other base."""
    system = SYSTEMS[name]
    tool = ZERO.make({TOOL_LINE: 1})
    for k, q in enumerate(_configurations(name, CONFIGURATIONS, seed=11)):
        for chain, qc in zip(system.chains, system.split(list(q)), strict=True):
            if k >= REPEATED_ARM_CONFIGURATIONS and _first_systems()[_arm(chain)] != (name, chain.name):
                continue
            qc = np.array(qc)
            kernel = _kernels(name)[f"{chain.name}_jacobians"]
            out = _call(kernel, qc)
            motor = K.forward_kinematics(ZERO, chain.joints, list(qc))
            np.testing.assert_allclose(out["M"].ravel(), _rows(motor, _port(kernel, "M")), atol=1e-12)
            np.testing.assert_allclose(out["P"].ravel(), _rows(K.end_point(motor), _port(kernel, "P")),
                                       atol=1e-12)
            np.testing.assert_allclose(out["L"].ravel(), _rows(motor.sandwich(tool), _port(kernel, "L")),
                                       atol=1e-12)
            d_motor, d_point, d_line = _chain_fd(chain.joints, qc, lambda m: m, K.end_point,
                                                 lambda m: m.sandwich(tool))
            spatial = np.array([(MultiVector(ALG, c) * ~motor * -2).coeffs for c in d_motor.T]).T
            body = np.array([(~motor * MultiVector(ALG, c) * -2).coeffs for c in d_motor.T]).T
            expected = {"J_A": d_motor, "J_S": spatial, "J_b": body, "J_P": d_point, "J_L": d_line}
            for key, dense in expected.items():
                np.testing.assert_allclose(out[key], _blade_rows(dense, _port(kernel, key)), atol=2e-7,
                                           err_msg=f"{chain.name} {key}")
            fk = _call(_kernels(name)[f"{chain.name}_fk"], qc)
            np.testing.assert_allclose(fk["M"], out["M"], atol=1e-15)
            np.testing.assert_allclose(fk["P"], out["P"], atol=1e-15)


@pytest.mark.slow
def test_three_panda_circle_kernel_cost_does_not_regress():
    """The chain rule through the end positions (AD on the task-space formulas only), the product rule
    over V_T V_R V_D (each factor differentiated alone) and guards that add constants instead of
    selecting values keep the 21-DOF circle's V_Sc + J_G,Sc kernel at 3 369 flops, 287 selects and
    18 sin/cos (AD of the whole similarity: 6 337 flops and 2 022 selects; AD through the kinematics
    too: ~45 000 flops)."""
    ops = _kernels("three_pandas_circle")["similarity"].op_count
    assert ops.flops <= 3_400
    assert ops.calls["if_else_zero"] <= 300
    assert ops.calls["sin"] == ops.calls["cos"] == 18


ONE_SYSTEM_PER_KIND = {SYSTEMS[name].kind: name for name in sorted(SYSTEMS)}


@pytest.mark.parametrize("name", tiered(sorted(ONE_SYSTEM_PER_KIND.values()),
                                        {"panda_point", "two_pandas_point_pair"}))
def test_task_space_derivatives_equal_plain_ad_of_the_whole_construction(name):
    """G = −2 V~ ∂V/∂p by the product rule over the similarity's factors, ∂V = −½ V G, and the local
    derivatives of the logarithms equal CasADi AD straight through V_S(X_u, X_c(p)) and the logs, at
    random end positions (1e-10 relative)."""
    import casadi as ca

    from gagen.apps.cooperative.catalogue import _Graph, _task_space

    system = SYSTEMS[name]
    graph = _Graph(system)
    p = ca.SX.sym("p", 3 * len(system.chains))
    vsd = ca.SX.sym("v", len(SIMILARITY))
    task = _task_space(graph, p, vsd)
    ours = ca.Function("ours", [p, vsd], [task[k] for k in ("dV_Sc", "dG", "dlog_V", "de")])
    plain = {k: ca.jacobian(task[k], p) for k in ("V_Sc", "log_V", "e")}
    reverse = graph.multivector(task["V_Sc"], SIMILARITY).reverse()
    g_plain = graph.matrix([(reverse * graph.multivector(plain["V_Sc"][:, k], SIMILARITY)) * -2
                            for k in range(p.numel())], SIMILARITY_GENERATOR)
    reference = ca.Function("plain", [p, vsd], [plain["V_Sc"], g_plain, plain["log_V"], plain["e"]])
    rng = np.random.default_rng(7)
    for _ in range(10):
        q = _configurations(name, 1, seed=int(rng.integers(1 << 30)))[0]
        euclid = [ALG.blade(b) for b in ("e1", "e2", "e3")]
        positions = np.concatenate([_chain_point(name, i, tuple(q[idx])).coeffs[euclid]
                                    for i, idx in enumerate(system.chain_indices())])
        desired = _desired(int(rng.integers(1 << 30))).coeffs[[ALG.blade(b) for b in SIMILARITY]]
        for key, a, b in zip(("dV_Sc", "G", "dlog_V", "de"), ours(positions, desired),
                             reference(positions, desired), strict=True):
            a, b = np.array(a), np.array(b)
            assert np.max(np.abs(a - b)) <= 1e-10 * max(1.0, np.max(np.abs(b))), f"{name} {key}"
