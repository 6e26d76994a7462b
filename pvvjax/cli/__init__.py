"""The `pvvjax` command line: one subcommand per pipeline stage, plus `run` (the main job).

Errors from bad input (campaign problems, config mistakes, missing files) are printed as
plain messages naming the file and field, with a non-zero exit; never a traceback.
"""

from __future__ import annotations

import os
import sys

from .._apidoc import api_reference
from ..experiment import use_deterministic_gpu
from ._parser import build_parser, cli_reference

__all__ = ["api_reference", "build_parser", "cli_reference", "main"]


def main(argv=None) -> int:
    """Run the CLI on `argv` (default: the process's arguments); returns the exit status
    (2 for bad input, reported as one clear message rather than a traceback)."""
    from .._strict import ConfigError
    from ..data.campaign import CampaignError

    args = build_parser().parse_args(argv)
    use_deterministic_gpu()  # before any command starts JAX
    try:
        return args.fn(args)
    except (CampaignError, ConfigError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except RuntimeError as e:  # TrainingError (imported lazily: JAX may not be started yet)
        if type(e).__name__ != "TrainingError" or os.environ.get("PVVJAX_DEBUG"):
            raise
        print(f"error: {e}", file=sys.stderr)
        return 2
    except (FileNotFoundError, KeyError, ValueError) as e:
        if os.environ.get("PVVJAX_DEBUG"):
            raise
        print(f"error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
