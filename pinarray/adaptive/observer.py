"""A simulated subject who answers from a known psychometric function, for checking a
procedure before running people.

Trial ``t`` at intensity ``x`` is answered correctly when ``u < p(x)``, with ``u`` uniform in
[0, 1) made of the top 53 bits of a 64-bit word drawn by PCG64 from the seed sequence
``[seed, t, PURPOSE]`` (``PURPOSE`` keeps these draws apart from the interleaving's with the
same seed). Each answer depends on the seed, the trial number and the intensity only, so a
run resumed from disk gets the answers it would have had, on any machine and numpy version
(numpy keeps its bit generators' streams stable).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pinarray.adaptive.psychometric import Psychometric
from pinarray.errors import PinArrayError

PURPOSE = 0x6F627376  # "obsv"


@dataclass(frozen=True)
class PsychometricObserver:
    """A subject whose probability of answering correctly is ``function.probability``."""

    function: Psychometric
    seed: int

    def __post_init__(self) -> None:
        if not 0 <= self.seed < 2**63:
            raise PinArrayError(f"an observer's seed must be a whole number from 0 to 2^63-1, found {self.seed}")

    def answer(self, trial: int, intensity: float) -> bool:
        """Whether the subject answers trial ``trial`` (1-based) at ``intensity`` correctly."""
        word = int(np.random.PCG64(np.random.SeedSequence([self.seed, trial, PURPOSE])).random_raw())
        uniform = (word >> 11) * 2.0**-53
        return bool(uniform < float(self.function.probability(intensity)))
