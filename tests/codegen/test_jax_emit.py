"""Kernels as jax.numpy functions emitted from the flat graph (gagen.codegen.backends.jax.printer)
against the C kernels of the bundled modules (built on first use): values (1e-12 relative), a vmapped
batch against the C batch, and jax.jacfwd of a JAX kernel against the generated Jacobian kernel."""

from __future__ import annotations

import numpy as np
import pytest

from gagen.apps.cooperative.bundled import system_module

jax = pytest.importorskip("jax")
jnp = pytest.importorskip("jax.numpy")

from gagen.codegen.backends.jax.printer import jax_kernel, jax_source  # noqa: E402 -- after the importorskip

RTOL = 1e-12


def _inputs(module, name: str, rng: np.random.Generator) -> list[np.ndarray]:
    entry = next(k for k in module.manifest["kernels"] if k["name"] == name)
    out = []
    for port in entry["inputs"]:
        size = len(port["rows"]) * port.get("cols", 1)
        if port["name"] == "V_Sd":  # a unit similarity: the module's own V_Sc somewhere else
            q = rng.uniform(-1, 1, module.manifest["dof"])
            out.append(np.asarray(module.c.similarity(q)[0]))
        else:
            out.append(rng.uniform(-1.2, 1.2, size))
    return out


def _close(jax_outputs, c_outputs, what: str) -> None:
    c_outputs = c_outputs if isinstance(c_outputs, tuple) else (c_outputs,)
    assert len(jax_outputs) == len(c_outputs), what
    for j, c in zip(jax_outputs, c_outputs, strict=True):
        j = np.asarray(j).reshape(np.shape(c))
        assert np.abs(j - c).max() <= RTOL * max(1.0, float(np.abs(c).max())), what


def test_every_kernel_of_panda_point():
    module = system_module("panda_point")
    rng = np.random.default_rng(0)
    for entry in module.manifest["kernels"]:
        name = entry["name"]
        f = jax_kernel(module, name)
        for _ in range(3):
            inputs = _inputs(module, name, rng)
            _close(f(*inputs), getattr(module.c, name)(*inputs), name)


@pytest.mark.compiling
@pytest.mark.slow
# every kernel of the representative modules (conftest.BACKEND_MODULES) runs as JAX against C in
# test_jax_backend.py; here the task-space kernels of the two largest graphs outside that set
@pytest.mark.parametrize("system", ["four_pandas_circle", "two_g1_sphere"])
def test_system_kernels_of_the_largest_bundled_systems(system):
    """The task-space kernels (the largest graphs: a fitted circle of 28 joints, a sphere of two
    humanoids), eagerly."""
    module = system_module(system)
    rng = np.random.default_rng(1)
    for name in ("similarity", "task", "similarity_rate"):
        inputs = _inputs(module, name, rng)
        _close(jax_kernel(module, name)(*inputs), getattr(module.c, name)(*inputs), f"{system} {name}")


def test_jit_vmap_and_jacfwd_on_panda_point():
    """jit(vmap(fk)) over a batch = the C batch; jacfwd of the JAX FK's end point = the generated point
    Jacobian J_P of ``arm0_jacobians``."""
    module = system_module("panda_point")
    rng = np.random.default_rng(2)
    Q = rng.uniform(-1.5, 1.5, (64, 7))
    fk = jax_kernel(module, "arm0_fk")
    motors, points = jax.jit(jax.vmap(fk))(jnp.asarray(Q))
    c_motors, c_points = module.c.arm0_fk.batch(Q)
    assert np.abs(np.asarray(motors).reshape(c_motors.shape) - c_motors).max() <= 1e-12
    assert np.abs(np.asarray(points).reshape(c_points.shape) - c_points).max() <= 1e-12
    names = module.c.arm0_jacobians.outputs
    for q in Q[:5]:
        jacobian = np.asarray(jax.jacfwd(lambda x: fk(x)[1][:, 0])(jnp.asarray(q)))
        generated = np.asarray(module.c.arm0_jacobians(q)[names.index("J_P")]).reshape(jacobian.shape)
        assert np.abs(jacobian - generated).max() <= 1e-12 * max(1.0, float(np.abs(generated).max()))


@pytest.mark.slow
def test_jacfwd_of_the_task_error_is_the_generated_j_be():
    """Three Pandas: jax.jacfwd of the JAX ``task`` kernel's e equals the generated J_Be (which is built by
    the chain rule through the end points, not by AD of e)."""
    module = system_module("three_pandas_circle")
    rng = np.random.default_rng(3)
    q, V_Sd = _inputs(module, "task", rng)
    task = jax_kernel(module, "task")
    jacobian = np.asarray(jax.jacfwd(lambda x: task(x, jnp.asarray(V_Sd))[0][:, 0])(jnp.asarray(q)))
    _, J_Be = module.c.task(q, V_Sd)
    assert np.abs(jacobian - J_Be).max() <= 1e-10 * float(np.abs(J_Be).max())


def test_unsupported_operations_are_named():
    import casadi as ca

    from gagen.codegen.backends.c.printer import UnsupportedOperation

    x = ca.SX.sym("x")
    with pytest.raises(UnsupportedOperation, match=r"no jax\.numpy form for CasADi operation ERF"):
        jax_source(ca.Function("f", [x], [ca.erf(x)]))


@pytest.mark.parametrize("name", ["f(): pass\nimport os\ndef g", "class", "a b", "", "1x"])
def test_a_hostile_name_never_reaches_the_executed_source(name):
    import casadi as ca

    x = ca.SX.sym("x")
    with pytest.raises(ValueError, match="must be a Python identifier"):
        jax_source(ca.Function("f", [x], [x * 2]), name)
