"""The fuzz tier's shared pieces (issue 29): hostile names and values, byte-level and YAML-level
mutations as hypothesis strategies, and the per-case verdict every input kind is held to.

A case passes when gagen either refuses the input with a one-line ``SpecError`` naming the file and a
field, or accepts it and the result passes the kind's own check (finite outputs, valid names). Any
other exception, a multi-line message, a case over ``CASE_SECONDS`` (a hang) or a refusal that does not
name the file fails the case. ``COUNTS`` keeps the outcomes per kind, printed at the end of the run.

Case counts: ``examples(fast, full)`` is the hypothesis setting of one fuzz test, the fast tier's count
or, in the full tier (``--full``/GAGEN_TESTS=full), the full one.
"""

from __future__ import annotations

import math
import os
import sys
from collections import Counter, defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml
from conftest import deadline
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

from gagen.errors import SpecError
from gagen.frontend import KernelError

CASE_SECONDS = 20.0  # a case running longer is a hang (the slowest accepted case is far below)

# names no spec may smuggle into generated code or a path: comment ends, quotes, path tricks, C and
# Python keywords and reserved identifiers, gagen's own symbols, unicode, control bytes, the empty name
HOSTILE_NAMES = [
    "*/ #error x /*", '"""', "'", "\\", "../escape", "/tmp/absolute", "a\nb", "a b", "${x}", "\x00",
    "\u00fc\u2603", "x" * 200, "", "-", "1", "1x", "for", "int", "class", "None", "True", "__init__",
    "_reserved", "main", "gagen", "GAGEN", "HAVE_LIBMVEC", "f_batch", "v", "W", "body", "%s%n", "<b>",
    "con", "a.b", "a:b", "on", "off", "yes", "null", "~", "1.5", "1e3", "0x10", ".inf", ".nan",
]
# values for any field: wrong types, non-finite and huge numbers, empty and nested containers
HOSTILE_VALUES: list[Any] = [
    None, True, False, 0, -1, 1.5, -1e-300, 1e308, float("nan"), float("inf"), -float("inf"), 10 ** 400,
    [], {}, [1, 2], [float("nan"), 0, 0], [0, 0, 1e9], [1, 2, 3, 4], {"a": 1}, [[1]], *HOSTILE_NAMES[:16],
]

COUNTS: dict[str, Counter[str]] = defaultdict(Counter)


def examples(fast: int, full: int) -> settings:
    """Hypothesis settings running ``fast`` cases in the fast tier and ``full`` in the full tier."""
    is_full = "--full" in sys.argv or os.environ.get("GAGEN_TESTS", "").strip().lower() == "full"
    return settings(max_examples=full if is_full else fast, deadline=None, database=None,
                    suppress_health_check=list(HealthCheck), derandomize=True)


def refusal_problem(error: BaseException, files: tuple[Path, ...]) -> str | None:
    """What is wrong with a refusal (None when it is right): a SpecError of one line naming one of
    ``files`` and a field, or a KernelError of one line naming the kernel and the field (a formula)."""
    if isinstance(error, KernelError):
        text = str(error)
        if "\n" in text or not error.kernel or not error.where:
            return f"a KernelError without a kernel or field, or of several lines: {text[:300]!r}"
        return None
    if not isinstance(error, SpecError):
        return f"{type(error).__name__} escaped: {error}"[:400]
    text = str(error)
    if "\n" in text.rstrip("\n") or len(text) > 2000:
        return f"a message of {text.count(chr(10)) + 1} lines / {len(text)} characters: {text[:300]!r}"
    if error.file not in {str(f) for f in files}:
        return f"names the file {error.file!r}, not one of {[str(f) for f in files]}"
    if not error.field.strip():
        return f"names no field: {text[:300]!r}"
    return None


def run_case(kind: str, files: tuple[Path, ...], action: Callable[[], Any],
             check: Callable[[Any], None], *, must_refuse: bool = False, what: str = "") -> None:
    """One fuzz case: ``action()`` under the hang deadline, then the verdict (see the module doc).
    ``check(result)`` raises AssertionError on an accepted result that is wrong; ``must_refuse`` marks an
    input that the generator made invalid, so accepting it is wrong."""
    try:
        with deadline(CASE_SECONDS):
            result = action()
    except TimeoutError as e:
        COUNTS[kind]["hang"] += 1
        raise AssertionError(f"{kind} {what}: a hang, {e}") from e
    except Exception as e:  # the fuzzer's point: nothing but a proper refusal may escape
        problem = refusal_problem(e, files)
        COUNTS[kind]["bad refusal" if problem else "refused"] += 1
        assert problem is None, f"{kind} {what}: {problem}"
        return
    if must_refuse:
        COUNTS[kind]["wrongly accepted"] += 1
        raise AssertionError(f"{kind} {what}: accepted an invalid input")
    try:
        check(result)
    except AssertionError:
        COUNTS[kind]["wrong result"] += 1
        raise
    COUNTS[kind]["accepted"] += 1


def all_finite(values) -> bool:
    """Every number in a (nested) structure of numbers and arrays is finite."""
    import numpy as np

    if isinstance(values, dict):
        return all(all_finite(v) for v in values.values())
    if isinstance(values, list | tuple):
        return all(all_finite(v) for v in values)
    array = np.asarray(values, dtype=float)
    return bool(np.all(np.isfinite(array)))


# ---- mutations ---------------------------------------------------------------------------------------

@st.composite
def byte_mutation(draw, text: str) -> tuple[str, bytes]:
    """(description, bytes): the text truncated, with flipped or inserted bytes (NUL, invalid UTF-8,
    a hostile name), a line deleted or doubled."""
    data = text.encode()
    kind = draw(st.sampled_from(["truncate", "flip", "insert", "delete line", "double line", "nul"]))
    at = draw(st.integers(0, max(len(data) - 1, 0)))
    if kind == "truncate":
        return f"{kind} at {at}", data[:at]
    if kind == "flip":
        flipped = bytearray(data)
        for i in draw(st.lists(st.integers(0, len(data) - 1), min_size=1, max_size=4)):
            flipped[i] = draw(st.integers(0, 255))
        return kind, bytes(flipped)
    if kind in ("insert", "nul"):
        piece = b"\x00" if kind == "nul" else draw(st.sampled_from(HOSTILE_NAMES)).encode()
        return f"{kind} at {at}", data[:at] + piece + data[at:]
    lines = data.splitlines(keepends=True)
    i = draw(st.integers(0, len(lines) - 1))
    if kind == "delete line":
        return f"{kind} {i + 1}", b"".join(lines[:i] + lines[i + 1:])
    return f"{kind} {i + 1}", b"".join(lines[:i + 1] + lines[i:])


def _slots(node, path=()):
    """Every (path, container, key) of a parsed YAML document."""
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else []
    for key, value in list(items):
        yield (*path, key), node, key
        yield from _slots(value, (*path, key))


def must_refuse_value(value: Any) -> bool:
    """A value no numeric or name field may take (the non-finite numbers)."""
    return isinstance(value, float) and not math.isfinite(value)


@st.composite
def yaml_mutation(draw, text: str) -> tuple[str, str]:
    """(description, YAML text): one field of the document deleted, renamed, replaced by a hostile
    value or name, or a list entry doubled."""
    data = yaml.safe_load(text)
    slots = list(_slots(data))
    path, container, key = draw(st.sampled_from(slots))
    kind = draw(st.sampled_from(["replace", "replace", "replace", "name", "delete", "rename", "double"]))
    where = ".".join(map(str, path))
    if kind == "delete":
        del container[key]
    elif kind == "rename" and isinstance(container, dict):
        new = draw(st.sampled_from([*HOSTILE_NAMES[:30], str(key) + "x", str(key)[:-1]]))
        container[new] = container.pop(key)
    elif kind == "double" and isinstance(container, list):
        container.insert(key, container[key])
    elif kind == "name":
        container[key] = draw(st.sampled_from(HOSTILE_NAMES))
    else:
        container[key] = draw(st.sampled_from(HOSTILE_VALUES))
    try:
        dumped = yaml.safe_dump(data, allow_unicode=True, sort_keys=False)
    except yaml.YAMLError:  # a value PyYAML cannot write (10**400 is fine, a NUL in a key is not)
        dumped = text
    return f"{kind} {where}", dumped


def mutated_file(draw, text: str, folder: Path, name: str, yaml_share: float = 0.7) -> tuple[str, Path]:
    """Write a YAML-level mutation (``yaml_share`` of the cases) or a byte-level one of ``text`` to
    ``folder/name``; (description, path)."""
    path = folder / name
    if draw(st.floats(0, 1)) < yaml_share:
        what, mutated = draw(yaml_mutation(text))
        path.write_text(mutated, encoding="utf-8")
    else:
        what, raw = draw(byte_mutation(text))
        path.write_bytes(raw)
    return what, path


def print_counts() -> str:
    """The outcomes per kind, one line each (the note's table)."""
    return "\n".join(f"{kind}: {dict(sorted(counts.items()))}" for kind, counts in sorted(COUNTS.items()))


def run_document(kind: str, file_name: str, document: Any, action: Callable[[Path], Any],
                 check: Callable[[Any], None], *, must_refuse: bool = False, what: str = "") -> None:
    """One case of a spec drawn from a schema: ``document`` written as YAML to ``file_name`` in a fresh
    folder, then ``run_case`` of ``action(path)``."""
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / file_name
        path.write_text(yaml.safe_dump(document, allow_unicode=True, sort_keys=False), encoding="utf-8")
        run_case(kind, (path,), lambda: action(path), check, must_refuse=must_refuse, what=what)
