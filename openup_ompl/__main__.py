"""``python -m openup_ompl`` and the ``openup-ompl`` script: dispatch to the command line
package :mod:`openup_ompl.cli`."""

from __future__ import annotations

from openup_ompl.cli import build_parser, main, run

__all__ = ["build_parser", "main", "run"]

if __name__ == "__main__":
    run()
