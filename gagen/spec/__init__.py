"""Robot specs: YAML files describing a cooperative system, validated with errors that name the
file, the line, the field and what was expected."""

from __future__ import annotations

from typing import Any

__all__ = ["load_system"]


def __getattr__(name: str) -> Any:
    # imported on first use: gagen.robots.urdf imports gagen.spec.names, and the loader imports it
    if name == "load_system":
        from gagen.spec.loader import load_system

        return load_system
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
