"""The statistics of an evaluation: how sure a success rate is, and whether two of them differ.

- :func:`wilson_interval`: the Wilson score interval of a binomial proportion. Unlike the textbook
  ``p ± z·sqrt(p(1-p)/n)`` (the Wald interval) it stays inside [0, 1], is not zero-width at 0/n or
  n/n, and keeps close to its nominal coverage for the small n (20-100 episodes) evaluations have.
- :func:`compare_success`: the two-sided Fisher exact test of two success counts. Exact (no normal
  approximation), so it is valid at 20 episodes a side and at rates near 0 or 1, where a
  chi-squared test is not. The two-sided p-value sums the probabilities of every table with the
  observed margins that is no more likely than the observed one (as R and SciPy do), computed in
  log space with :func:`math.lgamma` so that 100,000 episodes cost no big integers.
- :func:`mean_interval`: a mean with its Student-t interval (reward sums, times to success); the
  t quantile comes from the t distribution's closed form for whole degrees of freedom.

Only the standard library: no SciPy in the core (the tests use SciPy as the independent oracle).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from statistics import NormalDist

__all__ = ["MeanInterval", "compare_success", "mean_interval", "student_t_quantile", "wilson_interval"]

# Tables whose probabilities differ by less than this (relative) are ties: floating-point noise in
# log space must not drop a table exactly as likely as the observed one (R uses 1e-7 too).
_TIE_TOLERANCE = 1e-7
# Above this many degrees of freedom the quantile comes from the normal one by the Cornish-Fisher expansion
# (its first omitted term is below 1e-10 there); below, by bisection on the closed form.
_T_EXPANSION_DF = 1000


def _check_confidence(confidence: float) -> None:
    if not (isinstance(confidence, int | float) and 0.0 < confidence < 1.0):
        raise ValueError(f"confidence must be between 0 and 1 (exclusive), got {confidence!r}")


def _check_counts(successes: int, n: int, what: str = "") -> None:
    for name, value in (("successes", successes), ("n", n)):
        if isinstance(value, bool) or not isinstance(value, int):
            raise TypeError(f"{what}{name} must be an int, got {type(value).__name__}")
    if n < 0 or not 0 <= successes <= n:
        raise ValueError(f"{what}successes must be between 0 and n; got {successes} of {n}")


def wilson_interval(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """The Wilson score interval ``(low, high)`` of ``successes`` out of ``n`` at ``confidence``.

    ``n == 0`` gives ``(0.0, 1.0)``: nothing is known.
    """
    _check_counts(successes, n)
    _check_confidence(confidence)
    if n == 0:
        return 0.0, 1.0
    z = NormalDist().inv_cdf(0.5 + confidence / 2.0)
    p = successes / n
    z2n = z * z / n
    centre = (p + z2n / 2.0) / (1.0 + z2n)
    half = z / (1.0 + z2n) * math.sqrt(p * (1.0 - p) / n + z2n / (4.0 * n))
    # At 0/n and n/n the formula gives the bound exactly; rounding must not move it past [0, 1].
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == n else min(1.0, centre + half)
    return low, high


def _log_comb(n: int, k: int) -> float:
    return math.lgamma(n + 1) - math.lgamma(k + 1) - math.lgamma(n - k + 1)


def compare_success(k_a: int, n_a: int, k_b: int, n_b: int) -> float:
    """The two-sided Fisher exact test p-value that ``k_a / n_a`` and ``k_b / n_b`` share one success rate.

    The 2x2 table is (successes, failures) of A and of B; with its margins fixed, A's successes
    follow a hypergeometric distribution, and the p-value is the total probability of the values no
    more likely than ``k_a``. 1.0 when either side has no episodes (nothing to compare).
    """
    _check_counts(k_a, n_a, "A's ")
    _check_counts(k_b, n_b, "B's ")
    if n_a == 0 or n_b == 0:
        return 1.0
    total = n_a + n_b
    column = k_a + k_b  # all successes
    low, high = max(0, column - n_b), min(column, n_a)
    if low == high:
        return 1.0
    norm = _log_comb(total, column)

    def log_p(x: int) -> float:
        return _log_comb(n_a, x) + _log_comb(n_b, column - x) - norm

    observed = log_p(k_a)
    threshold = observed + math.log1p(_TIE_TOLERANCE)
    # The distribution is unimodal: walk in from both ends while the tables are no more likely than the
    # observed one; the rest (around the mode) are more likely and do not count.
    p_value = 0.0
    x = low
    while x <= high and log_p(x) <= threshold:
        p_value += math.exp(log_p(x))
        x += 1
    y = high
    while y >= x and log_p(y) <= threshold:
        p_value += math.exp(log_p(y))
        y -= 1
    return min(1.0, p_value)


def _t_two_sided_mass(t: float, df: int) -> float:
    """P(|T| < t) for Student's t with ``df`` (whole) degrees of freedom, by its closed form in atan(t/sqrt(df))."""
    theta = math.atan(t / math.sqrt(df))
    c2 = math.cos(theta) ** 2
    s = math.sin(theta)
    if df % 2 == 1:
        if df == 1:
            return 2.0 * theta / math.pi
        term, acc = math.cos(theta), math.cos(theta)
        for j in range(1, (df - 3) // 2 + 1):
            term *= c2 * (2 * j) / (2 * j + 1)
            acc += term
        return 2.0 / math.pi * (theta + s * acc)
    term, acc = 1.0, 1.0
    for j in range(1, (df - 2) // 2 + 1):
        term *= c2 * (2 * j - 1) / (2 * j)
        acc += term
    return s * acc


def student_t_quantile(confidence: float, df: int) -> float:
    """The two-sided quantile: the ``t`` with P(|T| < t) = ``confidence``, for Student's t with ``df`` degrees."""
    _check_confidence(confidence)
    if isinstance(df, bool) or not isinstance(df, int) or df < 1:
        raise ValueError(f"degrees of freedom must be an int >= 1, got {df!r}")
    normal = NormalDist().inv_cdf(0.5 + confidence / 2.0)
    if df > _T_EXPANSION_DF:
        z = normal
        return (z + (z**3 + z) / (4 * df) + (5 * z**5 + 16 * z**3 + 3 * z) / (96 * df**2)
                + (3 * z**7 + 19 * z**5 + 17 * z**3 - 15 * z) / (384 * df**3))
    low, high = normal, max(2.0 * normal, 1.0)
    while _t_two_sided_mass(high, df) < confidence:
        high *= 2.0
    for _ in range(200):
        mid = (low + high) / 2.0
        if _t_two_sided_mass(mid, df) < confidence:
            low = mid
        else:
            high = mid
        if high - low <= 1e-12 * high:
            break
    return (low + high) / 2.0


@dataclass(frozen=True)
class MeanInterval:
    """A mean and its interval; ``low``/``high`` are None with fewer than two values."""

    mean: float | None
    low: float | None
    high: float | None
    n: int
    #: Values left out because they were NaN or infinite (an env that returned NaN rewards).
    non_finite: int = 0
    median: float | None = None


def mean_interval(values: Iterable[float], confidence: float = 0.95) -> MeanInterval:
    """The mean of the finite ``values`` with its Student-t interval at ``confidence``.

    NaN and infinite values are counted (:attr:`MeanInterval.non_finite`), not used.
    """
    _check_confidence(confidence)
    finite: list[float] = []
    skipped = 0
    for value in values:
        v = float(value)
        if math.isfinite(v):
            finite.append(v)
        else:
            skipped += 1
    n = len(finite)
    if n == 0:
        return MeanInterval(None, None, None, 0, skipped)
    finite.sort()
    median = finite[n // 2] if n % 2 else finite[n // 2 - 1] / 2.0 + finite[n // 2] / 2.0
    # Computed on the values divided by the largest magnitude, so that sums and squares of values near the
    # float limit (an env's 1e308 reward) cannot overflow; an interval too wide for a float becomes infinite.
    scale = max(abs(finite[0]), abs(finite[-1])) or 1.0
    scaled = [v / scale for v in finite]
    mean_scaled = math.fsum(scaled) / n
    mean = mean_scaled * scale
    if n < 2:
        return MeanInterval(mean, None, None, n, skipped, median)
    sd_scaled = math.sqrt(math.fsum((v - mean_scaled) ** 2 for v in scaled) / (n - 1))
    half = student_t_quantile(confidence, n - 1) * (sd_scaled / math.sqrt(n)) * scale
    return MeanInterval(mean, mean - half, mean + half, n, skipped, median)
