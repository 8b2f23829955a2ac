"""Where the package's data lives: robot files, scene files, example-robot-data."""

from __future__ import annotations

import site
import sys
from functools import cache
from pathlib import Path

from openup_ompl.exceptions import ConfigError

ERD_SCHEME = "example-robot-data://"
_PACKAGE_DIR = Path(__file__).resolve().parent


def data_dir(kind: str) -> Path:
    """Directory of shipped ``robots``, ``scenes`` or (benchmark) ``problems``.

    A wheel carries them under ``openup_ompl/_data/``; an editable install or a source
    checkout finds them in the repository, beside the package (``problems`` under
    ``benchmarks/``).
    """
    source = _PACKAGE_DIR.parent / ("benchmarks" if kind == "problems" else "") / kind
    for candidate in (_PACKAGE_DIR / "_data" / kind, source):
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError(f"openup-ompl's {kind}/ directory is missing from this install")


@cache
def erd_share_dir() -> Path:
    """The ``share`` directory holding example-robot-data's files (no network, no module).

    example-robot-data 6.x installs its files under the environment's
    ``cmeel.prefix/share/example-robot-data/robots`` and ships no Python module.
    """
    roots = [*sys.path, *site.getsitepackages(), site.getusersitepackages()]
    for root in roots:
        share = Path(root) / "cmeel.prefix" / "share"
        if (share / "example-robot-data" / "robots").is_dir():
            return share
    raise FileNotFoundError(
        "example-robot-data's files were not found under any cmeel.prefix/share on sys.path; "
        "install it with `pip install example-robot-data`"
    )


def resolve_path(value: str, relative_to: Path, where: str) -> Path:
    """Resolve an ``example-robot-data://`` URI or a path relative to a definition file."""
    if value.startswith(ERD_SCHEME):
        path = erd_share_dir() / "example-robot-data" / "robots" / value[len(ERD_SCHEME) :]
    else:
        path = Path(value).expanduser()
        if not path.is_absolute():
            path = relative_to / path
    if not path.is_file():
        raise ConfigError(where, value, f"an existing file (looked at {path})")
    return path.resolve()
