"""Statistics shared by the training package and `scripts/compare_eval.py`.

Standard library only: `compare_eval.py` imports this module without numpy.
"""

import math


def sign_test(a, b):
    """Two-sided exact sign test: the chance of a split at least as uneven
    as a : b of a + b discordant pairs if either side were as likely."""
    n = a + b
    if n == 0:
        return 1.0
    return min(1.0, 2.0 * sum(math.comb(n, k) for k in range(min(a, b) + 1)) / 2.0 ** n)
