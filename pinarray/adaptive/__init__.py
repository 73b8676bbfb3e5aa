"""Adaptive procedures as pure numbers: psychometric functions, staircases, QUEST+, their
interleaving, a simulated subject and a subject's threshold from a grid posterior.

Nothing here reads or writes files, prints or knows a protocol: intensities are plain numbers
in the unit of the adapted parameter (ms of SOA, mm of stroke, Hz, ...), which the caller names.
"""
