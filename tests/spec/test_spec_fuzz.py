"""A derandomized fuzzer over the bundled specs and URDFs (issue 12, acceptance): every mutation either
loads into a System whose every joint constant is finite, or raises a SpecError whose file is the spec
or the URDF and whose field is not empty. No other exception, no case over CASE_SECONDS.

Mutations: keys deleted, renamed or duplicated; values replaced by wrong types, NaN, inf, huge numbers
and strings with injection payloads (comment ends, triple quotes, ../, newlines, unicode); files
truncated or with flipped bytes; aliases, alias bombs and recursive anchors inserted; URDF joint types
changed, parents removed or redirected (loops, two parents), numbers and names of joints replaced."""

from __future__ import annotations

import itertools
import math
import random
import re
import shutil
import time
from pathlib import Path

import yaml
from conftest import deadline

from gagen.errors import SpecError
from gagen.robots.spec import load_system
from gagen.robots.system import System

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
SPECS = sorted(ROBOTS.glob("*.yaml"))
URDFS = sorted(ROBOTS.glob("*/*.urdf"))
CASES = 240
CASE_SECONDS = 5.0
SEED = 20260412

PAYLOADS = ["*/ #error x /*", '"""', "../escape", "/tmp/absolute", "a\nb", "\u00fc\u2603", "x" * 200, "",
            "arm-0", "similarity", "for", "a b", "${x}", "\\", "'", "\x00"]
VALUES = [None, True, 0, -1, 1.5, 1e308, float("nan"), float("inf"), -float("inf"), 10 ** 400, [], {},
          [1, 2], [float("nan"), 0, 0], [0, 0, 1e9], [1, 2, 3, 4], "panda_link0", {"xyz": [0, 0]}, *PAYLOADS]
XML_NUMBERS = ["nan", "inf", "-inf", "1e9", "1e400", "x", "", "0 0", "1 2 3 4", "1e-320 0 0"]
JOINT_TYPES = ["floating", "planar", "fixed", "prismatic", "continuous", "weird", ""]




def _slots(node):
    """Every (container, key) of a parsed document, for structured mutations."""
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else []
    for key, value in list(items):
        yield node, key
        yield from _slots(value)


def _mutate_spec(rng: random.Random, text: str) -> tuple[str, str]:
    """(description, mutated text) of one spec."""
    kind = rng.choice(["delete", "rename", "replace", "replace", "replace", "duplicate", "truncate", "flip",
                       "alias", "bomb", "recursive", "chain", "name"])
    if kind in ("delete", "rename", "replace", "chain", "name"):
        data = yaml.safe_load(text)
        if kind == "chain":  # a copy of a chain, or one chain fewer
            chains = data["chains"]
            if rng.random() < 0.5:
                chains.append(dict(rng.choice(chains)))
            else:
                chains.pop(rng.randrange(len(chains)))
            return kind, yaml.safe_dump(data, allow_unicode=True)
        if kind == "name":  # a payload as the system, a chain or a robot name
            target = rng.choice([data, *data["chains"]])
            key = rng.choice(["name", "robot"]) if target is not data else "name"
            target[key] = rng.choice(PAYLOADS)
            return f"{kind} {key}={target[key]!r}", yaml.safe_dump(data, allow_unicode=True)
        container, key = rng.choice(list(_slots(data)))
        if kind == "delete":
            del container[key]
        elif kind == "rename" and isinstance(container, dict):
            i = rng.randrange(len(str(key)) + 1)
            container[str(key)[:i] + rng.choice("xe_") + str(key)[i + 1:]] = container.pop(key)
        else:
            container[key] = rng.choice(VALUES)
        return f"{kind} {key!r}", yaml.safe_dump(data, allow_unicode=True)
    lines = text.splitlines(keepends=True)
    if kind == "duplicate":
        keyed = [i for i, line in enumerate(lines) if re.match(r"\s*(- )?\w+:", line)]
        i = rng.choice(keyed)
        twin = lines[i].replace("- ", "  ", 1)  # the same key again, in the same mapping
        return f"{kind} line {i + 1}", "".join([*lines[:i + 1], twin, *lines[i + 1:]])
    if kind == "truncate":
        n = rng.randrange(len(text))
        return f"{kind} at {n}", text[:n]
    if kind == "flip":
        data = bytearray(text.encode())
        for _ in range(rng.randint(1, 4)):
            data[rng.randrange(len(data))] = rng.randrange(256)
        return kind, bytes(data)  # maybe not UTF-8
    if kind == "alias":  # anchor a chain's first mapping value and refer to it elsewhere
        return kind, text.replace("primitive:", "primitive: &p", 1).replace("name:", "name: *p #", 1)
    if kind == "bomb":
        keys = "abcdefghi"
        bomb = "a: &a [lol,lol,lol,lol,lol,lol,lol,lol,lol]\n" + "".join(
            f"{k}: &{k} [{','.join([f'*{p}'] * 9)}]\n" for p, k in itertools.pairwise(keys))
        return kind, bomb + text
    return kind, text.replace("configurations:", "configurations: &c", 1) + "  loop: *c\n"


def _mutate_urdf(rng: random.Random, text: str) -> tuple[str, str]:
    kind = rng.choice(["type", "parent", "redirect", "number", "name", "duplicate", "truncate", "flip"])
    joints = list(re.finditer(r'<joint name="([^"]*)" type="([^"]*)"', text))
    joint = rng.choice(joints)
    if kind == "type":
        new = rng.choice(JOINT_TYPES)
        return f"{kind} {joint[1]}={new}", text[:joint.start(2)] + new + text[joint.end(2):]
    parents = list(re.finditer(r'<parent link="([^"]*)"\s*/>', text))
    if kind == "parent":
        p = rng.choice(parents)
        return kind, text[:p.start()] + text[p.end():]
    if kind == "redirect":  # a joint's parent becomes another link: loops and links with two parents
        p = rng.choice(parents)
        links = re.findall(r'<link name="([^"]*)"', text)
        return kind, text[:p.start(1)] + rng.choice(links) + text[p.end(1):]
    if kind == "number":
        numbers = list(re.finditer(r'(xyz|rpy)="([^"]*)"', text))
        n = rng.choice(numbers)
        return f"{kind} {n[2]!r}", text[:n.start(2)] + rng.choice(XML_NUMBERS) + text[n.end(2):]
    if kind == "name":
        new = rng.choice(PAYLOADS).replace("&", "&amp;").replace("<", "&lt;").replace('"', "&quot;")
        return f"{kind} {joint[1]}", text[:joint.start(1)] + new + text[joint.end(1):]
    if kind == "duplicate":
        end = text.index("</joint>", joint.start()) + len("</joint>")
        return f"{kind} {joint[1]}", text[:end] + text[joint.start():end] + text[end:]
    if kind == "truncate":
        n = rng.randrange(len(text))
        return f"{kind} at {n}", text[:n]
    data = bytearray(text.encode())
    for _ in range(rng.randint(1, 4)):
        data[rng.randrange(len(data))] = rng.randrange(256)
    return kind, bytes(data)


def _finite(system: System, configurations: dict[str, list[float]]) -> bool:
    values = [v for chain in system.chains for j in chain.joints for v in (*j.xyz, *j.rpy, *j.axis)]
    mimics = [j.mimic for chain in system.chains for j in chain.joints if getattr(j, "mimic", None)]
    values += [v for mimic in mimics for v in mimic[1:]]
    values += [v for q in configurations.values() for v in q]
    return system.dof > 0 and all(isinstance(v, float) and math.isfinite(v) for v in values)


def test_mutated_specs_and_urdfs_load_or_name_the_file_and_field(tmp_path):
    root = tmp_path / "robots"
    shutil.copytree(ROBOTS, root, ignore=shutil.ignore_patterns("*.stl", "*.dae", "*.obj"))
    rng = random.Random(SEED)
    load_system(root / "panda_point.yaml")  # imports (yourdfpy, numpy) outside the timed cases
    outcomes: dict[str, int] = {"system": 0, "spec error": 0}
    fields: set[str] = set()
    failures = []
    slowest = 0.0
    for case in range(CASES):
        spec = root / rng.choice(SPECS).name
        original = spec.read_text()
        urdfs = sorted({(spec.parent / u).resolve() for u in re.findall(r"urdf: (\S+)", original)})
        restore = {spec: original}
        if rng.random() < 0.6:
            what, mutated = _mutate_spec(rng, original)
            target = spec
        else:
            target = rng.choice(urdfs)
            restore[target] = target.read_text()
            what, mutated = _mutate_urdf(rng, restore[target])
        if isinstance(mutated, bytes):
            target.write_bytes(mutated)
        else:
            target.write_text(mutated)
        start = time.perf_counter()
        try:
            with deadline(CASE_SECONDS):
                system, configurations = load_system(spec)
            if not _finite(system, configurations):
                failures.append(f"{case} {spec.name} {what}: a non-finite model")
            outcomes["system"] += 1
        except SpecError as e:
            if e.file not in (str(spec), *(str(u) for u in urdfs)) or not e.field:
                failures.append(f"{case} {spec.name} {what}: SpecError naming {e.file!r}, field {e.field!r}")
            outcomes["spec error"] += 1
            fields.add(re.sub(r"\[\d+\]| \(line \d+\)", "", e.field).split(".")[-1])
        except Exception as e:  # the fuzzer's point: nothing else may escape
            failures.append(f"{case} {spec.name} {what}: {type(e).__name__}: {e}"[:300])
        slowest = max(slowest, time.perf_counter() - start)
        for path, text in restore.items():
            path.write_text(text)
    print(f"{CASES} cases: {outcomes}, slowest {slowest:.3f} s, fields {sorted(fields)}")
    assert failures == [], "\n".join(failures)
    # the fuzzer is not vacuous: both outcomes, errors in many fields, no case near the deadline
    assert outcomes["system"] >= 10 and outcomes["spec error"] >= 150, outcomes
    assert len(fields) >= 10, fields
    assert slowest < 0.5 * CASE_SECONDS, slowest  # (a load-independent margin: 1.6 s was seen on a busy VM)
