"""A sweep's output folder: one Parquet file per finished chunk, and the sweep's description.

Layout of ``DIR``:

- ``sweep.json``: what the sweep is (its kind and parameters). A re-run into the same folder must
  describe the same sweep, else it is refused: chunk 7 of one sweep is not chunk 7 of another.
- ``chunk-000007.parquet``: the rows of chunk 7. Written under a hidden temporary name in the same
  folder, flushed to disk and renamed (``os.replace``, atomic on POSIX): a chunk file is either
  complete or absent, whatever is killed when. A chunk computed twice (a task rescheduled after its
  worker died) is renamed onto the same name twice with the same rows, so it is present once.
- ``.chunk-000007.parquet.<pid>.<random>.partial``: a write in progress, or the leftover of one that
  was killed; ``clear_partials`` removes them at the start of a run (one run per folder at a time).
"""

from __future__ import annotations

import json
import os
import re
import uuid
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from gagen.extras import MissingExtra

try:
    import pyarrow as pa
    import pyarrow.parquet as pq
except ModuleNotFoundError as e:  # the sweep extra
    raise MissingExtra("pyarrow", "gagen.sweep") from e


MANIFEST = "sweep.json"
CHUNK = re.compile(r"chunk-(\d{6})\.parquet")


class SweepError(ValueError):
    """A sweep that cannot run or be read: malformed parameters, another sweep's folder, a bad file."""


def chunk_name(index: int) -> str:
    return f"chunk-{index:06d}.parquet"


def _write_atomically(path: Path, write: Any) -> None:
    """``write(temporary_path)``, fsync, then rename onto ``path``."""
    partial = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.partial")
    try:
        write(partial)
        with open(partial, "rb") as handle:  # the rename must not reach the disk before the data
            os.fsync(handle.fileno())
        os.replace(partial, path)
    finally:
        partial.unlink(missing_ok=True)


class ChunkStore:
    """The chunk files of one sweep in ``folder`` (created on ``claim``)."""

    def __init__(self, folder: str | os.PathLike[str]) -> None:
        self.folder = Path(folder)

    def claim(self, description: Mapping[str, Any]) -> None:
        """Make the folder this sweep's: write ``sweep.json``, or check that the one there describes the
        same sweep (a SweepError naming the file and the first differing field otherwise)."""
        self.folder.mkdir(parents=True, exist_ok=True)
        path = self.folder / MANIFEST
        wanted = json.loads(json.dumps(dict(description)))  # tuples as lists, as they come back from JSON
        if path.exists():
            try:
                found = json.loads(path.read_text())
            except (OSError, json.JSONDecodeError) as e:
                raise SweepError(f"{path}: not a sweep description ({e})") from e
            if not isinstance(found, dict):
                raise SweepError(f"{path}: expected a JSON object describing a sweep, got "
                                 f"{type(found).__name__}")
            for key in sorted(set(found) | set(wanted)):
                if found.get(key) != wanted.get(key):
                    raise SweepError(f"{path}: this folder holds a sweep with {key} = {found.get(key)!r}, "
                                     f"not {wanted.get(key)!r}; resume it with the same arguments or choose "
                                     "another --out")
            return
        _write_atomically(path, lambda p: p.write_text(json.dumps(wanted, indent=2) + "\n"))

    def clear_partials(self) -> int:
        """Remove the leftovers of killed writes; how many there were."""
        leftovers = list(self.folder.glob(".chunk-*.partial"))
        for path in leftovers:
            path.unlink(missing_ok=True)
        return len(leftovers)

    def finished(self) -> set[int]:
        """Indices of the chunks whose files exist."""
        if not self.folder.is_dir():
            return set()
        names = (CHUNK.fullmatch(path.name) for path in self.folder.iterdir())
        return {int(match.group(1)) for match in names if match}

    def write(self, index: int, table: pa.Table) -> Path:
        path = self.folder / chunk_name(index)
        _write_atomically(path, lambda p: pq.write_table(table, p))
        return path

    def read(self, count: int | None = None) -> pa.Table:
        """Every chunk's rows in chunk order, as one table; with ``count``, chunks 0 … count − 1 must all be
        there (a SweepError names the first missing one)."""
        indices = sorted(self.finished())
        if count is not None:
            missing = sorted(set(range(count)) - set(indices))
            if missing:
                raise SweepError(f"{self.folder}: {len(missing)} of {count} chunks missing (first: "
                                 f"{chunk_name(missing[0])}); re-run the sweep to compute them")
            indices = [i for i in indices if i < count]
        if not indices:
            raise SweepError(f"{self.folder}: no chunk files (chunk-NNNNNN.parquet) to read")
        tables = []
        for index in indices:
            path = self.folder / chunk_name(index)
            try:
                tables.append(pq.read_table(path))
            except (OSError, pa.ArrowException) as e:
                raise SweepError(f"{path}: not a readable Parquet chunk ({e}); delete it and re-run") from e
        return pa.concat_tables(tables)
