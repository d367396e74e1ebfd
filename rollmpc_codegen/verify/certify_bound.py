"""The bound a work certificate states (certify.py): from K samples of which k stopped at
TIME_LIMIT, an upper bound eps on the probability of a stop, at confidence 1 - beta.

For a budget fixed before the samples are drawn (it is the design's, not fitted to them),
the scenario approach's bound with no support constraints is the binomial tail: with K
i.i.d. samples, P(Binomial(K, eps) <= k) = beta defines eps, the one-sided Clopper-Pearson
upper limit. With k = 0 it is eps = 1 - beta^(1/K) <= ln(1/beta) / K, so K >=
ln(1/beta) / eps samples without a stop bound the probability by eps; 99.5 % confidence
of P <= 1e-3 takes 5,296 samples.

What it assumes: the samples are independent draws from the distribution the bound is
about. The certificate states two bounds (certify.py): over its loops, which are
independent (each its own seed: reference, noise, mismatch), the probability that a loop
meets a stop at all, which holds as stated for loops drawn like them; and over its
samples, which treats the samples of one loop as independent although a closed loop's
consecutive QPs are not: stops come in runs, so that bound is optimistic (its K overstates
the independent information) and is the figure to compare flights with, not a guarantee.
"""
from __future__ import annotations

import math

from scipy.stats import beta as beta_distribution


def upper_bound(failures: int, trials: int, confidence: float) -> float:
    """The one-sided Clopper-Pearson upper limit on a probability from ``failures`` of
    ``trials`` independent trials, at ``confidence`` (1 - beta)."""
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    if trials <= 0 or failures >= trials:
        return 1.0
    return float(beta_distribution.ppf(confidence, failures + 1, trials - failures))


def samples_needed(eps: float, confidence: float) -> int:
    """The samples without a stop that bound the probability by ``eps`` at
    ``confidence``: the smallest K with 1 - (1 - confidence)^(1/K) <= eps."""
    return math.ceil(math.log(1 - confidence) / math.log(1 - eps))
