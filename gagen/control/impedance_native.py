"""The similarity impedance step [COOP Eq. 49-52] in C++, called from Python: ``NativeImpedance``.

``NativeImpedance(controller)`` evaluates the law of an ``ImpedanceController`` (its target V_Sd, gains,
q_rest and rank; the posture term included) in ``impedance_native.cpp``: the module's generated C
kernels (``similarity``, ``task``, ``similarity_rate``) called through their addresses, Pinocchio's
CRBA / RNEA / gravity on a copy of the controller's ``SystemDynamics.model``, and the task-space
algebra of ``gagen.dynamics.task_space`` in Eigen, with no Python in between. The source is compiled
once per content into gagen's cache (``gagen.control.native_build``; minutes the first time) and loaded
with ctypes. Any cooperative system whose dynamics ``SystemDynamics`` builds is served: any number of
chains of any DOF, each from its URDF and base placement, continuous joints included.

Inputs are checked before the C++ runs (shapes here; finiteness there, before any kernel reads them),
and a degenerate primitive or non-finite torque raises ``DynamicsError`` as the Python step does.
Each thread gets its own C++ workspace (Pinocchio's Data and the scratch), made on its first call.
"""

from __future__ import annotations

import ctypes
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.control.impedance import ImpedanceController
from gagen.dynamics.rigid_body import DynamicsError
from gagen.dynamics.task_space import RCOND

Array = NDArray[np.float64]
SOURCE = Path(__file__).with_name("impedance_native.cpp")
ROWS = 7  # the similarity bivector rows
JOINT_DOUBLES = 29  # per joint of the model description (see build_model in the C++)
# Pinocchio's joint types with one velocity, by the C++ side's codes (joint_of)
JOINT_TYPES = {"JointModelRX": 0, "JointModelRY": 1, "JointModelRZ": 2, "JointModelRevoluteUnaligned": 3,
               "JointModelRUBX": 4, "JointModelRUBY": 5, "JointModelRUBZ": 6,
               "JointModelRevoluteUnboundedUnaligned": 7, "JointModelPX": 8, "JointModelPY": 9,
               "JointModelPZ": 10, "JointModelPrismaticUnaligned": 11}
_UNALIGNED = {3, 7, 11}
_STATUS = {1: "q", 2: "qd"}  # the C++ step's codes for a non-finite input

_LOCK = threading.Lock()
_LIBRARY: dict[str, ctypes.CDLL] = {}


def native_library() -> ctypes.CDLL:
    """``impedance_native.cpp`` compiled against the installed Pinocchio (once per content) and loaded;
    a CompileError when no C++ compiler or header is found."""
    with _LOCK:
        if "library" not in _LIBRARY:
            _LIBRARY["library"] = _load()
        return _LIBRARY["library"]


def _load() -> ctypes.CDLL:
    import pinocchio

    from gagen.control.native_build import EIGEN_ABI, cmeel_prefix, compile_cached

    prefix = cmeel_prefix()
    include = prefix / "include"
    # -O3 -march=native as the Pinocchio benchmarks (benchmarks/programs.py); the MPL limits are those
    # Pinocchio's joint variant needs
    flags = ["-std=c++17", "-O3", "-march=native", "-DNDEBUG", "-fPIC", "-shared", "-w",
             "-DBOOST_MPL_LIMIT_LIST_SIZE=30", "-DBOOST_MPL_LIMIT_VECTOR_SIZE=30",
             "-DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS", *EIGEN_ABI, f"-I{include}", f"-I{include / 'eigen3'}"]
    libraries = [f"-L{prefix / 'lib'}", "-lpinocchio_default", f"-Wl,-rpath,{prefix / 'lib'}"]
    _, path = compile_cached(SOURCE, "impedance", flags, libraries, pinocchio.__version__, extension=False)
    library = ctypes.CDLL(str(path))
    pointer, integer, real = ctypes.c_void_p, ctypes.c_int, ctypes.c_double
    library.gagen_impedance_create.argtypes = [integer, pointer, pointer, pointer, integer, pointer, pointer,
                                               pointer, pointer, integer, real, ctypes.c_char_p,
                                               ctypes.c_long]
    library.gagen_impedance_create.restype = pointer
    library.gagen_impedance_clone.argtypes, library.gagen_impedance_clone.restype = [pointer], pointer
    library.gagen_impedance_configure.argtypes = [pointer, pointer, pointer, pointer, real, real, integer,
                                                  pointer]
    library.gagen_impedance_configure.restype = None
    library.gagen_impedance_step.argtypes, library.gagen_impedance_step.restype = [pointer, pointer], integer
    library.gagen_impedance_destroy.argtypes, library.gagen_impedance_destroy.restype = [pointer], None
    return library


def _address(array: NDArray[Any]) -> int:
    address: int = array.__array_interface__["data"][0]
    return address


def _model_description(model: Any) -> tuple[NDArray[np.intc], Array, Array]:
    """(parent, type code) per joint after the universe, the numbers per joint (placement, body
    inertia, axis, armature: ``JOINT_DOUBLES``) and the gravity (linear, angular) of a Pinocchio model."""
    count = model.njoints - 1
    ints = np.zeros((count, 2), dtype=np.intc)
    doubles = np.zeros((count, JOINT_DOUBLES))
    for j in range(1, model.njoints):
        joint = model.joints[j]
        code = JOINT_TYPES.get(joint.shortname())
        if code is None or joint.nv != 1:
            raise DynamicsError(f"joint {model.names[j]!r} is a {joint.shortname()}: the native impedance "
                                f"step supports revolute, continuous and prismatic joints")
        placement, inertia = model.jointPlacements[j], model.inertias[j]
        row = doubles[j - 1]
        row[0:9] = np.asarray(placement.rotation).ravel()  # row-major
        row[9:12] = placement.translation
        row[12], row[13:16] = inertia.mass, inertia.lever
        row[16:25] = np.asarray(inertia.inertia).ravel()
        if code in _UNALIGNED:
            row[25:28] = joint.extract().axis
        row[28] = model.armature[model.idx_vs[j]]
        ints[j - 1] = model.parents[j], code
    gravity = np.concatenate([model.gravity.linear, model.gravity.angular]).astype(float)
    return ints, doubles, gravity


def _check_kernels(c: Any, dof: int) -> tuple[int, int, int]:
    """The addresses of the module's similarity, task and similarity_rate kernels, after checking their
    shapes: the C++ calls them raw, so a kernel of another system would read or write out of bounds."""
    expected = {"similarity": ([(dof, 1)], [(12, 1), (1, 1), (ROWS, dof)]),
                "task": ([(dof, 1), (12, 1)], [(ROWS, 1), (ROWS, dof)]),
                "similarity_rate": ([(dof, 1), (dof, 1)], [(ROWS, 1), (ROWS, 1)])}
    addresses = []
    for name, (inputs, outputs) in expected.items():
        kernel = getattr(c, name, None)
        address = int(getattr(kernel, "address", 0) or 0)
        if not address:
            raise ValueError(f"{name}: the native impedance step needs the compiled kernels of a generated "
                             f"module (module.c.{name})")
        shapes = ([tuple(s) for s in getattr(kernel, "_in_shapes", ())],
                  [tuple(s) for s in getattr(kernel, "_out_shapes", ())])
        if shapes != (inputs, outputs):
            raise ValueError(f"{name}: the kernel takes {shapes[0]} and gives {shapes[1]}; a system of {dof} "
                             f"joints needs {inputs} -> {outputs}")
        addresses.append(address)
    return addresses[0], addresses[1], addresses[2]


def _vector(name: str, value: ArrayLike, size: int) -> Array:
    array = np.array(value, dtype=np.float64).reshape(-1)
    if array.size != size:
        raise ValueError(f"{name}: expected {size} values, got {array.size}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name}: expected finite values")
    return array


@dataclass(frozen=True, slots=True)
class NativeStep:
    """One native controller evaluation: τ, B_S,e and V_S (as ``Step``, without the task space)."""

    tau: Array
    error: Array
    twist: Array


class _Workspace:
    """One thread's C++ handle and the io buffer it reads and writes: q, q̇ | τ, B_S,e, V_S, conditioning."""

    def __init__(self, library: ctypes.CDLL, handle: int, dof: int) -> None:
        self.library, self.handle = library, handle
        self.io = np.zeros(3 * dof + 2 * ROWS + 1)
        self.address = _address(self.io)
        n = dof
        self.q, self.qd, self.tau = self.io[:n], self.io[n:2 * n], self.io[2 * n:3 * n]
        self.error, self.twist = self.io[3 * n:3 * n + ROWS], self.io[3 * n + ROWS:3 * n + 2 * ROWS]
        self.version = -1  # of the parameters configured
        self.busy = False

    def __del__(self) -> None:
        if getattr(self, "handle", None):
            self.library.gagen_impedance_destroy(self.handle)
            self.handle = 0


class NativeImpedance:
    """τ(q, q̇) of an ``ImpedanceController`` (see the module docstring): ``torque(q, q̇)`` gives τ;
    calling it gives a ``NativeStep`` (τ, B_S,e, V_S), so ``simulate`` runs it as it runs the controller.
    The target V_Sd, gains and q_rest are the controller's at construction; set ``target`` to move V_Sd."""

    def __init__(self, controller: ImpedanceController, rcond: float = RCOND) -> None:
        dynamics = controller.dynamics
        self.dynamics, self.gains, self.rank = dynamics, controller.gains, int(controller.rank)
        self.K, self.D = np.array(controller.K, dtype=float), np.array(controller.D, dtype=float)
        dof = self.dof = dynamics.dof
        self._shape = (dof,)
        if not 0 < self.rank <= ROWS:
            raise ValueError(f"rank must be between 1 and {ROWS}, got {self.rank}")
        self._kernels = controller.c  # holds the module's library, whose functions the C++ calls
        addresses = _check_kernels(controller.c, dof)
        self._target = _vector("target (V_Sd)", controller.target, 12)
        self.q_rest = _vector("q_rest", controller.q_rest, dof)
        model = dynamics.model
        ints, doubles, gravity = _model_description(model)
        joint_of = {model.idx_vs[j]: j for j in range(1, model.njoints)}
        ids = [joint_of[int(v)] for v in dynamics.order]
        self._joints = np.array([(model.idx_vs[j], model.idx_qs[j], model.nqs[j]) for j in ids],
                                dtype=np.intc)
        library = self._library = native_library()
        message = ctypes.create_string_buffer(512)
        handle = library.gagen_impedance_create(
            ints.shape[0], _address(ints), _address(doubles), _address(gravity), dof, _address(self._joints),
            *addresses, self.rank, float(rcond), message, len(message))
        if not handle:
            raise DynamicsError(f"the native impedance step: {message.value.decode(errors='replace')}")
        self._step = library.gagen_impedance_step
        self._prototype = _Workspace(library, handle, dof)  # never stepped: the threads' clones' source
        self._version = 0
        self._local = threading.local()

    @property
    def target(self) -> Array:
        """V_Sd (12); setting it takes effect at every thread's next step."""
        return self._target.copy()

    @target.setter
    def target(self, value: ArrayLike) -> None:
        self._target = _vector("target (V_Sd)", value, 12)
        self._version += 1

    def _configure(self, workspace: _Workspace) -> None:
        version = self._version  # (read first: a concurrent change is picked up at the next step)
        gains = self.gains
        self._library.gagen_impedance_configure(
            workspace.handle, _address(self._target), _address(self.K), _address(self.D),
            float(gains.posture_stiffness), float(gains.posture_damping), int(gains.gravity_nullspace),
            _address(self.q_rest))
        workspace.version = version

    def _new_workspace(self) -> _Workspace:
        handle = self._library.gagen_impedance_clone(self._prototype.handle)
        if not handle:
            raise MemoryError("the native impedance step could not make a workspace")
        return _Workspace(self._library, handle, self.dof)

    def _run(self, q: ArrayLike, qd: ArrayLike) -> _Workspace:
        """The step at (q, q̇) in this thread's workspace (a fresh one for a reentrant call), left busy."""
        try:
            workspace: _Workspace = self._local.workspace
        except AttributeError:
            workspace = self._local.workspace = self._new_workspace()
        if workspace.busy:
            workspace = self._new_workspace()
        if type(q) is not np.ndarray or q.shape != self._shape:
            q = self._checked("q", q)
        if type(qd) is not np.ndarray or qd.shape != self._shape:
            qd = self._checked("qd", qd)
        workspace.busy = True
        try:
            workspace.q[...] = q
            workspace.qd[...] = qd
            if workspace.version != self._version:
                self._configure(workspace)
            status = self._step(workspace.handle, workspace.address)
            if status:
                self._raise(status, workspace)
        except BaseException:
            workspace.busy = False
            raise
        return workspace

    def _checked(self, name: str, value: ArrayLike) -> Array:
        array = np.asarray(value, dtype=np.float64)
        if array.shape != self._shape:
            raise ValueError(f"{name}: expected shape {self._shape} (the system's joints), got {array.shape}")
        return array

    def _raise(self, status: int, workspace: _Workspace) -> None:
        if status in _STATUS:
            raise ValueError(f"{_STATUS[status]}: expected finite values")
        if status == 3:
            raise DynamicsError(f"the cooperative primitive is degenerate at q (conditioning "
                                f"{workspace.io[-1]:.3g})")
        raise DynamicsError("the impedance torque is not finite at this state (a degenerate configuration)")

    def torque(self, q: ArrayLike, qd: ArrayLike) -> Array:
        """τ at (q, q̇), in the system's joint order."""
        workspace = self._run(q, qd)
        tau = workspace.tau.copy()
        workspace.busy = False
        return tau

    def __call__(self, q: ArrayLike, qd: ArrayLike) -> NativeStep:
        workspace = self._run(q, qd)
        step = NativeStep(workspace.tau.copy(), workspace.error.copy(), workspace.twist.copy())
        workspace.busy = False
        return step
