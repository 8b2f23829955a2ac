"""The study's statistics against known values."""

from __future__ import annotations

import pytest

from openup_ompl.exceptions import ConfigError
from openup_ompl.study.stats import mcnemar_exact, wilson_interval


def test_wilson_known_values() -> None:
    """Wilson 95 % intervals match published values (Newcombe 1998, Table I)."""
    low, high = wilson_interval(81, 263)
    assert low == pytest.approx(0.2553, abs=5e-4)
    assert high == pytest.approx(0.3662, abs=5e-4)
    low, high = wilson_interval(15, 148)
    assert low == pytest.approx(0.0624, abs=5e-4)
    assert high == pytest.approx(0.1605, abs=5e-4)


def test_wilson_edges() -> None:
    """0 of n and n of n give one-sided intervals inside [0, 1]; 0 trials is (0, 1)."""
    low, high = wilson_interval(0, 10)
    assert low == 0.0 and high == pytest.approx(0.2775, abs=5e-4)
    low, high = wilson_interval(10, 10)
    assert high == pytest.approx(1.0) and low == pytest.approx(0.7225, abs=5e-4)
    assert wilson_interval(0, 0) == (0.0, 1.0)


def test_wilson_refuses_bad_counts() -> None:
    """More successes than trials, or a negative count, is a ConfigError."""
    with pytest.raises(ConfigError):
        wilson_interval(5, 4)
    with pytest.raises(ConfigError):
        wilson_interval(-1, 4)


def test_mcnemar_exact_known_values() -> None:
    """Exact McNemar: two-sided binomial tail doubled (1 vs 9 discordant: 2 * 11/1024)."""
    assert mcnemar_exact(1, 9) == pytest.approx(2 * 11 / 1024)
    assert mcnemar_exact(9, 1) == pytest.approx(2 * 11 / 1024)
    assert mcnemar_exact(0, 5) == pytest.approx(2 / 32)
    assert mcnemar_exact(3, 3) == pytest.approx(1.0)
    assert mcnemar_exact(0, 0) == 1.0
