"""The ``physdsl`` command line: a thin layer over the Python API.

Each subcommand lives in its own module here and registers itself on ``app`` with a
``register(app)`` function. ``main`` turns every PhysError into a rendered message and the
documented exit code (0 ok, 1 model or inference failure, 2 usage or input error).
"""
from __future__ import annotations

import importlib
import importlib.util
import sys
from pathlib import Path
from typing import Optional

import typer

from ..errors import PhysError

app = typer.Typer(
    name="physdsl",
    help="physdsl: probabilistic programs for physical scenes.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

# Subcommand modules, in the order they appear in --help.
COMMAND_MODULES = (
    "lint", "fmt", "infer", "check", "diagnose", "refine", "add_effect", "design_experiment",
    "import_", "export", "sample", "render", "track", "batch", "control", "mpc",
)


def _version_callback(value: bool) -> None:
    if value:
        from .. import __version__

        typer.echo(f"physdsl {__version__}")
        raise typer.Exit(0)


@app.callback()
def _root(
    version: bool = typer.Option(False, "--version", callback=_version_callback, is_eager=True,
                                 help="Print the version and exit."),
    cache_dir: Optional[Path] = typer.Option(
        None, "--cache-dir", metavar="DIR", file_okay=False,
        help="Folder of compiled programs kept across runs (default: PHYSDSL_CACHE_DIR, "
             "else ~/.cache/physdsl/jax); 'off' disables it."),
    no_cache: bool = typer.Option(False, "--no-cache", help="Compile afresh, keep nothing."),
) -> None:
    """physdsl: describe a physical scene, fit it to measurements, find what it misses."""
    if no_cache or cache_dir is not None:  # else the default set up at import stands
        from .. import cache

        cache.configure("off" if no_cache else cache_dir)


_registered = False


def _register_commands() -> None:
    """Attach every subcommand module once (main may be called many times in one process)."""
    global _registered
    if _registered:
        return
    _registered = True
    for name in COMMAND_MODULES:
        module_name = f"{__name__}.{name}"
        if importlib.util.find_spec(module_name) is not None:
            importlib.import_module(module_name).register(app)


def report_error(err: PhysError) -> int:
    """Print a user error to stderr; return its exit code."""
    print(err.render(), file=sys.stderr)
    return err.exit_code


def main(argv: list[str] | None = None) -> int:
    """Entry point of the console script; never lets a traceback reach the user.

    Usage errors are reported by the CLI library with exit code 2; PhysErrors are rendered
    with their place and hint; anything else is reported as a bug in one line (exit 1).
    """
    _register_commands()
    try:
        app(args=argv, prog_name="physdsl")  # standalone: raises SystemExit with the code
    except SystemExit as ex:
        return int(ex.code or 0) if not isinstance(ex.code, str) else 2
    except PhysError as err:
        return report_error(err)
    except KeyboardInterrupt as ex:  # a second Ctrl-C, or infer's Interrupted (a signal)
        note = getattr(ex, "note", "")
        print("interrupted" + (f": {note}" if note else ""), file=sys.stderr)
        return 128 + getattr(ex, "signum", 2)  # the shell's code of a signal: 130, 143
    except Exception as ex:  # noqa: BLE001 - last line of defence, reported as a bug
        print(f"internal error: {type(ex).__name__}: {ex}\n"
              "This is a bug in physdsl; please report it with the scene file.", file=sys.stderr)
        return 1
    return 0
