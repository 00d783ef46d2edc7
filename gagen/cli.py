"""The ``gagen`` command line: a dispatcher over the verbs that the core and the applications register
(``gagen.registry``). Each verb defines and parses its own arguments; a bad argument is one line on stderr
and exit status 2."""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from gagen import __version__
from gagen.errors import print_error
from gagen.extras import MissingExtra, check, optional_missing
from gagen.registry import OneLineParser, Verb, verbs


def parser() -> OneLineParser:
    """The parser of every registered verb."""
    top = OneLineParser(prog="gagen", description="Symbolic code generation for geometric algebra in "
                                                  "robotics.")
    top.add_argument("--version", action="version", version=f"gagen {__version__}")
    sub = top.add_subparsers(dest="command", required=True, metavar="VERB")
    for verb in verbs():
        each = sub.add_parser(verb.name, help=verb.help, description=verb.help)
        verb.add_arguments(each)
        each.set_defaults(verb=verb)
    return top


def run(verb: Verb, args: argparse.Namespace) -> int:
    """Run ``verb`` on its parsed arguments. Bad input it finds (a ValueError: a malformed spec, a goal of
    another kind, a SpecError naming the file and field), or an optional dependency it needs
    (``verb.needs``) or meets on the way that is not installed, is one line on stderr, exit status 2."""
    try:
        check(verb.needs, f"gagen {verb.name}")
        status: int = verb.run(args)
        return status
    except ValueError as e:  # bad input the verb could only check by reading it (a spec, a goal): one line
        print_error(e)
        return 2
    except ModuleNotFoundError as e:
        if not optional_missing(e):
            raise
        missing = e if isinstance(e, MissingExtra) else MissingExtra(e.name or "", f"gagen {verb.name}")
        print_error(missing)
        return 2


def main(argv: Sequence[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        return run(args.verb, args)
    except BrokenPipeError:  # the output went into `head` or a closed pager: stop quietly, as cat does
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141  # 128 + SIGPIPE


if __name__ == "__main__":
    sys.exit(main())
