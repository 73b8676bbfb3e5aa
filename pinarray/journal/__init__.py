"""The journal: where results are written and read, as a BIDS dataset.

`records` (trial rows, their columns, the reader), `paths` (labels and the BIDS layout),
`manifest` (the run's plan, provenance, sittings and status, in ``sourcedata/``), `timebase`
(one time base per run across sittings), `lock` (one writer per run), `dataset` (the
dataset's root files and each run's sidecars), `writer` (the fsync'ing `RunWriter`), `files`
(atomic replacement) and `runs` (opening a new or resumed run). `analysis` reads through it.
"""
