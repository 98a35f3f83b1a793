"""Paired comparison of two evaluations on the same test episodes: the exact McNemar test.

With 100 episodes a difference of a few points is usually noise; the test looks only at the
discordant episodes (one side succeeds, the other fails), matched by episode seed."""

from __future__ import annotations

import numpy as np
from scipy.stats import binomtest

from readjax import tasks
from readjax.lab.result_record import by_seed


def mcnemar_p(a, b) -> float:
    """Exact two-sided McNemar p-value for two methods' successes on the same episodes: a binomial
    test on the discordant episodes (one succeeds, the other fails). 1.0 when none are discordant."""
    a, b = np.asarray(a, bool), np.asarray(b, bool)
    if a.shape != b.shape:
        raise ValueError(f"paired outcomes must have the same episodes, got {a.shape} and {b.shape}")
    return sign_test_p(int((a & ~b).sum()), int((~a & b).sum()))


def sign_test_p(n_plus: int, n_minus: int) -> float:
    """Exact two-sided sign test: how likely a split at least as uneven as ``n_plus`` against
    ``n_minus`` is when each pair is equally likely to go either way (ties left out by the caller).
    1.0 when there are no pairs. McNemar's test is this test on the discordant episodes."""
    if n_plus < 0 or n_minus < 0:
        raise ValueError(f"counts must be >= 0, got {n_plus} and {n_minus}")
    n = n_plus + n_minus
    if n == 0:
        return 1.0
    return float(binomtest(n_plus, n, 0.5, alternative="two-sided").pvalue)


def paired_outcomes(a: dict, b: dict) -> tuple[np.ndarray, np.ndarray] | None:
    """Two results' successes (bool arrays) on the episodes both ran, matched by seed; None when
    they share no episode. Results of two suite versions share none: the same seed is another scene."""
    if tasks.suite_of(a) != tasks.suite_of(b):
        return None
    x, y = by_seed(a), by_seed(b)
    common = sorted(set(x) & set(y))
    if not common:
        return None
    return np.asarray([x[k] for k in common], bool), np.asarray([y[k] for k in common], bool)


def counts(a, b) -> tuple[int, int, float]:
    """(wins, losses, p): episodes only ``a`` solves, only ``b`` solves, and the exact McNemar p."""
    a, b = np.asarray(a, bool), np.asarray(b, bool)
    return int((a & ~b).sum()), int((~a & b).sum()), mcnemar_p(a, b)


def same_episodes(a: dict, b: dict) -> bool:
    """Whether two results ran the same test episodes: the same seeds, in order, of one suite version."""
    return bool(a.get("seeds")) and a.get("seeds") == b.get("seeds") and tasks.suite_of(a) == tasks.suite_of(b)


def pool(pairs) -> tuple[int, int, list[int]]:
    """(wins, losses, left out): the discordant episodes of result pairs (a, b), summed over the pairs
    run on the same episodes (``same_episodes``); ``left out`` indexes the pairs that were not. The
    pooled test is ``sign_test_p(wins, losses)``; :func:`pooled` formats it."""
    wins = losses = 0
    left_out = []
    for k, (a, b) in enumerate(pairs):
        if not same_episodes(a, b):
            left_out.append(k)
            continue
        w, lo, _ = counts(a["success"], b["success"])
        wins, losses = wins + w, losses + lo
    return wins, losses, left_out


def sign_text(wins: int, losses: int) -> str:
    """``+wins / -losses, p=...``: the discordant episodes and the exact two-sided test on them."""
    return f"+{wins} / -{losses}, p={sign_test_p(wins, losses):.2g}"


def pooled(pairs) -> tuple[int, int, list[int], str]:
    """(wins, losses, left out, text) of result pairs pooled as :func:`pool` does: the text is
    ``+w / -l, p=..., k pairs`` over the k pairs used, ``–`` where none ran the same episodes."""
    wins, losses, left_out = pool(pairs)
    used = len(pairs) - len(left_out)
    text = f"{sign_text(wins, losses)}, {used} pair{'s' if used > 1 else ''}" if used else "–"
    return wins, losses, left_out, text


def discordant(a: dict, b: dict) -> str:
    """``+wins / -losses, p=...`` of result ``a`` against ``b`` on the episodes both ran."""
    pair = paired_outcomes(a, b)
    if pair is None:
        return "no common episodes"
    return sign_text(*counts(*pair)[:2])
