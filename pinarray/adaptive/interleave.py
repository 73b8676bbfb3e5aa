"""Several procedures interleaved at random, so that a subject cannot guess which one runs.

The procedure that runs trial ``t`` (the 1-based number of the trial among the interleaved
procedures' trials) is decided from the seed, ``t`` and the unfinished procedures only, in
the order the protocol declares them: with ``u`` a 64-bit word drawn by PCG64 from the seed
sequence ``[seed, t, PURPOSE]`` (``numpy.random.SeedSequence``; ``PURPOSE`` keeps these draws
apart from a simulated subject's with the same seed), it is ``unfinished[(u * n) >> 64]`` of
the ``n`` unfinished ones. A run resumed from disk therefore continues exactly as it would
have: its trial number and the procedures still unfinished are in its rows. Only the bit
generator is used, whose streams numpy keeps stable across versions and machines (a
`Generator` method's algorithm may change between numpy versions).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TypeVar

import numpy as np

from pinarray.errors import PinArrayError

Name = TypeVar("Name")

MAX_SEED = 2**63 - 1
PURPOSE = 0x696E746C  # "intl"


def pick_procedure(seed: int, trial: int, unfinished: Sequence[Name]) -> Name:
    """The procedure that runs ``trial`` among ``unfinished`` (in declared order): see the module."""
    if not 0 <= seed <= MAX_SEED:
        raise PinArrayError(f"an interleaving seed must be a whole number from 0 to 2^63-1, found {seed}")
    if trial < 1:
        raise PinArrayError(f"interleaved trials are numbered from 1, found {trial}")
    if not unfinished:
        raise PinArrayError(f"trial {trial}: every interleaved procedure has finished")
    if len(set(unfinished)) != len(unfinished):
        raise PinArrayError(f"interleaved procedures must be named once each, found {list(unfinished)}")
    word = int(np.random.PCG64(np.random.SeedSequence([seed, trial, PURPOSE])).random_raw())
    return unfinished[(word * len(unfinished)) >> 64]
