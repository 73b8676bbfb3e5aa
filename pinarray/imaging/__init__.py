"""Imaging- and EEG-ready sessions: scanner triggers, time zero at the first counted volume, LSL.

`timeline` numbers volumes and judges them against the TR (pure); `triggers` reads them from
a serial trigger converter, a key, or an emulated scanner; `scanner` waits for the first
counted volume, logs every volume and holds trials for volume-locked onsets; `lsl` is the
marker outlet (pylsl is imported only when one is asked for) and `markers` what it sends.
The settings themselves are the protocol's ``sync`` section (`pinarray.protocol.imaging`).
"""
