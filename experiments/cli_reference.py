"""The command-line reference, generated from the CLI's own parser.

    python experiments/cli_reference.py [--docs]

Prints it; with --docs writes docs/cli.md (a test checks that the file is current).
"""

import argparse
from pathlib import Path

from pvvjax.cli import cli_reference


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--docs", action="store_true", help="write docs/cli.md")
    args = ap.parse_args()
    text = cli_reference()
    if args.docs:
        path = Path(__file__).resolve().parents[1] / "docs" / "cli.md"
        path.write_text(text)
        print(f"wrote {path}")
    else:
        print(text)


if __name__ == "__main__":
    main()
