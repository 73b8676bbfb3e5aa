"""The paradigms: each one room, a package implementing the paradigm seam (`base.Paradigm`).

A room holds everything its paradigm is: its conditions and how its ``design`` section is
read (``design``: pure, what ``pinarray validate`` loads), its rows and their checks
(``rows``), its simulated subject (``observer``) and its estimates, tables and figures
(``analysis``). The layers below never import a room: they find it by name through the
registry (`pinarray.registry`), and a lab's own paradigm, in a package of its own, is found
the same way by its entry point (group ``pinarray.paradigms``).
"""
