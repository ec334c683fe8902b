"""The bootstrap ([Efron1993]_): the one resampling behind every bootstrap interval poibench
prints (a suite's mean score fraction over its mazes, a card's false detections an image over
its images, the parts of a sim-to-real gap over their placards).

References
----------
Full entries in docs/SOURCES.md.

.. [Efron1993] B. Efron and R. J. Tibshirani, "An Introduction to the Bootstrap", Chapman &
   Hall, 1993.
"""

from __future__ import annotations

import numpy as np


def bootstrap_means(x, rng: np.random.Generator, resamples: int) -> np.ndarray:
    """The means of ``x`` ((n,) or (n, K), n >= 1) over ``resamples`` bootstrap resamples of its
    rows: (resamples,) or (resamples, K). Each resample draws n row indices uniformly with
    replacement ([Efron1993]_, 6.2); the 2.5% and 97.5% quantiles of these means are the 95%
    percentile interval (13.3).

    >>> sorted(set(bootstrap_means([1.0, 3.0], np.random.default_rng(0), 50).tolist()))  # 1+1, 1+3, 3+3
    [1.0, 2.0, 3.0]
    """
    x = np.asarray(x, dtype=float)
    draws = rng.integers(0, len(x), size=(resamples, len(x)))  # (resamples, n) row indices
    return x[draws].mean(axis=1)
