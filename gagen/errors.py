"""Errors that name what the user must fix: the file, the field, and what was expected."""

from __future__ import annotations

from pathlib import Path


class SpecError(ValueError):
    """A malformed robot spec or URDF: ``file: field: message``."""

    def __init__(self, file: str | Path, field: str, message: str) -> None:
        # one line whatever a library's text held (lxml and PyYAML put newlines in theirs)
        field, message = (" ".join(part.split()) for part in (field, message))
        self.file, self.field, self.message = str(file), field, message
        super().__init__(f"{file}: {field}: {message}")


def read_input(path: Path, field: str) -> bytes:
    """The bytes of an input file, or a SpecError naming it (missing, unreadable, a bad name)."""
    try:
        if not path.is_file():
            raise SpecError(path, field, "file not found")
        return path.read_bytes()
    except SpecError:
        raise
    except (OSError, ValueError) as e:  # unreadable, a name too long, a NUL in the name
        raise SpecError(path, field, f"cannot read the file ({type(e).__name__}: {e})") from e


def one_line(text: object) -> str:
    """``text`` on one line: a user's own newline (in a file name, an argument) written as ``\\n``."""
    return str(text).replace("\r", "\\r").replace("\n", "\\n")


def print_error(message: object) -> None:
    """``error: <message>`` as one line on stderr: how every verb reports bad input."""
    import sys

    print(f"error: {one_line(message)}", file=sys.stderr)
