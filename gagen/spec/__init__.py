"""Robot specs: YAML files describing a cooperative system, validated with errors that name the
file, the line, the field and what was expected."""

from gagen.spec.loader import load_system

__all__ = ["load_system"]
