"""Statistics of the study: Wilson intervals on rates, the exact McNemar test on pairs."""

from __future__ import annotations

import math

from openup_ompl.exceptions import ConfigError

__all__ = ["Z95", "mcnemar_exact", "wilson_interval"]

#: The standard normal quantile of a two-sided 95 % interval.
Z95 = 1.959963984540054


def _count(name: str, value: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise ConfigError(name, value, "a count (an integer >= 0)")
    return value


def wilson_interval(successes: int, trials: int, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval of a binomial rate (95 % by default).

    Args:
        successes: Successes.
        trials: Trials (0 gives the uninformative ``(0, 1)``).
        z: The normal quantile of the interval's coverage.

    Returns:
        ``(low, high)`` in ``[0, 1]``.

    Raises:
        ConfigError: Counts that are not integers ``0 <= successes <= trials``.
    """
    _count("successes", successes)
    _count("trials", trials)
    if successes > trials:
        raise ConfigError("successes", successes, f"at most trials ({trials})")
    if trials == 0:
        return 0.0, 1.0
    p = successes / trials
    z2 = z * z
    centre = (p + z2 / (2 * trials)) / (1 + z2 / trials)
    half = z / (1 + z2 / trials) * math.sqrt(p * (1 - p) / trials + z2 / (4 * trials * trials))
    return max(0.0, centre - half), min(1.0, centre + half)


def mcnemar_exact(a_only: int, b_only: int) -> float:
    """The exact McNemar test's two-sided p-value: the binomial test of ``a_only``
    successes in ``a_only + b_only`` discordant pairs at ``p = 1/2`` (SciPy's
    ``binomtest``); 1 without discordant pairs.

    Args:
        a_only: Pairs where only policy A held.
        b_only: Pairs where only policy B held.

    Returns:
        The p-value, in ``[0, 1]``.

    Raises:
        ConfigError: A count that is not a non-negative integer.
    """
    from scipy.stats import binomtest

    _count("a_only", a_only)
    _count("b_only", b_only)
    n = a_only + b_only
    if n == 0:
        return 1.0
    return float(binomtest(a_only, n, 0.5, alternative="two-sided").pvalue)
