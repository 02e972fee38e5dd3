"""``scanlight`` command line: one subcommand per job, same settings and renderer as the window.

Exit codes: 0 success, 1 internal error (a bug: please report), 2 usage, 3 bad input.
Errors are one line on stderr; ``-v`` adds the traceback of internal errors.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import signal
import sys
import threading

from app import __version__
from app.bench import BENCHES
from app.errors import ScanlightError, UsageError

log = logging.getLogger("scanlight")

# subcommand -> (module, help). Each module has add_arguments(parser) and run(args) -> int.
COMMANDS = {
    "view": ("app.commands.view", "open the look-dev viewer (default with no arguments)"),
    "demo": ("app.commands.demo", "headless end-to-end run on the built-in demo scene"),
    "expand": ("app.commands.expand", "HDR-expand an LDR point cloud from one HDR photo"),
    "render": ("app.commands.render", "relight an asset with the cloud (PBGI) into EXR/PNG"),
    "turntable": ("app.commands.turntable",
                  "render an orbit (or camera path) of the relit asset: EXR/PNG frames + MP4"),
    "evaluate": ("app.commands.evaluate", "measure errors against ground truth"),
    "bench": ("app.commands.bench", "run a benchmark: " + ", ".join(BENCHES)),
}


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2 (argparse's own convention)
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="scanlight", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"scanlight {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more logging")
    parser.add_argument("-q", "--quiet", action="store_true", help="only errors")
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)
    for name, (module, help_text) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        importlib.import_module(module).add_arguments(p)
    return parser


def _setup_logging(verbose: int, quiet: bool) -> None:
    level = logging.ERROR if quiet else logging.DEBUG if verbose > 1 else logging.INFO
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    _setup_logging(args.verbose, args.quiet)
    command = args.command or "view"
    if args.command is None:
        args = parser.parse_args(["view"] if argv is None else list(argv) + ["view"])
    from app.io.outputs import COMMITTED
    commits = len(COMMITTED)
    previous = _stop_on_sigterm()
    try:
        return int(importlib.import_module(COMMANDS[command][0]).run(args) or 0)
    except ScanlightError as err:
        print(f"scanlight {command}: error: {err}", file=sys.stderr)
        return err.exit_code
    except KeyboardInterrupt as stop:
        if command == "turntable":   # one output set per frame: the finished ones stay
            done = f"; {len(COMMITTED) - commits} complete output set(s) kept, none partial"
        elif len(COMMITTED) > commits:   # Ctrl-C came after the outputs were all in place
            done = " after its outputs were written (they are complete: " + ", ".join(
                COMMITTED[-1]) + ")"
        else:
            done = "; nothing written" if command in ("render", "expand", "evaluate") else ""
        print(f"scanlight {command}: interrupted{done}", file=sys.stderr)
        return 143 if isinstance(stop, Terminated) else 130
    except (MemoryError, OSError) as exc:   # the machine refused (app/errors.py: refusal)
        from app.errors import refusal
        print(f"scanlight {command}: error: {refusal(exc)}", file=sys.stderr)
        return 3
    except Exception as exc:  # a bug, not bad input: one line, traceback with -v
        if args.verbose:
            log.exception("internal error")
        print(f"scanlight {command}: internal error: {type(exc).__name__}: {exc} "
              "(run with -v for the traceback)", file=sys.stderr)
        return 1
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


class Terminated(KeyboardInterrupt):
    """SIGTERM (``timeout``, a render farm's kill): stopped as Ctrl-C stops a command - outputs
    not yet committed are discarded, a worker process is ended - where the default action left
    hidden temporaries beside the targets and an orphaned worker writing on. Exit 143."""


def _on_sigterm(signum, frame):
    raise Terminated()


def _stop_on_sigterm():
    """Install the SIGTERM handler; returns the one it replaced (None off the main thread)."""
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGTERM, _on_sigterm)


__all__ = ["main", "build_parser", "UsageError"]
