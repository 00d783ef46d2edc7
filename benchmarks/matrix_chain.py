"""The 4×4 homogeneous-matrix chain baseline for Panda FK and its 6×7 Jacobian, in CasADi SX.

The pose is the plain product T = Π_k T_origin,k · T_joint,k(q_k) of 4×4 matrices, over gagen's joint list
(``gagen.robots.urdf.load_chain``). Fixed rotations are exact: rpy angles within 1e-9 of a multiple of π/2
get exact 0/±1 sines and cosines, so CasADi folds the zeros and ±1 away (as gagen's own constants are). The
Jacobian is the analytic one from the joint frames (z_i: joint axis in the world, p_i: joint origin, p_e:
tip), in one of two conventions:

- ``spatial``   column i = [p_i × z_i; z_i]: Pinocchio's WORLD frame Jacobian, the same quantity as gagen's
  J_S (the joint screw axes in the world frame);
- ``geometric`` column i = [z_i × (p_e − p_i); z_i]: the textbook geometric Jacobian (tip velocity), which is
  Pinocchio's LOCAL_WORLD_ALIGNED frame Jacobian.

Both are checked against Pinocchio (position, rotation and Jacobian to 1e-10). Op counts come from the
CasADi instructions after ``casadi.cse`` on all outputs (``gagen.symbolic.flatten.casadi_op_count``:
mul/sq, add/sub/twice, neg, div/inv are flops; sin/cos are counted apart).

    python benchmarks/matrix_chain.py            # op counts and the Pinocchio check
    python benchmarks/matrix_chain.py --emit DIR # also write CasADi's C code (matrix_chain.c/.h) to DIR

Generated C functions (CasADi calling convention, see matrix_chain_bench.c):
  mc_fk(q) -> R (3×3, column-major), p (3)
  mc_fk_jacobian(q) -> R, p, J (6×7, column-major, rows [v; ω], spatial = Pinocchio WORLD)
  mc_fk_jacobian_geo(q) -> R, p, J (geometric = Pinocchio LOCAL_WORLD_ALIGNED)
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
URDF = ROOT / "robots" / "panda" / "panda.urdf"
BASE, TIP = "panda_link0", "panda_link8"
SNAP = 1e-9


def _cos_sin(angle: float) -> tuple[float, float]:
    """cos and sin, exact (0, ±1) when the angle is within SNAP of a multiple of π/2."""
    k = round(angle / (math.pi / 2))
    if abs(angle - k * math.pi / 2) < SNAP:
        return ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[k % 4]
    return math.cos(angle), math.sin(angle)


def rpy_matrix(rpy) -> list[list[float]]:
    """URDF R = Rz(yaw) Ry(pitch) Rx(roll), with exact entries for multiples of π/2."""
    (cr, sr), (cp, sp), (cy, sy) = (_cos_sin(a) for a in rpy)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return (rz @ ry @ rx).tolist()  # products of exact 0/±1 stay exact


def _homogeneous(rot, trans) -> ca.SX:
    t = ca.SX.eye(4)
    for i in range(3):
        for j in range(3):
            t[i, j] = rot[i][j]
        t[i, 3] = trans[i]
    return t


def _combine(terms) -> ca.SX | float:
    """Σ coefficient·value over (coefficient, value) pairs, skipping zeros and multiplying by no ±1."""
    out = 0.0
    for k, v in terms:
        if k == 0:
            continue
        term = v if k == 1 else -v if k == -1 else k * v
        out = term if isinstance(out, float) and out == 0 else out + term
    return out


def _joint_matrix(kind: str, axis, q) -> ca.SX:
    """T_joint(q): rotation about / translation along the unit axis a (Rodrigues,
    R_ij = a_i a_j + (δ_ij − a_i a_j) cos q − ε_ijk a_k sin q, constant coefficients folded here)."""
    a = [float(x) for x in axis]
    if kind == "prismatic":
        return _homogeneous(np.eye(3).tolist(), [_combine([(a[i], q)]) for i in range(3)])
    c, s = ca.cos(q), ca.sin(q)
    eps = np.zeros((3, 3, 3))
    eps[0, 1, 2] = eps[1, 2, 0] = eps[2, 0, 1] = 1
    eps[0, 2, 1] = eps[2, 1, 0] = eps[1, 0, 2] = -1
    rot = [[_combine([(a[i] * a[j], ca.SX(1)), ((i == j) - a[i] * a[j], c),
                      (-sum(eps[i, j, k] * a[k] for k in range(3)), s)]) for j in range(3)] for i in range(3)]
    return _homogeneous(rot, [0, 0, 0])


@dataclass
class Chain:
    q: ca.SX
    T: ca.SX  # 4×4 pose of the tip
    frames: list[tuple[str, ca.SX, ca.SX]]  # per moving joint: kind, z_i (world axis), p_i (world origin)


def build_chain(urdf=URDF, base=BASE, tip=TIP) -> Chain:
    from gagen.robots.urdf import load_chain

    joints = load_chain(urdf, base, tip)
    dof = sum(j.kind != "fixed" for j in joints)
    q = ca.SX.sym("q", dof)
    T = ca.SX.eye(4)
    frames = []
    k = 0
    for j in joints:
        T = ca.mtimes(T, _homogeneous(rpy_matrix(j.rpy), j.xyz))
        if j.kind == "fixed":
            continue
        z = ca.mtimes(T[:3, :3], ca.DM(j.axis))
        frames.append((j.kind, z, T[:3, 3]))
        T = ca.mtimes(T, _joint_matrix(j.kind, j.axis, q[k]))
        k += 1
    return Chain(q, T, frames)


def jacobian(chain: Chain, convention: str) -> ca.SX:
    """6×n analytic Jacobian, rows [v; ω]."""
    p_e = chain.T[:3, 3]
    cols = []
    for kind, z, p in chain.frames:
        if kind == "prismatic":
            cols.append(ca.vertcat(z, ca.SX.zeros(3)))
        elif convention == "spatial":
            cols.append(ca.vertcat(ca.cross(p, z), z))
        elif convention == "geometric":
            cols.append(ca.vertcat(ca.cross(z, p_e - p), z))
        else:
            raise ValueError(convention)
    return ca.horzcat(*cols)


def functions(chain: Chain | None = None) -> dict[str, ca.Function]:
    """mc_fk, mc_fk_jacobian (spatial) and mc_fk_jacobian_geo, each after cse on all its outputs."""
    chain = chain or build_chain()
    R, p = chain.T[:3, :3], chain.T[:3, 3]

    def make(name, outs, names):
        sizes = [o.numel() for o in outs]
        joined = ca.cse(ca.vertcat(*[ca.vec(o) for o in outs]))
        parts, at = [], 0
        for o, n in zip(outs, sizes, strict=True):
            parts.append(ca.reshape(joined[at:at + n], o.size1(), o.size2()))
            at += n
        return ca.Function(name, [chain.q], parts, ["q"], names)

    return {"mc_fk": make("mc_fk", [R, p], ["R", "p"]),
            "mc_fk_jacobian": make("mc_fk_jacobian", [R, p, jacobian(chain, "spatial")], ["R", "p", "J"]),
            "mc_fk_jacobian_geo": make("mc_fk_jacobian_geo", [R, p, jacobian(chain, "geometric")],
                                       ["R", "p", "J"])}


def op_counts(fns: dict[str, ca.Function]) -> dict:
    from gagen.symbolic.flatten import casadi_op_count

    return {name: casadi_op_count(f) for name, f in fns.items()}


def check_against_pinocchio(fns: dict[str, ca.Function], n: int = 50, seed: int = 7,
                            atol: float = 1e-10) -> float:
    """Largest deviation from Pinocchio over n random configurations; raises if above atol."""
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(URDF))
    data = model.createData()
    frame = model.getFrameId(TIP)
    rng = np.random.default_rng(seed)
    worst = 0.0
    for _ in range(n):
        q = rng.uniform(model.lowerPositionLimit, model.upperPositionLimit)
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacement(model, data, frame)
        pose = data.oMf[frame]
        world = pin.computeFrameJacobian(model, data, q, frame, pin.ReferenceFrame.WORLD)
        aligned = pin.computeFrameJacobian(model, data, q, frame, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        R, p = (np.asarray(x) for x in fns["mc_fk"](q))
        _, _, J = (np.asarray(x) for x in fns["mc_fk_jacobian"](q))
        _, _, Jg = (np.asarray(x) for x in fns["mc_fk_jacobian_geo"](q))
        for ours, theirs in ((R, pose.rotation), (p.ravel(), pose.translation), (J, world), (Jg, aligned)):
            worst = max(worst, float(np.max(np.abs(ours - theirs))))
    if worst > atol:
        raise AssertionError(f"matrix chain differs from Pinocchio by {worst:.3g} (> {atol})")
    return worst


def emit_c(fns: dict[str, ca.Function], outdir: Path) -> tuple[Path, Path]:
    """CasADi's own C code for the three functions: outdir/matrix_chain.c and .h."""
    outdir.mkdir(parents=True, exist_ok=True)
    gen = ca.CodeGenerator("matrix_chain.c", {"with_header": True, "casadi_real": "double",
                                              "casadi_int": "long long int"})
    for f in fns.values():
        gen.add(f)
    gen.generate(str(outdir) + "/")
    return outdir / "matrix_chain.c", outdir / "matrix_chain.h"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--emit", type=Path, help="write CasADi's C code to this folder")
    args = ap.parse_args(argv)
    fns = functions()
    for name, ops in op_counts(fns).items():
        print(f"{name:20s} {ops}")
    print(f"max |matrix chain − Pinocchio| = {check_against_pinocchio(fns):.3g}")
    if args.emit:
        for path in emit_c(fns, args.emit):
            print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
