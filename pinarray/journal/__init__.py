"""The journal: where results are written and read.

`records` (trial rows, their columns, the reader), `manifest` (labels, the BIDS layout, the
run's manifest) and `runs` (opening a new or resumed run). `analysis` reads through it.
"""
