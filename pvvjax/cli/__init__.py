"""The `pvvjax` command line: one subcommand per pipeline stage, plus `run` (the main job).

Errors from bad input (campaign problems, config mistakes, missing files) are printed as
plain messages naming the file and field, with a non-zero exit; never a traceback.
"""

from __future__ import annotations

import os
import sys

from .._apidoc import api_reference
from ..experiment import use_deterministic_gpu
from ..interrupts import check_interrupt, interruptible
from ._parser import build_parser, cli_reference

__all__ = ["api_reference", "build_parser", "cli_reference", "main"]


def _error(text: str) -> None:
    """An error on a line of its own (after a progress bar's partial line, too)."""
    sys.stdout.flush()
    print(("\n" if sys.stderr.isatty() else "") + f"error: {text}", file=sys.stderr)


def _message(e: BaseException) -> str:
    if isinstance(e, KeyError) and e.args:
        return str(e.args[0])
    if isinstance(e, (FileExistsError, NotADirectoryError)) and e.filename is not None:
        return f"{e.filename}: a file stands where a folder is needed; give a path under a folder"
    if isinstance(e, OSError) and e.filename is not None and e.strerror:
        return f"{e.filename}: {e.strerror}"
    return str(e)


def main(argv=None) -> int:
    """Run the CLI on `argv` (default: the process's arguments); returns the exit status.

    A user's mistake (campaign problems, config mistakes, missing or unwritable paths, a
    results folder of other settings) is one clear message and status 2, never a traceback
    (`PVVJAX_DEBUG=1` shows it); Ctrl-C is status 130 with how to resume, wherever it lands
    (`interrupts`); a closed pipe
    (`pvvjax validate … | head`) ends quietly."""
    from .._strict import ConfigError
    from ..data.campaign import CampaignError

    try:  # a flag's mistake: argparse has said which (status 2); a caller gets the status
        args = build_parser().parse_args(argv)
    except SystemExit as e:
        return e.code if isinstance(e.code, int) else 2
    use_deterministic_gpu()  # before any command starts JAX
    import warnings

    plain, warnings.formatwarning = warnings.formatwarning, _warning_line
    try:
        with interruptible():
            code = args.fn(args)
            check_interrupt()  # a Ctrl-C swallowed where it landed still stops the command
        sys.stdout.flush()  # inside the try: a reader that left shows here, not at exit
        return code
    except KeyboardInterrupt:
        _error("interrupted; run the same command to resume (finished work is kept)")
        return 130
    except BrokenPipeError:  # the reader went away: nothing more to say, and nowhere to say it
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except (CampaignError, ConfigError) as e:
        _error(str(e))
        return 2
    except RuntimeError as e:  # TrainingError (imported lazily: JAX may not be started yet)
        if type(e).__name__ != "TrainingError" or os.environ.get("PVVJAX_DEBUG"):
            raise
        _error(str(e))
        return 2
    except (OSError, KeyError, ValueError) as e:
        if os.environ.get("PVVJAX_DEBUG"):
            raise
        _error(_message(e))
        return 2
    finally:
        warnings.formatwarning = plain


def _warning_line(message, category, filename, lineno, line=None) -> str:
    """A warning as the user reads it: `warning: <what and where>`, without the source line
    (a dropped channel, a degenerate model exported on request)."""
    return f"warning: {message}\n"


if __name__ == "__main__":
    sys.exit(main())
