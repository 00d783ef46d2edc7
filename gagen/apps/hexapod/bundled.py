"""Where the hexapod application's bundled specs are (``robots/``, shipped with the package)."""

from pathlib import Path

BUNDLED = Path(__file__).resolve().parent / "robots"  # the bundled hexapods
SPEC = BUNDLED / "hexapod.yaml"  # the bundled hexapod
