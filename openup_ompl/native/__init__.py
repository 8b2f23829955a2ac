"""The compiled coupled check: an optional C++ module doing
:meth:`~openup_ompl.state_check.StateChecker.is_valid` in one call (the arm joints'
placements, the palm frame, ``d``, the law's hand, the hand joints' placements, Coal's
broadphase query), on the checker's own Pinocchio data and Coal manager.

Nothing is compiled when the package is installed. ``openup-ompl build-native``
(:func:`build`) compiles ``coupled_check.cpp`` on this machine
against the headers and libraries of the pin and coal wheels in use, into a per-user
cache folder named after the exact versions (:func:`build_key`): a pin or coal upgrade
changes the name, so a stale binary is never found, let alone loaded. The module works
on the Python objects' C++ types in place, so it may only run with the very builds it
was compiled against: :func:`load` also compares the versions the binary records
(``built_with``) with the ones running and refuses a mismatch.

The checkers' ``native`` option (:data:`NATIVE_MODES`) chooses: ``"auto"`` (the
default) uses the compiled check when a matching binary is built and it is exact for
the law, else the Python check; ``"on"`` raises
:class:`~openup_ompl.exceptions.NativeUnavailable` instead of falling back; ``"off"``
never uses it. It is exact (the same verdicts, the same ``d`` bit for bit) for the
``"translation"`` distance and for a fixed hand; with the ``"weighted"`` distance its
``d`` may differ from Python's in the last bits, so ``"auto"`` keeps the Python check.
The compiled check places the arm joints, reads ``d``, then places the hand joints: one
forward kinematics per state wherever it lies, so it needs no
:data:`~openup_ompl.state_check.NEAR_HINT` ordering. Built and tested on Linux (x86-64,
g++); other platforms' wheels lay their libraries out differently and are untested.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import importlib.util
import json
import os
import sys
import sysconfig
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any

import coal
import pinocchio as pin

from openup_ompl.exceptions import ConfigError, NativeUnavailable
from openup_ompl.urdf import cache_dir

if TYPE_CHECKING:
    from openup_ompl.collision import CollisionWorld
    from openup_ompl.hand_law import HandLaw
    from openup_ompl.state_check import StateChecker

__all__ = [
    "BUILD_COMMAND",
    "CXXFLAGS",
    "DIR_VARIABLE",
    "KEY_DISTRIBUTIONS",
    "MODULE_NAME",
    "NATIVE_MODES",
    "SOURCE",
    "binary_path",
    "build",
    "build_key",
    "check_built_with",
    "check_mode",
    "compiled_check",
    "inexact_reason",
    "law_table",
    "load",
    "native_dir",
    "resolve",
    "status",
]

#: The values of the checkers' ``native`` option: ``"auto"`` uses the compiled check when
#: it is built for the versions in use and exact for the law (else the Python check),
#: ``"on"`` raises :class:`~openup_ompl.exceptions.NativeUnavailable` when it cannot be
#: used, ``"off"`` never uses it.
NATIVE_MODES = ("auto", "on", "off")
#: The C++ source, shipped in the package.
SOURCE = Path(__file__).resolve().parent / "coupled_check.cpp"
#: The module's name (its ``PyInit_`` function).
MODULE_NAME = "_coupled_check"
#: How to build it.
BUILD_COMMAND = "openup-ompl build-native"
#: The compiler flags (beside the include and library paths). The ``BOOST_MPL_LIMIT_*``
#: and ``PINOCCHIO_*`` definitions are those of pinocchio's and coal's CMake targets: they
#: fix the joint variant's layout, which must match the wheels'.
CXXFLAGS: tuple[str, ...] = (
    "-std=c++17",
    "-O3",
    "-ffp-contract=off",
    "-fPIC",
    "-shared",
    "-fvisibility=hidden",
    "-DBOOST_MPL_LIMIT_LIST_SIZE=30",
    "-DBOOST_MPL_LIMIT_VECTOR_SIZE=30",
    "-DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS",
    "-DBOOST_FUSION_INVOKE_MAX_ARITY=12",
    "-DPINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION",
    "-DPINOCCHIO_WITH_COLLISION",
    "-DPINOCCHIO_WITH_HPP_FCL",
    "-DCOAL_BACKWARD_COMPATIBILITY_WITH_HPP_FCL",
    "-DCOAL_HAS_OCTOMAP",
    "-DCOAL_HAVE_OCTOMAP",
    "-DOCTOMAP_MAJOR_VERSION=1",
    "-DOCTOMAP_MINOR_VERSION=10",
    "-DOCTOMAP_PATCH_VERSION=0",
    "-DNDEBUG",
)
#: The distributions whose exact versions key a build (the C++ libraries and headers the
#: module is compiled against, and the boost.python that converts their objects).
KEY_DISTRIBUTIONS = ("pin", "libpinocchio", "coal", "libcoal", "cmeel-boost", "eigenpy")
#: Environment variable naming the folder of builds (default: ``native`` in the cache).
DIR_VARIABLE = "OPENUP_OMPL_NATIVE_DIR"

_MODULES: dict[Path, ModuleType] = {}


def native_dir() -> Path:
    """The folder of the compiled builds: ``$OPENUP_OMPL_NATIVE_DIR``, else ``native``
    in the package's cache (:func:`~openup_ompl.urdf.cache_dir`).

    Returns:
        The folder (not created here).
    """
    given = os.environ.get(DIR_VARIABLE)
    return Path(given).expanduser() if given else cache_dir() / "native"


def _distribution_version(name: str) -> str:
    try:
        return importlib.metadata.version(name)
    except importlib.metadata.PackageNotFoundError:
        return "none"


@functools.lru_cache(maxsize=1)
def build_key() -> dict[str, str]:
    """What a build is valid for: the Python ABI, the versions of pinocchio and coal
    (their modules' and their distributions', :data:`KEY_DISTRIBUTIONS`) and a digest of
    the source and flags.

    Returns:
        ``name -> version`` strings.
    """
    source = SOURCE.read_bytes() + json.dumps(CXXFLAGS).encode()
    key = {
        "python": sys.implementation.cache_tag,
        "abi": str(sysconfig.get_config_var("EXT_SUFFIX")),
        "pinocchio": pin.__version__,
        "coal": coal.__version__,
        "source": hashlib.sha256(source).hexdigest()[:16],
    }
    key.update({f"dist:{name}": _distribution_version(name) for name in KEY_DISTRIBUTIONS})
    return key


def binary_path(directory: Path | None = None) -> Path:
    """Where the build for the versions in use is (or would be).

    Args:
        directory: The folder of builds (default :func:`native_dir`).

    Returns:
        ``<directory>/<python>-pin<version>-coal<version>-<digest>/_coupled_check<suffix>``.
    """
    key = build_key()
    digest = hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:12]
    name = f"{key['python']}-pin{key['pinocchio']}-coal{key['coal']}-{digest}"
    root = native_dir() if directory is None else Path(directory)
    return root / name / f"{MODULE_NAME}{key['abi']}"


def check_built_with(module: Any) -> None:
    """Refuse a compiled module built against other pinocchio or coal versions than the
    running ones (its ``built_with``): it would read their objects with another layout.

    Args:
        module: The loaded module.

    Raises:
        NativeUnavailable: The versions differ (or the module records none).
    """
    running = {"pinocchio": pin.__version__, "coal": coal.__version__}
    recorded = getattr(module, "built_with", None)
    built = {name: recorded.get(name) for name in running} if isinstance(recorded, dict) else None
    if built != running:
        raise NativeUnavailable(
            f"it was built against {built}, not the running {running}",
            f"rebuild it: {BUILD_COMMAND} --force",
        )


def load(directory: Path | None = None) -> ModuleType:
    """The compiled module built for the versions in use (loaded once per process).

    Args:
        directory: The folder of builds (default :func:`native_dir`).

    Returns:
        The module (``CoupledCheck``, ``built_with``).

    Raises:
        NativeUnavailable: Not built for these versions, not loadable, or built against
            other versions of pinocchio or coal.
    """
    path = binary_path(directory)
    module = _MODULES.get(path)
    if module is None:
        if not path.is_file():
            key = build_key()
            raise NativeUnavailable(
                f"it is not built for pinocchio {key['pinocchio']}, coal {key['coal']} and "
                f"{key['python']} (no {path})",
                f"build it: {BUILD_COMMAND}",
            )
        try:
            spec = importlib.util.spec_from_file_location(MODULE_NAME, path)
            assert spec is not None and spec.loader is not None
            module = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(module)
        except ImportError as error:
            raise NativeUnavailable(
                f"{path} does not load ({error})", f"rebuild it: {BUILD_COMMAND} --force"
            ) from None
        _MODULES[path] = module
    check_built_with(module)
    return module


def inexact_reason(law: HandLaw) -> str | None:
    """Why the compiled check would not be exact for ``law``, or ``None`` when it is
    (a fixed hand, or the ``"translation"`` distance: the same verdicts and ``d``).

    With the ``"weighted"`` distance the compiled ``d`` may differ from Python's in its
    last bits (Python's rotation product goes through numpy), and a state with ``d`` at
    ``mga`` could then get another hand.
    """
    if law.fixed_clipped is None and law.distance != "translation":
        return f"the law's {law.distance!r} distance (d may differ from Python's in the last bits)"
    return None


def check_mode(mode: object) -> None:
    """Refuse a ``native`` option that is not one of :data:`NATIVE_MODES`.

    Args:
        mode: The option's value.

    Raises:
        ConfigError: It is not one of them.
    """
    if not isinstance(mode, str) or mode not in NATIVE_MODES:
        raise ConfigError("native", mode, f"one of {list(NATIVE_MODES)}")


def resolve(mode: str, law: HandLaw) -> ModuleType | None:
    """The compiled module a checker with option ``native=mode`` uses for ``law``.

    Args:
        mode: One of :data:`NATIVE_MODES`.
        law: The checker's hand law.

    Returns:
        The module, or ``None`` for the Python check (``"off"``, or ``"auto"`` when it is
        not built for the versions in use or not exact for ``law``).

    Raises:
        ConfigError: ``mode`` is not one of :data:`NATIVE_MODES`.
        NativeUnavailable: ``mode`` is ``"on"`` and the compiled check cannot be used.
    """
    check_mode(mode)
    if mode == "off":
        return None
    try:
        reason = inexact_reason(law)
        if reason is not None:
            raise NativeUnavailable(f"it is not exact for {reason}", "use native='auto' or 'off'")
        return load()
    except NativeUnavailable:
        if mode == "on":
            raise
        return None


def status(directory: Path | None = None) -> tuple[bool, str]:
    """Whether the compiled check is built and loadable for the versions in use, and a
    line saying so (where, or why not).

    Args:
        directory: The folder of builds (default :func:`native_dir`).
    """
    try:
        load(directory)
    except NativeUnavailable as error:
        return False, str(error)
    return True, f"the compiled coupled check is built: {binary_path(directory)}"


def law_table(checker: StateChecker) -> dict[str, Any]:
    """The law and Algorithm 1's distance as the compiled check takes them: the affine
    form of :class:`~openup_ompl.hand_law.HandLaw` and the checker's grasp and start."""
    law = checker.law
    grasp = checker.problem.grasp
    weighted = law.distance == "weighted"
    return {
        "mga": law.mga,
        "arrival": law.arrival.tolist(),
        "low_slope": law.low_slope.tolist(),
        "high": law.high.tolist(),
        "clip_low": law.clip_low,
        "lower": law.lower.tolist(),
        "upper": law.upper.tolist(),
        "fixed": None if law.fixed_clipped is None else law.fixed_clipped.tolist(),
        "goal": grasp.translation.tolist(),
        "goal_rotation_t": grasp.rotation.T.reshape(-1).tolist() if weighted else None,
        "rotation_weight": law.rotation_weight,
        "inv_start": 1.0 / checker.goal_distance.start_distance,
    }


def compiled_check(module: ModuleType, checker: StateChecker, world: CollisionWorld) -> Any:
    """A compiled check on the calling thread's context of ``world`` (its Pinocchio data
    and Coal manager), with the checker's law, grasp and start.

    Args:
        module: The compiled module (:func:`load`).
        checker: The checker whose law, grasp and robot to use.
        world: One of the checker's worlds.

    Returns:
        A ``CoupledCheck``: ``is_valid(arm)`` for any sequence of floats, ``distance``
        (``d`` at the last state checked, ``inf`` for a fixed hand), ``distance_q(q)``
        (``d`` at a full configuration) and ``collides_columns(qs, stop_at_first)``.
    """
    context = world.context()
    robot = checker.robot
    return module.CoupledCheck(
        context.data,
        context.manager,
        robot.arm_idx.tolist(),
        robot.hand_idx.tolist(),
        robot.palm_frame_id,
        context.q.tolist(),
        law_table(checker),
    )


# After the names it imports from here.
from openup_ompl.native._build import build  # noqa: E402
