"""Building the compiled coupled check: one ``c++`` call against the pin and coal wheels'
headers and libraries (their ``cmeel.prefix``) and Eigen's headers, which no runtime
wheel ships (PyPI's ``cmeel-eigen``, installed beside the builds on first use)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from collections.abc import Callable
from pathlib import Path

import pinocchio as pin

from openup_ompl.exceptions import NativeBuildError
from openup_ompl.native import (
    BUILD_COMMAND,
    CXXFLAGS,
    SOURCE,
    binary_path,
    build_key,
    native_dir,
)

#: The Eigen PyPI ships for cmeel (headers only), pinocchio's wheels' series.
EIGEN_REQUIREMENT = "cmeel-eigen>=3.4,<3.5"
#: Longest wait [s] for pip to fetch Eigen, and for the compiler.
PIP_TIMEOUT = 300.0
COMPILE_TIMEOUT = 1800.0
#: Lines of a failed tool's output quoted in the error.
TAIL_LINES = 12


def _tail(text: str) -> str:
    lines = [line for line in text.strip().splitlines() if line.strip()]
    return " | ".join(lines[-TAIL_LINES:]) or "no output"


def _compiler(compiler: str | None) -> str:
    """The C++ compiler: ``compiler``, else ``$CXX``, else ``c++``, ``g++`` or ``clang++``."""
    given = compiler or os.environ.get("CXX")
    names = [given] if given else ["c++", "g++", "clang++"]
    for name in names:
        found = shutil.which(name)
        if found:
            return found
    raise NativeBuildError(
        "compiler",
        f"no C++ compiler found (tried {names})",
        "install a C++17 compiler (Debian/Ubuntu: apt install g++) or pass --cxx PATH",
    )


def wheel_prefix() -> Path:
    """The ``cmeel.prefix`` of the pin and coal wheels in use (headers and libraries).

    Raises:
        NativeBuildError: Pinocchio was not installed from the PyPI wheels (no prefix
            with pinocchio's and coal's headers and libraries beside it).
    """
    prefix = Path(pin.__file__).resolve().parents[4]
    python = f"{sys.version_info[0]}{sys.version_info[1]}"
    needed = [
        prefix / "include" / "pinocchio" / "multibody.hpp",
        prefix / "include" / "coal" / "config.hh",
        prefix / "include" / "boost" / "python.hpp",
        prefix / "lib" / "libpinocchio_default.so",
        prefix / "lib" / "libpinocchio_collision.so",
        prefix / "lib" / "libcoal.so",
        prefix / "lib" / f"libboost_python{python}.so",
    ]
    missing = [str(path) for path in needed if not path.is_file()]
    if missing:
        raise NativeBuildError(
            "headers",
            f"the pinocchio in use ({pin.__file__}) has no {missing[0]}"
            + (f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""),
            "the compiled check builds only against the pin and coal wheels from PyPI "
            "(pip install pin coal)",
        )
    return prefix


def eigen_include(eigen: Path | None, directory: Path) -> Path:
    """A folder holding ``Eigen/Core``: ``eigen`` if given, else cmeel-eigen's beside the
    wheels or beside the builds, else cmeel-eigen installed there now with pip.

    Raises:
        NativeBuildError: ``eigen`` holds no Eigen, or pip could not fetch it.
    """
    if eigen is not None:
        if not (Path(eigen) / "Eigen" / "Core").is_file():
            raise NativeBuildError(
                "eigen", f"{eigen} holds no Eigen/Core", "pass the folder that holds Eigen/"
            )
        return Path(eigen)
    target = directory / "eigen"
    for prefix in (wheel_prefix(), target / "cmeel.prefix"):
        candidate = prefix / "include" / "eigen3"
        if (candidate / "Eigen" / "Core").is_file():
            return candidate
    command = [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps"]
    command += ["--target", str(target), EIGEN_REQUIREMENT]
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=PIP_TIMEOUT)
    except (OSError, subprocess.TimeoutExpired) as error:
        done = subprocess.CompletedProcess(command, 1, "", str(error))
    candidate = target / "cmeel.prefix" / "include" / "eigen3"
    if done.returncode != 0 or not (candidate / "Eigen" / "Core").is_file():
        raise NativeBuildError(
            "eigen",
            f"pip could not install {EIGEN_REQUIREMENT} into {target}: {_tail(done.stderr)}",
            "check the network (PyPI), or pass --eigen DIR, a folder holding Eigen/Core "
            "(Eigen 3.4, e.g. /usr/include/eigen3)",
        )
    return candidate


def compile_command(compiler: str, prefix: Path, eigen: Path, output: Path) -> list[str]:
    """The compiler's command line for the module (:data:`~openup_ompl.native.CXXFLAGS`)."""
    python = f"{sys.version_info[0]}{sys.version_info[1]}"
    include = str(sysconfig.get_paths()["include"])
    return [
        compiler,
        *CXXFLAGS,
        "-isystem",
        str(prefix / "include"),
        "-isystem",
        str(eigen),
        "-isystem",
        include,
        str(SOURCE),
        "-o",
        str(output),
        f"-L{prefix / 'lib'}",
        f"-Wl,-rpath,{prefix / 'lib'}",
        "-lpinocchio_collision",
        "-lpinocchio_default",
        "-lcoal",
        f"-lboost_python{python}",
    ]


def _verify(path: Path) -> None:
    """Load the new module in a fresh interpreter (so a crash cannot take this one down,
    nor an older module loaded here hide it) and check its recorded versions."""
    code = (
        "import sys; from pathlib import Path; from openup_ompl import native; "
        "native.load(Path(sys.argv[1]))"
    )
    env = dict(os.environ)
    package_root = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [package_root, env.get("PYTHONPATH")]))
    done = subprocess.run(
        [sys.executable, "-c", code, str(path.parent.parent)],
        capture_output=True,
        text=True,
        env=env,
        timeout=PIP_TIMEOUT,
    )
    if done.returncode != 0:
        path.unlink(missing_ok=True)
        raise NativeBuildError(
            "load", f"the module built but does not load: {_tail(done.stderr)}", "report it"
        )


def build(
    directory: Path | None = None,
    *,
    force: bool = False,
    compiler: str | None = None,
    eigen: Path | None = None,
    log: Callable[[str], None] = print,
) -> Path:
    """Compile the coupled check for the pinocchio, coal and Python in use.

    Takes about 20 s of one core and 2 GB of memory; the first build downloads Eigen's
    headers (PyPI's ``cmeel-eigen``, 1 MB) unless ``eigen`` is given. Nothing is written
    outside ``directory``; the module appears there atomically, only once it loads.

    Args:
        directory: The folder of builds (default :func:`~openup_ompl.native.native_dir`).
        force: Build again even if a build for these versions exists.
        compiler: The C++17 compiler (default ``$CXX``, else ``c++``).
        eigen: A folder holding Eigen 3.4's ``Eigen/Core`` (default: cmeel-eigen).
        log: Where progress lines go.

    Returns:
        The path of the module.

    Raises:
        NativeBuildError: No compiler, not the PyPI wheels of pin and coal, no Eigen (no
            network), a compile error, or a module that does not load.
    """
    root = native_dir() if directory is None else Path(directory)
    path = binary_path(root)
    key = build_key()
    if path.is_file() and not force:
        log(f"already built for pinocchio {key['pinocchio']}, coal {key['coal']}: {path}")
        return path
    log("[1/4] compiler")
    cxx = _compiler(compiler)
    log(f"      {cxx}")
    log("[2/4] pinocchio's and coal's headers and libraries")
    prefix = wheel_prefix()
    log(f"      {prefix} (pinocchio {key['pinocchio']}, coal {key['coal']})")
    log("[3/4] Eigen's headers")
    eigen_dir = eigen_include(eigen, root)
    log(f"      {eigen_dir}")
    log("[4/4] compiling (about 20 s of one core and 2 GB of memory)")
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(suffix=path.suffix, prefix=".building-", dir=path.parent)
    os.close(handle)
    partial = Path(temporary)
    command = compile_command(cxx, prefix, eigen_dir, partial)
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=COMPILE_TIMEOUT)
    except (OSError, subprocess.TimeoutExpired) as error:
        done = subprocess.CompletedProcess(command, 1, "", str(error))
    if done.returncode != 0:
        partial.unlink(missing_ok=True)
        raise NativeBuildError(
            "compile",
            f"{command[0]} exited with status {done.returncode}: {_tail(done.stderr)}",
            f"a C++17 compiler is needed (--cxx); run {BUILD_COMMAND} again after fixing it",
        )
    os.replace(partial, path)
    (path.parent / "key.json").write_text(json.dumps(key, indent=1, sort_keys=True) + "\n")
    log("      checking that it loads")
    _verify(path)
    log(f"built: {path}")
    return path
