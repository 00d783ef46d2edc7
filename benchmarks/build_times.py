"""Build time of the bundled examples (robots/*.yaml), from scratch (--force) into a temporary folder.

- ``sequential``: one ``gagen build SPEC -o ROOT/<name> --force`` process per spec, one after another;
  the wall time of each process (interpreter start and imports included) and the phases from gagen's
  progress lines: "N kernel graphs ready (X s)", "<system>: compiled <library> and <binding> (X s)"
  and "<system>: built in Y s" (everything but interpreter start);
- ``parallel``: all specs in one process through the Python API, ``build_many(specs, force=True,
  outputs=[ROOT/<name>, ...])``: models and C sources one after another while the C compiler runs on
  the finished ones on every core. Timed around the whole process.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

MODEL = re.compile(r"(\d+) kernel graphs (?:built|ready) \(([\d.]+) s\)")
COMPILED = re.compile(r"^\s*(\S+): compiled .* \(([\d.]+) s\)$", re.M)
BUILT = re.compile(r"^(\S+): built in ([\d.]+) s", re.M)

PARALLEL = """
import sys
from pathlib import Path
from gagen.build import build_many
root, specs = Path(sys.argv[1]), sys.argv[2:]
build_many(specs, force=True, outputs=[root / Path(s).stem for s in specs], progress=print)
"""


def gagen_command() -> list[str]:
    """The ``gagen`` console script next to this interpreter (else on PATH)."""
    script = Path(sys.executable).parent / "gagen"
    if script.exists():
        return [str(script)]
    found = shutil.which("gagen")
    if not found:
        raise SystemExit("no `gagen` command: pip install -e . in this environment")
    return [found]


def _last_line(text: str) -> str:
    """The last non-empty line of a failed build's output (the error, not its traceback)."""
    lines = [line.strip() for line in text.strip().splitlines() if line.strip()]
    return lines[-1] if lines else "(no output)"


def _c_source_kb(folder: Path) -> float | None:
    sources = [p for p in folder.glob("*.c") if not p.name.endswith("_binding.c")]
    return sum(p.stat().st_size for p in sources) / 1000 if sources else None


def sequential(specs: list[Path], root: Path, log=print) -> list[dict]:
    rows = []
    for spec in specs:
        out = root / spec.stem
        command = [*gagen_command(), "build", str(spec), "-o", str(out), "--force"]
        log(f"  {spec.name} ...")
        start = time.perf_counter()
        done = subprocess.run(command, capture_output=True, text=True)
        wall = time.perf_counter() - start
        text = done.stdout + done.stderr
        model, compiled, built = MODEL.search(text), COMPILED.search(text), BUILT.search(text)
        row = {"spec": spec.name, "wall": wall, "ok": done.returncode == 0,
               "kernels": int(model.group(1)) if model else None,
               "model": float(model.group(2)) if model else None,
               "compile": float(compiled.group(2)) if compiled else None,
               "built": float(built.group(2)) if built else None,
               "c_kb": _c_source_kb(out), "error": None if done.returncode == 0 else _last_line(text)}
        if row["built"] is not None and row["compile"] is not None:
            row["source"] = row["built"] - row["compile"] - (row["model"] or 0.0)
        rows.append(row)
    return rows


def parallel(specs: list[Path], root: Path) -> dict:
    command = [sys.executable, "-c", PARALLEL, str(root), *map(str, specs)]
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True)
    wall = time.perf_counter() - start
    text = done.stdout + done.stderr
    return {"wall": wall, "ok": done.returncode == 0,
            "compile_sum": sum(float(m.group(2)) for m in COMPILED.finditer(text)),
            "built": {m.group(1): float(m.group(2)) for m in BUILT.finditer(text)},
            "error": None if done.returncode == 0 else _last_line(text)}
