"""Which of several files claiming one run is the run, and which are copies of it.

A run is one sitting of a subject at the array: its time zero on the wall clock, to the
microsecond (the manifest's, or its sidecar's ``TimeBase.ZeroAt``), is its own, and so are its
subject, session, task and run number within a dataset. Two files claiming one of them are
one run copied: a backup taken mid-run (its rows a prefix of the run's), a copy saved with
other line ends or edited cells, a copy under the next run number. Which is the run:

1. the one read with its manifest (at its own place in a dataset, beside ``sourcedata/``);
2. else, among those with a manifest (or all, when none has one), the one whose rows hold
   every other's (line ends aside): the others are copies taken before it ended, or the
   same rows;
3. else nothing tells, and the run is refused in one line naming both files rather than
   guessed (the person who made the copy knows).

Two files with different time zeros are two runs, whatever their names: distinct real runs
(two subjects, two runs of one subject, two sessions, the same labels in two datasets) are
never passed over.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Claim:
    """One file read as a run: where, which run its name says (``label``), whether its
    manifest was read with it, its time zero on the wall clock (empty when nothing says it)
    and its rows' lines (line ends aside)."""

    source: Path
    label: str
    with_manifest: bool
    zero_at: str
    rows: tuple[str, ...]


@dataclass(frozen=True)
class Verdict:
    """The claims that are runs (their indices), one line for each copy passed over, and one
    line for each run refused because nothing tells its file from its copy's (with the
    claims it leaves out)."""

    runs: tuple[int, ...]
    passed_over: tuple[str, ...]
    refused: tuple[tuple[str, tuple[int, ...]], ...]


def _why_one(a: Claim, b: Claim) -> str | None:
    """What says that ``a`` and ``b`` are one run, or None: two runs."""
    if a.zero_at and a.zero_at == b.zero_at:
        return f"the same time zero {a.zero_at}"
    if a.label == b.label and not (a.zero_at and b.zero_at):
        return f"the same {a.label}, no time zero to tell them apart"
    return None


def _holds(a: Claim, b: Claim) -> bool:
    """Whether ``a``'s rows hold every row of ``b`` in order (``b`` a copy taken before ``a``
    ended, or the same rows)."""
    return a.rows[:len(b.rows)] == b.rows


def judged(claims: Sequence[Claim]) -> Verdict:
    """Each group of claims that are one run (`_why_one`, through any chain) judged: its run
    kept, its copies passed over and named, or the group refused when nothing tells."""
    group = list(range(len(claims)))

    def root(i: int) -> int:
        while group[i] != i:
            group[i] = group[group[i]]
            i = group[i]
        return i

    why: dict[int, str] = {}
    for i in range(len(claims)):
        for j in range(i):
            found = _why_one(claims[j], claims[i])
            if found is not None:
                why.setdefault(i, found)
                group[root(i)] = root(j)
    members: dict[int, list[int]] = {}
    for i in range(len(claims)):
        members.setdefault(root(i), []).append(i)
    runs: list[int] = []
    passed_over: list[str] = []
    refused: list[tuple[str, tuple[int, ...]]] = []
    for together in members.values():
        if len(together) == 1:
            runs.extend(together)
            continue
        said = why.get(together[-1], "")
        copies = [claims[i] for i in together]
        the_run = _the_run(copies)
        if isinstance(the_run, tuple):
            a, b = (copies[i] for i in the_run)
            refused.append((f"{b.source}: the same run as {a.source} ({said}), and nothing "
                            "tells which is the run: their rows differ and no manifest says "
                            "which is the run; keep the run's file and move the copy out of "
                            "the dataset's sub- folders", tuple(together)))
            continue
        kept = together[the_run]
        reason = ("read with its manifest" if claims[kept].with_manifest
                  and sum(c.with_manifest for c in copies) == 1
                  else "its rows hold every row of the copy's")
        runs.append(kept)
        for i in together:
            if i != kept:
                passed_over.append(
                    f"{claims[i].source}: passed over: a copy of the run {claims[kept].source} "
                    f"({_why_one(claims[kept], claims[i]) or said}); that file is the run, "
                    f"{reason}")
    return Verdict(tuple(sorted(runs)), tuple(passed_over), tuple(refused))


def _the_run(copies: list[Claim]) -> int | tuple[int, int]:
    """Which of ``copies`` (one run's) is the run; or the two that nothing tells apart."""
    with_manifest = [i for i, c in enumerate(copies) if c.with_manifest]
    if len(with_manifest) == 1:
        return with_manifest[0]
    among = with_manifest or list(range(len(copies)))
    longest = max(among, key=lambda i: (len(copies[i].rows), -i))
    for i in among:
        if not _holds(copies[longest], copies[i]):
            return (longest, i) if longest < i else (i, longest)
    return longest
