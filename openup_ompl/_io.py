"""Writing files so that a reader never sees a partial one, and reading the package's
JSON formats back."""

from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path
from typing import Any

from openup_ompl.exceptions import ConfigError


def _umask() -> int:
    """The process's file mode creation mask (read by setting it and setting it back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def check_dir(path: Path, what: str = "directory") -> Path:
    """Refuse, without creating anything, a directory path that is (or lies under) a
    file; returns ``path``.

    Raises:
        ConfigError: ``path`` or one of its parents is a file, naming ``what``.
    """
    file = next((p for p in (path, *path.parents) if p.exists() and not p.is_dir()), None)
    if file is not None:
        raise ConfigError(what, str(path), f"a directory ({file} is a file)")
    return path


def make_dir(path: Path) -> Path:
    """Create the directory ``path`` and its parents if missing; returns ``path``.

    Raises:
        ConfigError: ``path`` or one of its parents is a file.
    """
    try:
        path.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        check_dir(path)
        raise
    return path


def write_atomic(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` through a temporary file in the same directory and
    ``os.replace``: the file is either absent, the old one, or complete; the temporary file
    never survives a failure. The file gets the mode ``open`` would give a new one
    (``0o666`` less the umask: shared plan files stay readable), not the temporary file's
    ``0o600``. Creates the parent directory (:func:`make_dir`). Returns ``path``."""
    path = Path(path)
    make_dir(path.parent)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "w") as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def read_json(path: str | Path, fmt: str, what: str) -> dict[str, Any]:
    """The JSON object in ``path`` whose ``format`` is ``fmt`` (``what`` names the file in
    errors, e.g. ``"plan file"``).

    Raises:
        ConfigError: Unreadable, not JSON, or another format (naming the one found).
    """
    if not isinstance(path, (str, os.PathLike)):
        raise ConfigError(what, path, f"a path to a JSON {what}")
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, RecursionError, json.JSONDecodeError) as error:
        raise ConfigError(what, str(path), f"a readable JSON {what} ({error})") from None
    if not isinstance(data, dict) or data.get("format") != fmt:
        found = data.get("format") if isinstance(data, dict) else data
        raise ConfigError(f"{path.name}: format", found, fmt)
    return data


def json_safe(value: Any, digits: int | None = None) -> Any:
    """``value`` (dicts, lists and tuples walked) with every non-finite float as ``None``,
    since JSON has no NaN; with ``digits``, finite floats rounded to that many significant
    digits (a file that reads well and stays deterministic)."""
    if isinstance(value, float):
        if not math.isfinite(value):
            return None
        return value if digits is None else float(f"{value:.{digits}g}")
    if isinstance(value, dict):
        return {key: json_safe(item, digits) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(item, digits) for item in value]
    return value
