"""``openup-ompl build-native``: compile the optional coupled check for the pinocchio and
coal in use (see :mod:`openup_ompl.native`)."""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = (
    "compile the optional C++ coupled check for the pin and coal in use (about 20 s, "
    "2 GB of memory; needs a C++17 compiler and, once, PyPI for Eigen's headers)"
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``--status``, ``--force``, ``--dir``, ``--cxx``, ``--eigen``.

    Args:
        parser: The command's parser.
    """
    parser.add_argument(
        "--status",
        action="store_true",
        help="only say whether a build for the versions in use is there (exit 1 if not)",
    )
    parser.add_argument("--force", action="store_true", help="build again even if built")
    parser.add_argument(
        "--dir",
        type=Path,
        default=None,
        help="the folder of builds (default: $OPENUP_OMPL_NATIVE_DIR, else "
        "~/.cache/openup-ompl/native)",
    )
    parser.add_argument("--cxx", default=None, help="the C++17 compiler (default: $CXX, c++)")
    parser.add_argument(
        "--eigen",
        type=Path,
        default=None,
        help="a folder holding Eigen 3.4's Eigen/Core (default: PyPI's cmeel-eigen, fetched once)",
    )


def run(args: argparse.Namespace) -> int:
    """Build (or with ``--status`` look for) the compiled check.

    Args:
        args: The parsed command line.

    Returns:
        0 when it is built, 1 when ``--status`` finds none.
    """
    from openup_ompl import native

    if args.status:
        usable, line = native.status(args.dir)
        print(line)
        return 0 if usable else 1
    native.build(args.dir, force=args.force, compiler=args.cxx, eigen=args.eigen)
    return 0
