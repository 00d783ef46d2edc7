"""Errors that name what the user must fix: the file, the field, and what was expected."""

from __future__ import annotations

from pathlib import Path


class SpecError(ValueError):
    """A malformed robot spec or URDF: ``file: field: message``."""

    def __init__(self, file: str | Path, field: str, message: str) -> None:
        self.file, self.field, self.message = str(file), field, message
        super().__init__(f"{file}: {field}: {message}")
