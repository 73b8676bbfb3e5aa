"""pinarray's Builder components: PsychoPy's plugin manager loads them by entry point (group
``psychopy.experiment.components``).

Builder imports these modules to show its components panel and dialogs, and to compile an
experiment: they import PsychoPy's experiment classes alone, never PsychoPy's hardware or
pinarray's array (tests/psychopy/test_builder.py sees it). What a compiled script runs is
`pinarray.psychopy.PinArrayTouch` and `pinarray.psychopy.PinArrayDevice`.
"""
