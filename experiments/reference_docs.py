"""The reference pages, generated from the package itself: the command line (docs/cli.md,
from the CLI's own parser) and the Python API (docs/api.md, from the modules' `__all__`,
signatures and docstrings).

    python experiments/reference_docs.py [--docs]

Prints both; with --docs writes them (tests check that the files are current).
"""

import argparse
from pathlib import Path

from pvvjax.cli import api_reference, cli_reference

DOCS = Path(__file__).resolve().parents[1] / "docs"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--docs", action="store_true", help="write docs/cli.md and docs/api.md")
    args = ap.parse_args()
    for name, text in (("cli.md", cli_reference()), ("api.md", api_reference())):
        if args.docs:
            (DOCS / name).write_text(text)
            print(f"wrote {DOCS / name}")
        else:
            print(text)


if __name__ == "__main__":
    main()
