"""The hand law: Algorithm 3 (open_hand, HandLaw) and Algorithm 1 (GoalDistance)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pytest

import openup_ompl as ou

# Referential configurations of a made-up two-joint hand, chosen so that every expected
# value below is easy to compute by hand: b - c = [0.5, 0.5], w - c = [1, 1],
# w - b = [0.5, 0.5].
C = [0.0, 1.0]
B = [0.5, 1.5]
W = [1.0, 2.0]
MGA = 0.25
EPS = 1e-12  # "just below" / "just above" mga

# (u, d, expected) for the paper's law, Algorithm 3 as printed:
#   d <= mga: c + (d / mga) * ((b - c) + (w - c) * u);   d > mga: b + (w - b) * u
PAPER_VALUES = [
    # u = 0: c -> b linearly, then b.
    (0.0, 0.0, [0.0, 1.0]),
    (0.0, 0.1, [0.2, 1.2]),  # 0.4 * 0.5
    (0.0, MGA - EPS, [0.5, 1.5]),
    (0.0, MGA, [0.5, 1.5]),
    (0.0, MGA + EPS, [0.5, 1.5]),
    (0.0, 1.0, [0.5, 1.5]),
    (0.0, 2.0, [0.5, 1.5]),
    # u = 1: slope (b - c) + (w - c) = 1.5 per unit d / mga; plateau w.
    (1.0, 0.0, [0.0, 1.0]),
    (1.0, 0.1, [0.6, 1.6]),  # 0.4 * 1.5
    (1.0, MGA - EPS, [1.5, 2.5]),
    (1.0, MGA, [1.5, 2.5]),
    (1.0, MGA + EPS, [1.0, 2.0]),
    (1.0, 1.0, [1.0, 2.0]),
    (1.0, 2.0, [1.0, 2.0]),
    # u = 0.3: slope 0.5 + 0.3 = 0.8; plateau b + 0.5 * 0.3 = b + 0.15.
    (0.3, 0.0, [0.0, 1.0]),
    (0.3, 0.1, [0.32, 1.32]),  # 0.4 * 0.8
    (0.3, MGA - EPS, [0.8, 1.8]),
    (0.3, MGA, [0.8, 1.8]),
    (0.3, MGA + EPS, [0.65, 1.65]),
    (0.3, 1.0, [0.65, 1.65]),
    (0.3, 2.0, [0.65, 1.65]),
]

# (u, d, expected) for continuous=True: below mga c + (d / mga) * ((b - c) + (w - b) * u).
CONTINUOUS_VALUES = [
    (0.0, 0.1, [0.2, 1.2]),
    (0.0, MGA, [0.5, 1.5]),
    (0.0, 2.0, [0.5, 1.5]),
    (1.0, 0.0, [0.0, 1.0]),
    (1.0, 0.1, [0.4, 1.4]),  # 0.4 * (0.5 + 0.5)
    (1.0, MGA - EPS, [1.0, 2.0]),
    (1.0, MGA, [1.0, 2.0]),
    (1.0, MGA + EPS, [1.0, 2.0]),
    (1.0, 2.0, [1.0, 2.0]),
    (0.3, 0.1, [0.26, 1.26]),  # 0.4 * (0.5 + 0.15)
    (0.3, MGA - EPS, [0.65, 1.65]),
    (0.3, MGA, [0.65, 1.65]),
    (0.3, MGA + EPS, [0.65, 1.65]),
    (0.3, 1.0, [0.65, 1.65]),
]

# (u, d, expected) for open_arrival=True: arrival c_u = c + (w - c) u, plateau
# b_u = b + (w - b) u, and c_u + (d / mga) * (b_u - c_u) in between.
OPEN_ARRIVAL_VALUES = [
    (0.0, 0.1, [0.2, 1.2]),  # u = 0: the paper's law
    (0.3, 0.0, [0.3, 1.3]),  # c_u = c + 0.3
    (0.3, 0.1, [0.44, 1.44]),  # 0.3 + 0.4 * (0.65 - 0.3)
    (0.3, MGA, [0.65, 1.65]),
    (0.3, MGA + EPS, [0.65, 1.65]),
    (1.0, 0.0, [1.0, 2.0]),  # arrives at w
    (1.0, 0.1, [1.0, 2.0]),
    (1.0, 2.0, [1.0, 2.0]),
]


@pytest.mark.parametrize(("u", "d", "expected"), OPEN_ARRIVAL_VALUES)
def test_open_hand_open_arrival_matches_hand_computed_values(u, d, expected):
    """open_hand(open_arrival=True) reaches the grasp at c + (w - c) u, computed by hand."""
    hand = ou.open_hand(d, C, B, W, u, MGA, open_arrival=True)
    np.testing.assert_allclose(hand, expected, rtol=0, atol=1e-9)


@pytest.mark.parametrize(("u", "d", "expected"), PAPER_VALUES)
def test_open_hand_matches_hand_computed_values(u, d, expected):
    """open_hand gives the paper's Algorithm 3 values, computed by hand."""
    hand = ou.open_hand(d, C, B, W, u, MGA)
    assert isinstance(hand, np.ndarray)
    np.testing.assert_allclose(hand, expected, rtol=0, atol=1e-9)


@pytest.mark.parametrize(("u", "d", "expected"), CONTINUOUS_VALUES)
def test_open_hand_continuous_matches_hand_computed_values(u, d, expected):
    """open_hand(continuous=True) gives the jump-free variant's values, computed by hand."""
    hand = ou.open_hand(d, C, B, W, u, MGA, continuous=True)
    np.testing.assert_allclose(hand, expected, rtol=0, atol=1e-9)


@pytest.mark.parametrize("u", [0.0, 0.3, 1.0])
def test_open_hand_jump_at_mga_is_b_minus_c_times_u(u):
    """The paper's law jumps by (b - c) * u when d crosses mga."""
    below = ou.open_hand(MGA - EPS, C, B, W, u, MGA)
    above = ou.open_hand(MGA + EPS, C, B, W, u, MGA)
    expected = (np.array(B) - np.array(C)) * u
    np.testing.assert_allclose(below - above, expected, rtol=0, atol=1e-9)


@pytest.mark.parametrize("u", [0.0, 0.3, 1.0])
def test_open_hand_continuous_has_no_jump_at_mga(u):
    """With continuous=True the law is continuous at d = mga."""
    below = ou.open_hand(MGA - EPS, C, B, W, u, MGA, continuous=True)
    above = ou.open_hand(MGA + EPS, C, B, W, u, MGA, continuous=True)
    np.testing.assert_allclose(below, above, rtol=0, atol=1e-9)


def test_open_hand_accepts_mga_one():
    """mga = 1 (the upper end of (0, 1]) is accepted: d = 1 is then on the rising branch."""
    np.testing.assert_allclose(ou.open_hand(1.0, C, B, W, 0.3, 1.0), [0.8, 1.8], atol=1e-12)


@pytest.mark.parametrize(
    ("changes", "where", "shown"),
    [
        ({"u": -0.1}, "u", "-0.1"),
        ({"u": 1.5}, "u", "1.5"),
        ({"u": math.nan}, "u", "nan"),
        ({"mga": 0.0}, "mga", "0.0"),
        ({"mga": 1.5}, "mga", "1.5"),
        ({"mga": "x"}, "mga", "'x'"),
        ({"u": "0.3"}, "u", "'0.3'"),
        ({"u": True}, "u", "True"),
        ({"continuous": "no"}, "continuous", "'no'"),  # a non-empty string is truthy
        ({"open_arrival": "no"}, "open_arrival", "'no'"),
        ({"d": -0.1}, "d", "-0.1"),
        ({"d": math.nan}, "d", "nan"),
        ({"d": "abc"}, "d", "'abc'"),
        ({"c": [math.nan, 0.0]}, "c", "nan"),
        ({"c": [0.0, 1.0, 2.0]}, "c, b, w", "(3,)"),
        ({"w": [1.0]}, "c, b, w", "(1,)"),
    ],
)
def test_open_hand_rejects_bad_input_with_config_error(changes, where, shown):
    """Bad u, mga, d or mismatched lengths raise ConfigError (a ValueError) naming the value."""
    args = {"d": 0.1, "c": C, "b": B, "w": W, "u": 0.3, "mga": MGA, **changes}
    with pytest.raises(ou.ConfigError) as info:
        ou.open_hand(**args)
    assert isinstance(info.value, ValueError)
    assert info.value.where == where
    assert str(info.value).startswith(f"{where}: ")
    assert shown in str(info.value)


def test_hand_law_clips_to_the_joint_limits(panda):
    """HandLaw clips the law to the hand joints' limits: at u = 1 Algorithm 3's jump
    opens the Panda to b + (w - c) = 0.055 m just below mga, past its 0.04 m limit."""
    law = panda.hand_law(u=1.0)
    upper = panda.model.upperPositionLimit[panda.hand_idx]
    lower = panda.model.lowerPositionLimit[panda.hand_idx]
    np.testing.assert_allclose(upper, [0.04, 0.04])
    raw = ou.open_hand(law.mga, law.c, law.b, law.w, law.u, law.mga)
    assert np.all(raw > upper)
    for d in [0.0, 0.1, law.mga - EPS, law.mga, 0.5, 1.0, 2.0]:
        raw = ou.open_hand(d, law.c, law.b, law.w, law.u, law.mga)
        hand = law(d)
        np.testing.assert_allclose(hand, np.clip(raw, lower, upper), atol=1e-12)
        assert np.all(hand <= upper) and np.all(hand >= lower)
    np.testing.assert_allclose(law(law.mga), upper)


@pytest.mark.parametrize(
    ("changes", "named"),
    [
        ({"c": [-0.01, -0.01]}, "hand.c"),
        ({"w": [0.05, 0.05]}, "hand.w"),
        ({"b": [1e300, 1e300]}, "hand.b"),  # crashed OMPL's setup with a traceback
        ({"fixed": [0.03, 0.05]}, "hand.fixed"),
    ],
)
def test_reference_beyond_a_joint_limit_is_refused(panda, changes, named):
    """c, b, w or a fixed hand beyond a hand joint's limit is a ConfigError naming it and
    the limit (it was clipped silently: a 0.5 m close preshape planned as 0.04)."""
    with pytest.raises(ou.ConfigError, match=named) as info:
        panda.hand_law(**changes)
    assert "[0, 0.04]" in str(info.value)


@pytest.mark.parametrize("variant", ["paper", "continuous", "open_arrival"])
@pytest.mark.parametrize("u", [0.0, 0.3, 1.0])
def test_hand_law_equals_clipped_open_hand(panda, u, variant):
    """HandLaw(d) equals open_hand(d) with the same parameters, clipped to the limits."""
    options = {"continuous": variant == "continuous", "open_arrival": variant == "open_arrival"}
    law = panda.hand_law(u=u, **options)
    for d in [0.0, 0.05, law.mga - EPS, law.mga, law.mga + EPS, 0.7, 1.0, 1.5]:
        raw = ou.open_hand(d, law.c, law.b, law.w, u, law.mga, **options)
        expected = np.clip(raw, law.lower, law.upper)
        np.testing.assert_allclose(law(d), expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("u", [0.3, 1.0])
def test_hand_law_batch_equals_per_distance_calls(panda, u):
    """HandLaw.batch(ds) row i equals HandLaw(ds[i]), clipped (u = 1) or not;
    HandLaw.columns is its transpose."""
    law = panda.hand_law(u=u)
    ds = np.array([0.0, 0.01, 0.1, law.mga - EPS, law.mga, law.mga + EPS, 0.5, 1.0, 3.0])
    rows = law.batch(ds)
    assert rows.shape == (ds.size, law.size)
    for d, row in zip(ds, rows, strict=True):
        np.testing.assert_array_equal(row, law(d))
    np.testing.assert_array_equal(law.columns(ds), rows.T)


def test_hand_law_fixed_keeps_the_hand_constant(panda):
    """With fixed= the hand stays at that configuration whatever d."""
    law = panda.hand_law(u=1.0, fixed=[0.03, 0.04])
    ds = np.array([0.0, 0.1, law.mga, 0.9, 2.0])
    expected = [0.03, 0.04]
    for d in ds:
        np.testing.assert_allclose(law(d), expected)
    np.testing.assert_allclose(law.batch(ds), np.tile(expected, (ds.size, 1)))
    np.testing.assert_allclose(law.columns(ds), np.tile(expected, (ds.size, 1)).T)


def test_hand_law_rejects_u_out_of_range(panda):
    """HandLaw validates u like open_hand does."""
    with pytest.raises(ou.ConfigError, match="1.5"):
        panda.hand_law(u=1.5)


@pytest.mark.parametrize("d", [math.nan, -5.0, math.inf])
def test_hand_law_rejects_a_bad_distance(panda, d):
    """A NaN, negative or infinite d is refused, not clipped into a hand."""
    law = panda.hand_law()
    with pytest.raises(ou.ConfigError, match="^d: "):
        law(d)
    with pytest.raises(ou.ConfigError, match="^d: "):
        law.batch(np.array([0.1, d]))


def test_open_hand_accepts_a_small_mga_a_hand_law_refuses_it(panda):
    """open_hand is Algorithm 3 for any mga in (0, 1]; a HandLaw, which plans, needs
    mga >= MGA_MIN (below it one motion check would not end)."""
    np.testing.assert_allclose(ou.open_hand(0.0, C, B, W, 0.3, 1e-9), C)
    with pytest.raises(ou.ConfigError, match="hand.mga"):
        panda.hand_law(mga=1e-9)


def test_hand_law_rejects_crossed_limits(panda):
    law = panda.hand_law()
    with pytest.raises(ou.ConfigError, match="lower <= upper"):
        dataclasses.replace(law, lower=law.upper + 0.01, upper=law.lower)


GRASP = pin.SE3(pin.rpy.rpyToMatrix(math.pi, 0.0, 0.0), np.array([0.6, 0.0, 0.2]))
START = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.5, 0.3), np.array([0.3, 0.4, 0.6]))


@pytest.mark.parametrize("distance", ["translation", "weighted"])
def test_goal_distance_is_one_at_start_and_zero_at_grasp(distance):
    """Algorithm 1: d is 1 at the start placement and 0 at the grasp."""
    goal_distance = ou.GoalDistance(GRASP, START, distance=distance)
    assert goal_distance(START) == pytest.approx(1.0, abs=1e-12)
    assert goal_distance(GRASP) == pytest.approx(0.0, abs=1e-12)


def test_goal_distance_translation_is_euclidean_and_normalised():
    """The translation distance is |p - p_goal| / |p_start - p_goal|, rotation ignored."""
    goal_distance = ou.GoalDistance(GRASP, START)
    start_distance = np.linalg.norm(START.translation - GRASP.translation)
    assert goal_distance.start_distance == pytest.approx(start_distance)
    halfway = pin.SE3(START.rotation, 0.5 * (START.translation + GRASP.translation))
    assert goal_distance(halfway) == pytest.approx(0.5)
    rotated_at_goal = pin.SE3(START.rotation, GRASP.translation.copy())
    assert goal_distance(rotated_at_goal) == pytest.approx(0.0, abs=1e-12)


def test_goal_distance_weighted_counts_rotation():
    """The weighted distance is positive at the grasp position with another orientation."""
    goal_distance = ou.GoalDistance(GRASP, START, distance="weighted", rotation_weight=0.1)
    rotated_at_goal = pin.SE3(
        GRASP.rotation @ pin.rpy.rpyToMatrix(0.0, 0.0, 0.5), GRASP.translation
    )
    expected = 0.1 * 0.5 / goal_distance.start_distance
    assert goal_distance(rotated_at_goal) == pytest.approx(expected, rel=1e-9)


def test_goal_distance_rejects_start_at_the_grasp():
    """A start whose palm is on the grasp pose cannot normalise d: ConfigError."""
    with pytest.raises(ou.ConfigError, match="start"):
        ou.GoalDistance(GRASP, GRASP)


@pytest.mark.parametrize("weight", [-10.0, math.nan, "x"])
def test_normalized_distance_names_a_bad_rotation_weight(weight):
    """A negative, NaN or non-number rotation weight is named (a negative one blamed the
    start, as if it were at the grasp)."""
    start = pin.SE3(np.eye(3), np.array([0.5, 0.0, 0.5]))
    with pytest.raises(ou.ConfigError, match="rotation_weight"):
        ou.NormalizedDistance(pin.SE3.Identity(), start, "weighted", weight)


def test_law_refuses_distances_it_cannot_read():
    """The law at a non-number, or a batch that is not a vector, is a ConfigError naming
    ``d`` (a string was a TypeError; a matrix came back with a shape the docs do not
    give)."""
    law = ou.load_scene(ou.default_scene_path()).hand_law
    for bad in ("a", None, float("nan"), -0.1):
        with pytest.raises(ou.ConfigError, match="^d: "):
            law(bad)  # type: ignore[arg-type]
    with pytest.raises(ou.ConfigError, match="a vector"):
        law.batch(np.ones((2, 3)))
    assert law.batch([0.1, 0.5]).shape == (2, law.size)
