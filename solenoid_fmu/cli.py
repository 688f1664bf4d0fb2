"""Command line: ``solenoid-fmu <command> ...``.

Each subpackage's ``cli`` module owns its subcommands through a function ``add_cli(subparsers)`` that
registers an argparse parser and sets ``func`` (called with the parsed namespace; returns the
exit code). This module only collects them, prints errors without a traceback and sets the exit
code: 0 success, 1 a checked error (bad file, non-convergence), 2 a usage error.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from ._version import __version__
from .errors import SolenoidError

#: Where each group of subcommands is registered (``module:function``, the function takes the
#: subparsers), in the order of the data flow, which is the order of ``--help``.
COMMAND_MODULES = (
    "field.cli:add_cli",
    "maps.cli:add_cli",
    "measure.cli:add_cli",
    "rig.cli:add_cli",
    "identification.cli:add_cli",
    "maps.cli:add_eddy_cli",
    "fmu.cli:add_cli",
    "loop.cli:add_cli",
    "pipeline:add_cli",
    "lot.cli:add_cli",
)

EPILOG = """examples:
  solenoid-fmu solve --x-mm 1.5 --i-A 1.5 --json
  solenoid-fmu maps -o maps/ps45-literature
  solenoid-fmu export maps/ps45-literature -o build/ps45.fmu
  solenoid-fmu pipeline fitting/ps45-demo -o build/ps45-demo
"""


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser with every available subcommand registered."""
    parser = argparse.ArgumentParser(
        prog="solenoid-fmu",
        description="Valve solenoid: FEM, B(H) identification, characteristic maps, FMU export.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"solenoid-fmu {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for entry in COMMAND_MODULES:
        module, function = entry.split(":")
        getattr(importlib.import_module(f"solenoid_fmu.{module}"), function)(sub)
    return parser


def _not_a_directory(path, strerror: str) -> str:
    """The message for a folder that cannot be made because ``path`` or one of its parents is a file
    (``mkdir`` raises FileExistsError or NotADirectoryError): names that file."""
    from pathlib import Path

    for p in (Path(path), *Path(path).parents):
        if p.exists() and not p.is_dir():
            where = "" if p == Path(path) else f"cannot write there, {p} "
            return f"{path}: {where}is a file, not a directory"
    return f"{strerror}: {path}"


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit code (also used by ``python -m solenoid_fmu``).

    Errors the user can act on print one line (``error: ...``, exit 1); Ctrl-C, also during
    start-up, prints ``interrupted`` (exit 130).
    """
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        if getattr(args, "func", None) is None:
            parser.print_help()
            return 2
        return int(args.func(args) or 0)
    except SolenoidError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except (FileExistsError, NotADirectoryError) as exc:
        print(f"error: {_not_a_directory(exc.filename2 or exc.filename, exc.strerror)}", file=sys.stderr)
        return 1
    except OSError as exc:  # a file that cannot be read or written (missing, rights, full disk, link loop)
        # os.replace(temporary, destination) names the destination second: report that one
        where = exc.filename2 or exc.filename
        print(f"error: {exc.strerror or exc}" + (f": {where}" if where else ""), file=sys.stderr)
        return 1
    except RuntimeError as exc:
        if not str(exc).startswith("Symlink loop"):  # pathlib's resolve() on a link loop (Python < 3.13)
            raise
        print(f"error: {exc}: a link that points back to itself; give another path", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
