"""The ``gelrig`` console entry point: parses the command line and dispatches to a command.

A composition root (design.md): it may import every package; nothing imports it. Every
user-facing failure ends as one line on stderr and exit code 2 (bad input) or 1 (a fault
while running); ``--debug`` shows the traceback instead. Building the parser imports no heavy
package (numpy, scipy, matplotlib, nidaqmx, grpc, h5py, Qt): each command imports what it
needs when it runs, so ``gelrig --help`` answers at once.
"""

from __future__ import annotations

import argparse
import errno
import functools
import importlib
import os
import sys
from collections.abc import Callable, Sequence
from typing import Any, NoReturn

from gelrig.instrument.core.errors import ConfigError, GelrigError

# gRPC's core (the DAQ link) logs at INFO to stderr unless told otherwise, e.g. "Got goaway"
# when the DAQ server closes first: stderr holds gelrig's one line and nothing else. Set
# before grpc is imported (a command imports it when it runs); an explicit setting wins.
os.environ.setdefault("GRPC_VERBOSITY", "ERROR")


class UsageError(GelrigError):
    """Bad command-line usage; reported as one line with exit code 2."""


class Parser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one line and exit code 2."""

    def error(self, message: str) -> NoReturn:
        raise UsageError(f"{self.prog}: error: {message}")


class LazyParser(Parser):
    """A subcommand's parser whose options are added (by ``populate``) when it is first used,
    to parse or to show its help: building the whole command line then imports nothing that
    only this subcommand needs (``gelrig sim serve``'s options come from the simulators'
    configurations)."""

    def __init__(self, *args: Any,
                 populate: Callable[[argparse.ArgumentParser], None] | None = None,
                 **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._populate = populate

    def _ready(self) -> None:
        if self._populate is not None:
            populate, self._populate = self._populate, None
            populate(self)

    def parse_known_args(self, args: Any = None, namespace: Any = None) -> Any:
        self._ready()
        return super().parse_known_args(args, namespace)

    def format_usage(self) -> str:
        self._ready()
        return super().format_usage()

    def format_help(self) -> str:
        self._ready()
        return super().format_help()


Handler = Callable[[argparse.Namespace], int]


def build_parser() -> Parser:
    from gelrig.commands import (
        analyze,
        bringup,
        campaign,
        check,
        demo,
        fit,
        gui,
        model,
        run,
        runs,
        series,
        validate,
    )

    parser = Parser(prog="gelrig", description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    parser.add_argument("--version", action="store_true", help="print the version and exit")
    sub = parser.add_subparsers(dest="command", parser_class=Parser, metavar="COMMAND")
    model.register(sub)
    fit.register(sub)
    demo.register(sub)
    run.register(sub)
    analyze.register(sub)
    series.register(sub)
    gui.register(sub)
    campaign.register(sub)
    runs.register(sub)
    validate.register(sub)
    bringup.register(sub)
    check.register(sub)
    _register_sim(sub)
    return parser


def _register_sim(sub: argparse._SubParsersAction) -> None:
    from gelrig.simulators.serve_options import SERVED

    sim = sub.add_parser("sim", help="simulated instruments")
    sim_sub = sim.add_subparsers(dest="sim_command", parser_class=Parser, metavar="ACTION")
    sim_sub.required = True
    serve = sim_sub.add_parser("serve", help="serve a simulated instrument on its wire protocol")
    which = serve.add_subparsers(dest="instrument", parser_class=LazyParser,
                                 metavar="INSTRUMENT")
    which.required = True
    for name, served in SERVED.items():
        p = which.add_parser(name, help=served.summary, populate=served.add_arguments)
        p.set_defaults(handler=functools.partial(_serve, served.module))
    from gelrig.commands import replay

    replay.register(sim_sub)


def _serve(module_name: str, args: argparse.Namespace) -> int:
    """Import a simulator's serve module only now, and serve it."""
    run: Handler = importlib.import_module(module_name).run
    return run(args)


def main(argv: Sequence[str] | None = None) -> int:
    args_list = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in args_list
    try:
        parser = build_parser()
        args = parser.parse_args(args_list)
        if args.version:
            from gelrig import __version__

            print(f"gelrig {__version__}")
            return 0
        handler: Handler | None = getattr(args, "handler", None)
        if handler is None:
            parser.print_help()
            return 2
        args.argv = args_list  # what a wire log's header records (gelrig sim replay)
        return handler(args)
    except UsageError as exc:
        if debug:
            raise
        print(exc, file=sys.stderr)
        return 2
    except ConfigError as exc:
        if debug:
            raise
        print(f"gelrig: error: {exc}", file=sys.stderr)
        return 2
    except GelrigError as exc:
        if debug:
            raise
        print(f"gelrig: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("gelrig: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # output piped into `head` and the like: stop quietly
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
    except OSError as exc:  # a path no check foresaw: still one line, exit 2
        if debug or exc.errno != errno.ENAMETOOLONG:
            raise
        print(f"gelrig: error: {str(exc.filename)[:60]}...: a name or path longer than the "
              "file system allows", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
