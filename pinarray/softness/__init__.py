"""Softness display models from the seeds, as a numeric library (SI units inside).

One module a job:

- ``hertz``          Hertz contact of two solids of revolution (seed 000, eqs. 1-7; seed 001, 9.3)
- ``telescopic``     the telescopic display of concentric cylinders (seed 000, 4.2)
- ``tf_display``     the TF/CASR cone display, F = p A(z) (seed 001, 9.4.1)
- ``identification`` least-squares force/area and force/displacement fits (seed 001, 9.5)
- ``control``        combined CASR + DHD control and the force-ramp tracking run (9.5.1, 9.6)
- ``forceps``        forceps samples -> Young's modulus -> force/area -> display pressure (000, 4.1)
- ``plots``          PNG figures (the only matplotlib importer)
- ``commands``       the ``pinarray softness ...`` subcommands

This file imports nothing on purpose: the CLI imports ``commands`` at start-up and must not
pay for numpy there.
"""
