"""The command-line parser of the project's argparse commands, whose refusals are one line.

``argparse`` reports a bad command line as a usage block and a message (several lines); here it is one line,
``error: <command>: <what>; see <command> --help``, with exit status 2, as every other bad input.
"""

from __future__ import annotations

import argparse
import sys

__all__ = ["ArgumentParser"]


class ArgumentParser(argparse.ArgumentParser):
    """``argparse.ArgumentParser`` with a one-line refusal (``--help`` is unchanged)."""

    def error(self, message: str):
        print(f"error: {self.prog}: {' '.join(message.split())}; see {self.prog} --help", file=sys.stderr)
        sys.exit(2)
