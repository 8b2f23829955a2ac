"""Writing files so that a reader never sees a partial one, and reading the package's
JSON formats back."""

from __future__ import annotations

import json
import math
import os
import stat
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


def resolved(path: str | Path, what: str) -> Path:
    """``path`` made absolute, its symbolic links resolved (``~`` expanded).

    Raises:
        ConfigError: Its symbolic links form a loop (naming the path), which
            :meth:`pathlib.Path.resolve` reports as a bare ``RuntimeError`` or ``OSError``.
    """
    try:
        return Path(path).expanduser().resolve()
    except (RuntimeError, OSError) as error:
        raise ConfigError(
            what, str(path), f"a path that resolves, not a loop of symbolic links ({error})"
        ) from None


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


#: The largest file the package reads [bytes]: 256 MiB, several times the largest file it
#: writes; without a bound a device such as ``/dev/zero`` was read whole into memory.
MAX_FILE_BYTES = 256 * 2**20

_KINDS = (
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISFIFO, "a named pipe"),
    (stat.S_ISSOCK, "a socket"),
)


def _cap() -> str:
    """:data:`MAX_FILE_BYTES` as errors give it."""
    cap = MAX_FILE_BYTES
    return f"{cap / 2**20:g} MiB" if cap >= 2**20 else f"{cap} bytes"


def _too_large(what: str, path: Path, size: int, read: bool = False) -> ConfigError:
    """The error for a file of ``size`` bytes over :data:`MAX_FILE_BYTES` (``read``: the
    bytes read before giving up, so at least that many)."""
    held = f"{size:,} bytes{' or more' if read else ''}"
    return ConfigError(what, str(path), f"a file of at most {_cap()} (it holds {held})")


def read_bytes(path: str | Path, what: str) -> bytes:
    """The contents of the regular file ``path``, of at most :data:`MAX_FILE_BYTES`
    (reading at most one byte more: a file growing, or one whose size the system does
    not report, is cut there); ``what`` names the file in errors (e.g. ``"plan file"``).

    Raises:
        ConfigError: ``path`` is not a regular file (a directory, a device, a pipe: it is
            refused before it is opened, since opening a pipe waits for a writer), or
            is larger than :data:`MAX_FILE_BYTES`, naming the path and its size.
        OSError: It cannot be read (missing, no permission).
    """
    path = Path(path)
    info = os.stat(path)
    if not stat.S_ISREG(info.st_mode):
        kind = next((name for test, name in _KINDS if test(info.st_mode)), "another kind of file")
        raise ConfigError(
            what,
            str(path),
            f"a regular file of at most {_cap()} (this is {kind})",
        )
    if info.st_size > MAX_FILE_BYTES:
        raise _too_large(what, path, info.st_size)
    with open(path, "rb") as stream:
        data = stream.read(MAX_FILE_BYTES + 1)
    if len(data) > MAX_FILE_BYTES:
        raise _too_large(what, path, len(data), read=True)
    return data


def read_json(path: str | Path, fmt: str, what: str) -> dict[str, Any]:
    """The JSON object in ``path`` whose ``format`` is ``fmt`` (``what`` names the file in
    errors, e.g. ``"plan file"``).

    Raises:
        ConfigError: Unreadable, not a regular file, larger than :data:`MAX_FILE_BYTES`
            (:func:`read_bytes`), not JSON, or another format (naming the one found).
    """
    if not isinstance(path, (str, os.PathLike)):
        raise ConfigError(what, path, f"a path to a JSON {what}")
    path = Path(path)
    try:
        data = json.loads(read_bytes(path, what).decode("utf-8"))
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


def json_with_rows(data: dict[str, Any], keys: tuple[str, ...]) -> str:
    """``data`` as indented JSON text, the lists of number rows at ``keys`` written one row
    a line (by the C encoder: the indented encoder is pure Python, slow on a plan's
    thousands of rows)."""
    rows = {key: data[key] for key in keys}
    marks = {key: f"@@{key}@@" for key in rows}
    text = json.dumps({**data, **marks}, indent=1, allow_nan=False)
    for key, value in rows.items():
        # Rows of numbers only: "], [" occurs between rows and nowhere else.
        lines = json.dumps(value, allow_nan=False)[1:-1].replace("], [", "],\n  [")
        text = text.replace(json.dumps(marks[key]), f"[\n  {lines}\n ]", 1)
    return text
