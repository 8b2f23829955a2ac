"""The study's policies: how far the hand opens (the hand law's ``u``) on each trial.

Every policy maps what the trial knows about the object's pose error
(:class:`Evidence`) to a ``u`` in ``[0, 1]``:

- ``"0"``, ``"0.3"``, ``"0.6"``, ``"1"`` (any number in ``[0, 1]``): that fixed ``u``.
- ``"covariance"``: the project's rule
  (:func:`~openup_ompl.perception.uncertainty.u_from_covariance`), which opens the hand to
  cover :data:`~openup_ompl.perception.uncertainty.COVERAGE` standard deviations of the
  lateral pose error.
- ``"diameter"``: the paper's first candidate, the fitted superquadric's diameter ``D``
  (twice its largest half-size), mapped by ``u = clip(D / DIAMETER_FULL, 0, 1)``: the
  larger the object, the wider the hand. Without perception (direct pose error) ``D`` is
  the diameter of the object's known shape, the value a perfect fit would give.
- ``"residual"``: the paper's second candidate, the fit's mean residual ``r`` (mean
  distance of the points to the fit), read as the standard deviation of the lateral error
  it stands for: ``u = clip(COVERAGE * r / k, 0, 1)`` with ``k`` the clearance one unit
  of ``u`` buys (:func:`~openup_ompl.perception.uncertainty.clearance_per_u`). Without
  perception there is no fit and no residual: the policy then takes the known error's
  standard deviation for ``r``, and is the covariance rule for a round object.
- ``"adaptive"``: opens as far as the error needs where the fingertips first pass the
  object, and no farther than the scene lets the hand pass. The need is the covariance
  rule's cover taken at the fingertips' arrival rather than at the maximum aperture
  (``u_from_covariance(..., at_arrival=True)``): Algorithm 3 has closed the hand to a
  share of its extra opening by then (:func:`~openup_ompl.perception.uncertainty.
  arrival_fraction`, about a third on the study's Panda grasps), and a finger that lands
  on a light object pushes it away before the hand closes. The clearance is the planner's
  own coupled check (no finger or link may touch a neighbour, wall or shelf on the way
  in, in the scene as believed): when no collision-free path exists at the needed ``u``
  (the plan fails) it plans again at :data:`FALLBACK_U`, the narrowest hand the law has
  (:func:`~openup_ompl.study.run.run_trial`).
- ``"capped"``: the covariance rule's ``u``, capped before planning by the largest ``u``
  whose fingers, swept along a straight approach, are predicted to come no nearer than a
  margin to a neighbour or wall
  (:meth:`~openup_ompl.study.geometry.HandSweep.largest_safe_u`). A cheaper prediction than
  ``adaptive``'s, and a more cautious one: the planner's path need not be straight, and a
  graze the margin forbids is not a collision.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from openup_ompl.exceptions import ConfigError
from openup_ompl.perception.uncertainty import COVERAGE, clearance_per_u, u_from_covariance
from openup_ompl.scene import Problem, Shape
from openup_ompl.study.geometry import HandSweep

__all__ = [
    "DEFAULT_POLICIES",
    "DIAMETER_FULL",
    "FALLBACK_U",
    "NAMED",
    "Evidence",
    "check_policies",
    "policy_u",
    "shape_diameter",
]

#: The object diameter [m] at which the ``diameter`` policy opens fully.
DIAMETER_FULL = 0.2
#: Policies that are names, not numbers.
NAMED = ("covariance", "diameter", "residual", "capped", "adaptive")
#: The study's policies, in table order.
DEFAULT_POLICIES = (
    "0", "0.3", "0.6", "1", "covariance", "diameter", "residual", "capped", "adaptive",
)  # fmt: skip
#: The ``u`` the ``adaptive`` policy plans at when its first plan fails (unitless).
FALLBACK_U = 0.0


@dataclass(frozen=True)
class Evidence:
    """What a trial knows about its pose error, for the policies.

    Attributes:
        position_covariance: ``(3, 3)`` position covariance [m^2], world frame.
        rotation_covariance: ``(3, 3)`` rotation covariance [rad^2], world frame.
        diameter: The (fitted or known) object's diameter [m].
        residual: The fit's mean residual [m], or the known lateral error's standard
            deviation when there was no fit.
        sizes: The fitted superquadric's half-sizes [m] (``None``: the scene's shape).
        perceived: Whether the evidence came from a fit.
    """

    position_covariance: np.ndarray
    rotation_covariance: np.ndarray
    diameter: float
    residual: float
    sizes: np.ndarray | None = None
    perceived: bool = False


def shape_diameter(shape: Shape) -> float:
    """The largest extent of a scene shape (box: largest side; cylinder: the larger of
    diameter and length; sphere: diameter; mesh: largest side of its bounding box).

    Args:
        shape: The scene shape.

    Returns:
        The extent [m].
    """
    if shape.shape == "box":
        assert shape.size is not None
        return float(np.max(shape.size))
    if shape.shape == "cylinder":
        assert shape.radius is not None and shape.length is not None
        return float(max(2 * shape.radius, shape.length))
    if shape.shape == "sphere":
        assert shape.radius is not None
        return float(2 * shape.radius)
    from openup_ompl.meshes import hull_points

    assert shape.file is not None
    points = hull_points(shape.file, shape.scale or 1.0)
    return float(np.max(np.ptp(points, axis=0)))


def check_policies(policies: tuple[str, ...] | list[str]) -> tuple[str, ...]:
    """``policies`` as canonical names (a number as ``f"{u:g}"``), distinct.

    Args:
        policies: Policy names: a fixed ``u`` in ``[0, 1]`` or one of :data:`NAMED`.

    Returns:
        The canonical names, in the order given.

    Raises:
        ConfigError: An empty list, an unknown name, a number outside ``[0, 1]``, or a
            policy given twice.
    """
    if isinstance(policies, str) or not policies:
        raise ConfigError("policies", policies, f"a non-empty list of u in [0, 1] or {NAMED}")
    names = []
    for policy in policies:
        if policy in NAMED:
            names.append(policy)
            continue
        try:
            value = float(policy)
        except (TypeError, ValueError):
            value = math.nan
        if not 0 <= value <= 1:
            raise ConfigError("policy", policy, f"a u in [0, 1] or one of {list(NAMED)}")
        names.append(f"{value:g}")
    if len(set(names)) != len(names):
        raise ConfigError("policies", list(policies), "distinct policies")
    return tuple(names)


def policy_u(policy: str, evidence: Evidence, believed: Problem, safe: float | None) -> float:
    """The ``u`` of ``policy`` (canonical, :func:`check_policies`) on a trial.

    Args:
        policy: The policy's name.
        evidence: What the trial knows of its error.
        believed: The problem as believed (the object at its estimate).
        safe: ``HandSweep(believed).largest_safe_u()`` if already computed (the
            ``capped`` policy computes it otherwise).

    Returns:
        The trial's ``u`` (unitless, in ``[0, 1]``); for ``adaptive``, the ``u`` of its
        first plan (:func:`~openup_ompl.study.run.run_trial` plans again at
        :data:`FALLBACK_U` if that plan fails).
    """
    if policy not in NAMED:
        return float(policy)
    if policy == "diameter":
        return float(min(max(evidence.diameter / DIAMETER_FULL, 0.0), 1.0))
    if policy == "residual":
        k = clearance_per_u(believed)
        if evidence.residual <= 0:
            return 0.0
        return 1.0 if k <= 0 else float(min(COVERAGE * evidence.residual / k, 1.0))
    need = u_from_covariance(
        evidence.position_covariance,
        evidence.rotation_covariance,
        believed,
        sizes=evidence.sizes,
        at_arrival=policy == "adaptive",
    )
    if policy in ("covariance", "adaptive"):
        return need
    if safe is None:
        safe = HandSweep(believed).largest_safe_u()
    return float(min(need, safe))
