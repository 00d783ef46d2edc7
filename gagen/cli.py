"""The ``gagen`` command line: a dispatcher over the verbs that the core and the applications register
(``gagen.registry``). Each verb defines and parses its own arguments; a bad argument is one line on stderr
and exit status 2."""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence

from gagen import __version__
from gagen.registry import OneLineParser, verbs


def parser() -> OneLineParser:
    """The parser of every registered verb."""
    top = OneLineParser(prog="gagen", description="Symbolic code generation for geometric algebra in "
                                                  "robotics.")
    top.add_argument("--version", action="version", version=f"gagen {__version__}")
    sub = top.add_subparsers(dest="command", required=True, metavar="VERB")
    for verb in verbs():
        each = sub.add_parser(verb.name, help=verb.help, description=verb.help)
        verb.add_arguments(each)
        each.set_defaults(run=verb.run)
    return top


def main(argv: Sequence[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        status: int = args.run(args)
        return status
    except BrokenPipeError:  # the output went into `head` or a closed pager: stop quietly, as cat does
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141  # 128 + SIGPIPE


if __name__ == "__main__":
    sys.exit(main())
