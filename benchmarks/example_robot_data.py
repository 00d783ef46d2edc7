"""Every URDF of ``example-robot-data`` through gagen, against Pinocchio: which chains build, which agree.

    .venv/bin/python benchmarks/example_robot_data.py [--limit N] [--only NAME ...] [--snap]

For each URDF the package ships (the PyPI wheel, a cmeel prefix of URDFs and meshes), the chains tried
are those from the URDF's root link (below a leading floating joint, if any) to each leaf link, one per
distinct sequence of moving joints (the leaves behind fixed joints only, such as sensor frames, add
nothing). Each chain is written as a one-chain spec (``primitive: point``, ``snap: false`` unless
``--snap``) into a temporary folder, loaded by ``gagen.robots.spec.load_system`` and its
``<chain>_fk_jacobian`` kernel traced from the cooperative catalogue (pure CasADi, nothing compiled).
At random configurations (every joint of the robot random, continuous ones too), its end point, the
rotation of its motor and its spatial Jacobian are compared with Pinocchio's on the same file: the
tip's placement relative to the chain's base link, and the chain's columns of the tip's world Jacobian
less the base link's (a chain may go up the tree from its base link, then down), moved to the base
frame (mimic followers folded into their leaders with their multipliers).

Prints a markdown table, one row per URDF: chains tried, built, agreeing (FK and Jacobian ≤ 1e-12),
the largest differences, and why any chain or file was refused. ``tests/robots`` holds five of these
robots to the same bound; the latest table is in ``docs/robots.md``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

TOLERANCE = 1e-12


def urdf_files() -> list[Path]:
    """Every ``.urdf`` file the installed ``example-robot-data`` ships, sorted by name (empty if the
    package is not installed)."""
    try:
        dist = metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        return []
    files = [Path(str(dist.locate_file(f))) for f in dist.files or () if str(f).endswith(".urdf")]
    return sorted((f for f in files if f.is_file()), key=lambda f: (f.name, str(f)))


def find_urdf(name: str) -> Path | None:
    """The shipped URDF called ``name`` (e.g. ``ur10_robot.urdf``), or None."""
    return next((f for f in urdf_files() if f.name == name), None)


@dataclass
class Outcome:
    """What one chain gave: refused (``reason``), or built with its largest differences to Pinocchio."""

    base: str
    tip: str
    dof: int = 0
    reason: str = ""
    fk: float = float("nan")
    jacobian: float = float("nan")
    continuous: int = 0

    @property
    def built(self) -> bool:
        return not self.reason

    @property
    def agrees(self) -> bool:
        return self.built and self.fk <= TOLERANCE and self.jacobian <= TOLERANCE


@dataclass
class Report:
    urdf: Path
    outcomes: list[Outcome] = field(default_factory=list)
    refused: str = ""  # why no chain was tried (the file itself)


def _tree(urdf: Path) -> tuple[str, dict[str, list[tuple[str, str, str]]]]:
    """The root link and, per link, its child joints (name, type, child link), from the XML."""
    from lxml import etree

    root = etree.parse(str(urdf), etree.XMLParser(resolve_entities=False, no_network=True)).getroot()
    children: dict[str, list[tuple[str, str, str]]] = {}
    child_links = set()
    for joint in root.findall("joint"):
        parent, child = joint.find("parent").get("link"), joint.find("child").get("link")
        children.setdefault(parent, []).append((joint.get("name"), joint.get("type"), child))
        child_links.add(child)
    links = [link.get("name") for link in root.findall("link")]
    roots = [link for link in links if link not in child_links]
    if not links:
        raise ValueError("no links (an empty <robot>)")
    if len(roots) != 1:
        raise ValueError(f"{len(roots)} root links")
    return roots[0], children


def chains_of(urdf: Path) -> list[tuple[str, str]]:
    """(base link, tip link) of each chain tried: see the module docstring."""
    root, children = _tree(urdf)
    while len(children.get(root, [])) == 1 and children[root][0][1] in ("floating", "planar"):
        root = children[root][0][2]  # a world link with a floating joint: start below it
    chains: dict[tuple[str, ...], tuple[str, str]] = {}

    def walk(link: str, moving: tuple[str, ...]) -> None:
        below = children.get(link, [])
        if not below:
            if moving and moving not in chains:
                chains[moving] = (root, link)
            return
        for name, kind, child in below:
            walk(child, moving + ((name,) if kind != "fixed" else ()))

    walk(root, ())
    return list(chains.values())


def _spec(folder: Path, urdf: Path, base: str, tip: str, snap: bool) -> Path:
    spec = folder / "chain.yaml"
    spec.write_text(f"name: erd_chain\nprimitive: point\nsnap: {str(snap).lower()}\nchains:\n"
                    f"  - name: arm\n    urdf: {urdf.resolve()}\n"
                    f"    base_link: {base}\n    tip_link: {tip}\n")
    return spec


def chain_kernel(urdf: Path, base: str, tip: str, folder: Path, snap: bool = False) -> tuple[Any, Any]:
    """(the loaded chain, its traced ``arm_fk_jacobian`` Kernel) from a one-chain spec in ``folder``."""
    from gagen.apps.cooperative.catalogue import chain_kernel_functions
    from gagen.robots.spec import load_system

    system, _ = load_system(_spec(folder, urdf, base, tip, snap))
    return system.chains[0], chain_kernel_functions(system)["arm_fk_jacobian"].trace()


def random_configuration(pin: Any, model: Any, rng: np.random.Generator) -> np.ndarray:
    """Pinocchio's q with every 1-DOF joint random (within its limits where finite, else ±π), continuous
    joints as (cos, sin) of a random angle, a free-flyer root at a random placement."""
    q = pin.neutral(model)
    for j in range(1, model.njoints):
        joint, i = model.joints[j], model.joints[j].idx_q
        if joint.nq == 1:
            lo, hi = model.lowerPositionLimit[i], model.upperPositionLimit[i]
            finite = np.isfinite(lo) and np.isfinite(hi) and lo < hi and hi - lo < 1e3
            q[i] = rng.uniform(lo, hi) if finite else rng.uniform(-np.pi, np.pi)
        elif joint.nq == 2 and joint.nv == 1:
            a = rng.uniform(-np.pi, np.pi)
            q[i:i + 2] = np.cos(a), np.sin(a)
        elif joint.nq == 7:  # free flyer
            q[i:i + 3] = rng.uniform(-1, 1, 3)
            quaternion = rng.normal(size=4)
            q[i + 3:i + 7] = quaternion / np.linalg.norm(quaternion)
    return q


def _angle(model: Any, q: np.ndarray, joint_id: int) -> float:
    joint = model.joints[joint_id]
    i = joint.idx_q
    return float(q[i]) if joint.nq == 1 else float(np.arctan2(q[i + 1], q[i]))


def compare(chain: Any, kernel: Any, urdf: Path, base: str, tip: str, samples: int = 20, seed: int = 0,
            floating: bool = False) -> tuple[float, float]:
    """The largest differences of the kernel's end point and motor rotation (FK) and spatial Jacobian to
    Pinocchio's, at ``samples`` random configurations of the whole robot (a free-flyer root when
    ``floating``)."""
    import pinocchio as pin

    from gagen.algebra.signature import cga3d
    from gagen.interp import MultiVector
    from gagen.model import kinematics as K
    from gagen.model.conformal import EUCLID, location, vector

    algebra = cga3d()
    model = pin.buildModelFromUrdf(str(urdf), pin.JointModelFreeFlyer()) if floating \
        else pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    base_frame, tip_frame = model.getFrameId(base), model.getFrameId(tip)
    names = K.chain_variables(chain.joints)
    ids = {j.name: model.getJointId(j.name) for j in chain.joints if j.moves}
    # per chain variable: the Pinocchio velocity columns it moves, with their multipliers
    columns: list[list[tuple[int, float]]] = [[] for _ in names]
    followers: list[tuple[int, int, float, float]] = []  # (follower id, leader id, multiplier, offset)
    for joint in (j for j in chain.joints if j.moves):
        leader, multiplier, offset = joint.mimic or (joint.name, 1.0, 0.0)
        if joint.mimic is not None:
            followers.append((ids[joint.name], model.getJointId(leader), multiplier, offset))
        columns[names.index(leader)].append((model.joints[ids[joint.name]].idx_v, multiplier))
    rng = np.random.default_rng(seed)
    like = MultiVector.zero(algebra)
    rows = {port.name: port.rows for port in kernel.outputs}
    worst_fk = worst_jacobian = 0.0
    for _ in range(samples):
        q = random_configuration(pin, model, rng)
        for follower, leader, multiplier, offset in followers:  # Pinocchio's mimic joints are free
            value = multiplier * _angle(model, q, leader) + offset
            f = model.joints[follower]
            if f.nq == 1:
                q[f.idx_q] = value
            else:
                q[f.idx_q:f.idx_q + 2] = np.cos(value), np.sin(value)
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        placement = data.oMf[base_frame].actInv(data.oMf[tip_frame])
        # the tip's twist relative to the base link (a chain may go up the tree, then down), at the
        # world origin in world axes; moved to the base frame below
        world = (pin.getFrameJacobian(model, data, tip_frame, pin.ReferenceFrame.WORLD)
                 - pin.getFrameJacobian(model, data, base_frame, pin.ReferenceFrame.WORLD))
        jacobian = data.oMf[base_frame].inverse().action @ np.column_stack(
            [sum(m * world[:, v] for v, m in cols) for cols in columns])
        values = kernel.function(np.array([_angle(model, q, ids[n]) if n in ids else
                                           _angle(model, q, model.getJointId(n)) for n in names]))
        out = {port.name: np.array(v) for port, v in zip(kernel.outputs, values, strict=True)}

        def multivector(name: str, column: int = 0, out: dict[str, np.ndarray] = out) -> Any:
            dense = np.zeros(algebra.size)
            for label, v in zip(rows[name], out[name][:, column], strict=True):
                dense[algebra.blade(label)] = v
            return MultiVector(algebra, dense)

        motor = multivector("M")
        position = [location(multivector("P"))[k] for k in EUCLID]
        rotation = np.column_stack([[motor.sandwich(vector(like, np.eye(3)[i]))[k] for k in EUCLID]
                                    for i in range(3)])
        twists = np.column_stack([[c["e1inf"], c["e2inf"], c["e3inf"], c["e23"], -c["e13"], c["e12"]]
                                  for c in (multivector("J_S", k) for k in range(len(names)))])
        worst_fk = max(worst_fk, float(np.abs(position - placement.translation).max()),
                       float(np.abs(rotation - placement.rotation).max()))
        worst_jacobian = max(worst_jacobian, float(np.abs(twists - jacobian).max()))
    return worst_fk, worst_jacobian


def check(urdf: Path, base: str, tip: str, snap: bool = False, samples: int = 20,
          floating: bool = False, folder: Path | None = None) -> Outcome:
    """One chain: built through a spec written into ``folder`` (default: a temporary one; refused: the
    reason) and compared with Pinocchio."""
    from gagen.errors import SpecError

    outcome = Outcome(base, tip)
    with tempfile.TemporaryDirectory() as temporary:
        try:
            chain, kernel = chain_kernel(urdf, base, tip, folder or Path(temporary), snap)
        except SpecError as e:
            path = str(urdf.resolve())
            outcome.reason = e.message.replace(f"{path}: ", "").replace(path, urdf.name)
            return outcome
    outcome.dof = chain.dof
    outcome.continuous = sum(j.kind == "continuous" for j in chain.joints)
    outcome.fk, outcome.jacobian = compare(chain, kernel, urdf, base, tip, samples, floating=floating)
    return outcome


def survey(files: Sequence[Path], snap: bool = False, samples: int = 20) -> Iterator[Report]:
    for urdf in files:
        report = Report(urdf)
        try:
            chains = chains_of(urdf)
        except Exception as e:  # a file the XML walk cannot read: reported, not fatal
            report.refused = str(e)
            yield report
            continue
        if not chains:
            report.refused = "no moving joint"
        for base, tip in chains:
            try:
                report.outcomes.append(check(urdf, base, tip, snap, samples))
            except Exception as e:  # e.g. Pinocchio refusing the file: reported per chain
                reason = f"comparison failed ({type(e).__name__}: {e})"
                report.outcomes.append(Outcome(base, tip, reason=reason))
        yield report


def _short(reason: str) -> str:
    reason = reason.replace("|", "\\|").replace("\n", " ")
    return reason if len(reason) <= 140 else reason[:137] + "…"


def table(reports: Sequence[Report]) -> str:
    lines = ["| URDF | chains tried | built | agree ≤ 1e-12 | max FK diff | max Jacobian diff "
             "| refused: why |",
             "|---|---:|---:|---:|---:|---:|---|"]
    for r in reports:
        built = [o for o in r.outcomes if o.built]
        agree = [o for o in r.outcomes if o.agrees]
        fk = max((o.fk for o in built), default=float("nan"))
        jac = max((o.jacobian for o in built), default=float("nan"))
        reasons = [o.reason for o in r.outcomes if o.reason]
        why = r.refused or (_short(reasons[0]) + (f" (and {len(reasons) - 1} more chains alike)"
                                                  if len(reasons) > 1 else "") if reasons else "")
        name = f"{r.urdf.parent.parent.name}/{r.urdf.name}"
        lines.append(f"| {name} | {len(r.outcomes)} | {len(built)} | {len(agree)} | "
                     f"{fk:.1e} | {jac:.1e} | {why} |".replace("nan", "–"))
    tried = sum(len(r.outcomes) for r in reports)
    built = sum(o.built for r in reports for o in r.outcomes)
    agree = sum(o.agrees for r in reports for o in r.outcomes)
    files = sum(any(o.built for o in r.outcomes) for r in reports)
    lines.append(f"| **{len(reports)} files** ({files} with a chain built) | **{tried}** | **{built}** | "
                 f"**{agree}** | | | |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--only", nargs="*", help="URDF file names to try (default: all)")
    parser.add_argument("--limit", type=int, help="try the first N files only")
    parser.add_argument("--samples", type=int, default=20, help="random configurations per chain")
    parser.add_argument("--snap", action="store_true", help="snap angles (the default spec); the table's "
                                                            "bound is for the numbers as written")
    args = parser.parse_args(argv)
    files = urdf_files()
    if not files:
        print("example-robot-data is not installed: pip install example-robot-data", file=sys.stderr)
        return 2
    if args.only:
        files = [f for f in files if f.name in args.only]
    files = files[:args.limit] if args.limit else files
    start, reports = time.perf_counter(), []
    for report in survey(files, args.snap, args.samples):
        reports.append(report)
        print(f"{report.urdf.name}: {sum(o.agrees for o in report.outcomes)}/{len(report.outcomes)} agree "
              f"({time.perf_counter() - start:.0f} s)", file=sys.stderr, flush=True)
    version = metadata.version("example-robot-data")
    print(f"example-robot-data {version}, snap {'on' if args.snap else 'off'}, {args.samples} random "
          f"configurations per chain ({time.perf_counter() - start:.0f} s)\n")
    print(table(reports))
    return 0


if __name__ == "__main__":
    sys.exit(main())
