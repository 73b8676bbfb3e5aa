"""Unit conversions used at the edges: the seeds' fitted curves are in centimetres and newtons.

Every constant says which way it converts; multiply a value in the first unit by it to get
the second (``area_cm2 * M2_PER_CM2`` is square metres).
"""

M_PER_CM = 1e-2
M_PER_MM = 1e-3
M2_PER_CM2 = 1e-4
M2_PER_MM2 = 1e-6
PA_PER_KPA = 1e3
PA_PER_BAR = 1e5
S_PER_MS = 1e-3
