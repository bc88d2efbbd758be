"""The ``gear-env`` command. Each sub-command lives in its own module of this package and
defines ``add_parser(subparsers)``, which registers the parser and sets ``func(args) -> int``."""

from __future__ import annotations

import argparse
import importlib
import sys

# sub-command modules, in the order shown by --help
COMMANDS = (
    "demo",
    "simulate",
    "sweep",
    "stability",
    "continuation",
    "figures",
    "evaluate",
    "train",
    "report",
    "compile",
)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every sub-command that is installed."""
    from .. import __version__

    parser = argparse.ArgumentParser(
        prog="gear-env",
        description="Spur gear-bearing dynamics (constant/dynamic backlash) and speed-scheduling RL.",
    )
    parser.add_argument("--version", action="version", version=f"gear-env {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        try:
            mod = importlib.import_module(f"{__name__}.{name}")
        except ModuleNotFoundError as exc:  # a command module not written yet
            if exc.name == f"{__name__}.{name}":
                continue
            raise
        mod.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``gear-env`` console script; returns the process exit code."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # a usage error (exit 2, message printed) or --help/--version (0)
        return exc.code if isinstance(exc.code, int) else 2
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except (ValueError, OSError) as exc:
        print(f"gear-env {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except ImportError as exc:  # an optional dependency (gear_env._extras.require names the extra)
        from .._extras import EXTRA_OF

        top = (exc.name or "").split(".")[0]
        hint = f" (pip install 'gear-env[{EXTRA_OF[top]}]')" if top in EXTRA_OF and "gear-env[" not in str(exc) else ""
        print(f"gear-env {args.command}: error: {exc}{hint}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
