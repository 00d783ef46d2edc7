"""Argument types and shared options of the ``gagen`` verbs: each type refuses a bad value with a message
that ``argparse`` prints on one line (``gagen build: error: argument -j/--jobs: expected an integer >= 1,
got '-3'``), so no bad value reaches the library."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Sequence
from typing import Any

from gagen.extras import MissingExtra, installed

DEFAULT_VIEWER_PORT = 8080  # the viewer's port on 127.0.0.1 (= gagen.viewer.DEFAULT_PORT)


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None


def finite_float(text: str) -> float:
    """A finite number (nan and inf are refused)."""
    value = _number(text)
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def non_negative_float(text: str) -> float:
    """A finite number ≥ 0."""
    value = _number(text)
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"expected a finite number ≥ 0, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0 (nan, inf, 0 and negatives are refused)."""
    value = _number(text)
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text!r}")
    return value


def non_negative_int(text: str) -> int:
    """An integer ≥ 0."""
    value = _integer(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected an integer ≥ 0, got {text!r}")
    return value


def positive_int(text: str) -> int:
    """An integer >= 1."""
    value = _integer(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}")
    return value


def numbers(count: int) -> Callable[[str], tuple[float, ...]]:
    """An argparse type: ``count`` finite numbers, comma-separated (``0,0,0.1``)."""

    def parse(text: str) -> tuple[float, ...]:
        parts = text.split(",")
        values = [finite_float(part.strip()) for part in parts] if len(parts) == count else []
        if len(values) != count:
            raise argparse.ArgumentTypeError(f"expected {count} comma-separated numbers, got {text!r}")
        return tuple(values)

    parse.__name__ = f"{count} numbers"  # argparse names the type in its messages
    return parse


def port(text: str) -> int:
    """A TCP port, 0 (any free one) to 65535."""
    value = _integer(text)
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"expected a port from 0 to 65535, got {text!r}")
    return value


class FlagNeeding(argparse.Action):
    """A flag (``store_true``) that needs an optional module: given without it, the parser's one-line error
    names the extra that brings it, before anything runs (``add_argument("--view", action=FlagNeeding,
    module="viser")``)."""

    def __init__(self, option_strings: Sequence[str], dest: str, module: str, default: bool = False,
                 required: bool = False, help: str | None = None) -> None:
        super().__init__(option_strings, dest, nargs=0, const=True, default=default, required=required,
                         help=help)
        self.module = module

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any,
                 option_string: str | None = None) -> None:
        if not installed(self.module):
            parser.error(str(MissingExtra(self.module, option_string or self.dest)))
        setattr(namespace, self.dest, True)


def view_arguments(parser: argparse.ArgumentParser, what: str) -> None:
    """``--view`` and ``--port``: play a demo's joint trajectory in the browser (gagen.viewer)."""
    parser.add_argument("--view", action=FlagNeeding, module="viser",
                        help=f"then play {what} in the browser viewer (http://127.0.0.1:PORT) until Ctrl-C")
    parser.add_argument("--port", type=port, default=DEFAULT_VIEWER_PORT,
                        help=f"the viewer's port on 127.0.0.1 (default {DEFAULT_VIEWER_PORT})")
