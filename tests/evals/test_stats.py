"""The statistics against independent oracles: SciPy's Fisher exact test, Wilson interval and t distribution."""

from __future__ import annotations

import math
import random

import pytest

from agents_core.evals.stats import compare_success, mean_interval, student_t_quantile, wilson_interval

scipy_stats = pytest.importorskip("scipy.stats", reason="SciPy is the oracle of these tests (the local extra)")


def _fisher(k_a: int, n_a: int, k_b: int, n_b: int) -> float:
    return float(scipy_stats.fisher_exact([[k_a, n_a - k_a], [k_b, n_b - k_b]], alternative="two-sided")[1])


def test_fisher_matches_scipy_on_every_small_table() -> None:
    worst = 0.0
    for n_a in range(1, 9):
        for n_b in range(1, 9):
            for k_a in range(n_a + 1):
                for k_b in range(n_b + 1):
                    ours, theirs = compare_success(k_a, n_a, k_b, n_b), _fisher(k_a, n_a, k_b, n_b)
                    worst = max(worst, abs(ours - theirs) / theirs)
    assert worst < 1e-9


def test_fisher_matches_scipy_on_random_tables_of_evaluation_sizes() -> None:
    rng = random.Random(39)
    for _ in range(800):
        n_a, n_b = rng.randint(1, 300), rng.randint(1, 300)
        # Rates that differ a lot, a little, and sit near 0 and 1.
        p_a = rng.choice([0.0, 0.02, 0.1, 0.5, 0.8, 0.97, 1.0, rng.random()])
        p_b = min(1.0, max(0.0, p_a + rng.choice([0.0, 0.05, -0.2, 0.4, rng.uniform(-1, 1)])))
        k_a = sum(rng.random() < p_a for _ in range(n_a))
        k_b = sum(rng.random() < p_b for _ in range(n_b))
        ours, theirs = compare_success(k_a, n_a, k_b, n_b), _fisher(k_a, n_a, k_b, n_b)
        assert ours == pytest.approx(theirs, rel=1e-9, abs=1e-300), (k_a, n_a, k_b, n_b)


@pytest.mark.parametrize(("k_a", "n_a", "k_b", "n_b"), [
    (16, 20, 5, 20), (20, 20, 0, 20), (0, 20, 0, 20), (20, 20, 20, 20), (1, 1, 0, 1), (0, 1, 0, 500),
    (4900, 5000, 4850, 5000), (50_000, 100_000, 49_000, 100_000), (3, 7, 30, 31)])
def test_fisher_matches_scipy_at_the_edges_and_at_large_n(k_a: int, n_a: int, k_b: int, n_b: int) -> None:
    assert compare_success(k_a, n_a, k_b, n_b) == pytest.approx(_fisher(k_a, n_a, k_b, n_b), rel=1e-9)


def test_fisher_is_symmetric_and_a_probability() -> None:
    rng = random.Random(7)
    for _ in range(300):
        n_a, n_b = rng.randint(1, 60), rng.randint(1, 60)
        k_a, k_b = rng.randint(0, n_a), rng.randint(0, n_b)
        p = compare_success(k_a, n_a, k_b, n_b)
        assert 0.0 < p <= 1.0
        assert p == pytest.approx(compare_success(k_b, n_b, k_a, n_a), rel=1e-12)
        # Swapping success and failure on both sides is the same table, mirrored.
        assert p == pytest.approx(compare_success(n_a - k_a, n_a, n_b - k_b, n_b), rel=1e-12)


def test_fisher_with_an_empty_side_is_no_evidence() -> None:
    assert compare_success(0, 0, 5, 10) == 1.0
    assert compare_success(3, 10, 0, 0) == 1.0


@pytest.mark.parametrize(("args", "error"), [((5, 4, 1, 2), ValueError), ((-1, 4, 1, 2), ValueError),
                                             ((1.0, 4, 1, 2), TypeError), ((True, 4, 1, 2), TypeError),
                                             ((1, 2, 3, 2), ValueError)])
def test_fisher_refuses_impossible_counts(args: tuple[int, int, int, int], error: type[Exception]) -> None:
    with pytest.raises(error, match=r"successes|must be an int"):
        compare_success(*args)


def test_wilson_textbook_value() -> None:
    # 15 of 20 at 95 %: 0.5313-0.8881 (Newcombe 1998's method 3; statsmodels'
    # proportion_confint(15, 20, method="wilson")).
    low, high = wilson_interval(15, 20)
    assert (round(low, 4), round(high, 4)) == (0.5313, 0.8881)
    low, high = wilson_interval(0, 10)
    assert low == 0.0 and round(high, 4) == 0.2775


def test_wilson_matches_scipy() -> None:
    for n in [1, 2, 5, 10, 20, 37, 100, 1000]:
        for k in sorted({0, 1, n // 3, n // 2, n - 1, n}):
            for confidence in (0.8, 0.9, 0.95, 0.99):
                ci = scipy_stats.binomtest(k, n).proportion_ci(confidence_level=confidence, method="wilson")
                low, high = wilson_interval(k, n, confidence)
                assert low == pytest.approx(float(ci.low), abs=1e-12), (k, n, confidence)
                assert high == pytest.approx(float(ci.high), abs=1e-12), (k, n, confidence)


def test_wilson_stays_in_the_unit_interval_and_contains_the_rate() -> None:
    for n in range(1, 80):
        for k in range(n + 1):
            low, high = wilson_interval(k, n)
            assert 0.0 <= low <= k / n <= high <= 1.0
    assert wilson_interval(0, 20)[0] == 0.0 and wilson_interval(20, 20)[1] == 1.0
    assert wilson_interval(0, 0) == (0.0, 1.0)


@pytest.mark.parametrize("confidence", [0, 1, 1.5, -0.1, float("nan")])
def test_wilson_refuses_a_confidence_outside_0_1(confidence: float) -> None:
    with pytest.raises(ValueError, match=r"confidence"):
        wilson_interval(3, 10, confidence)


@pytest.mark.parametrize("df", [*range(1, 41), 59, 60, 99, 100, 999, 1000, 1001, 4000, 100_000])
def test_t_quantile_matches_scipy(df: int) -> None:
    for confidence in (0.5, 0.8, 0.9, 0.95, 0.99, 0.999):
        theirs = float(scipy_stats.t.ppf(0.5 + confidence / 2, df))
        assert student_t_quantile(confidence, df) == pytest.approx(theirs, rel=1e-9), (df, confidence)


def test_mean_interval_matches_scipy() -> None:
    rng = random.Random(3)
    for n in (2, 3, 5, 20, 100):
        values = [rng.gauss(-5.0, 2.0) for _ in range(n)]
        got = mean_interval(values)
        mean = sum(values) / n
        sem = float(scipy_stats.sem(values))
        low, high = scipy_stats.t.interval(0.95, n - 1, loc=mean, scale=sem)
        assert got.mean == pytest.approx(mean, rel=1e-12)
        assert got.low == pytest.approx(float(low), rel=1e-9) and got.high == pytest.approx(float(high), rel=1e-9)
        assert got.median == pytest.approx(float(sorted(values)[n // 2] if n % 2 else
                                                 (sorted(values)[n // 2 - 1] + sorted(values)[n // 2]) / 2))


def test_mean_interval_leaves_out_non_finite_values_and_counts_them() -> None:
    got = mean_interval([1.0, float("nan"), 3.0, float("inf"), -float("inf")])
    assert (got.mean, got.n, got.non_finite, got.median) == (2.0, 2, 3, 2.0)
    one = mean_interval([4.0])
    assert (one.mean, one.low, one.high, one.n) == (4.0, None, None, 1)
    none = mean_interval([math.nan])
    assert (none.mean, none.n, none.non_finite) == (None, 0, 1)
    constant = mean_interval([2.0] * 5)
    assert (constant.low, constant.high) == (2.0, 2.0)
