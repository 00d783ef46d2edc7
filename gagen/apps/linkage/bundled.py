"""Where the linkage application's bundled specs are (``robots/``, shipped with the package)."""

from pathlib import Path

BUNDLED = Path(__file__).resolve().parent / "robots"  # the bundled mechanisms
