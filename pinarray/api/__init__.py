"""Where the public face's names live: import them from `pinarray` itself.

``import pinarray`` loads none of this until a name is used (PEP 562: `pinarray.__getattr__`),
so the commands start as fast as before. What `pinarray.__all__` lists is the promise
(semantic versioning, CHANGELOG.md, tests/test_public_api.py); these modules may move.

`protocols` (reading a protocol, its plan and its conditions), `array` (an open array that
presents stimuli, now or armed for a time), `ports` (the serial ports where servos answer),
`sessions` (a whole run from a script, answered by the script), `results` (runs read back)
and `errors` (the one exception family).
"""
