"""Protocols: the validated model (`model`), read from YAML (`load`, over `yaml_nodes`), with
the drive and feasibility checks a protocol must pass (`drives`, `feasibility`); a design's
paradigm is found through the paradigm seam (`seam`).

The model's names are importable from here (``from pinarray.protocol import Protocol``);
loading is ``from pinarray.protocol.load import load_protocol``.
"""

from pinarray.protocol.model import (
    BAUD_RATES,
    DIRECTION_OF_WAVE,
    NS_PER_S,
    AnyWave,
    Condition,
    Constraints,
    Design,
    Device,
    Direction,
    HobbyServos,
    Ordering,
    PathWave,
    Pca9685Board,
    PinCalibration,
    PinDrive,
    Protocol,
    Servos,
    ServoSettings,
    Stimulus,
    Train,
    TrainShape,
    TrainStimulus,
    Wave,
    WaveKind,
    WaveStimulus,
)

__all__ = [
    "AnyWave", "BAUD_RATES", "DIRECTION_OF_WAVE", "NS_PER_S", "Condition",
    "Constraints", "Design", "Device", "Direction", "HobbyServos", "Ordering", "PathWave",
    "Pca9685Board",
    "PinCalibration", "PinDrive", "Protocol", "Servos", "ServoSettings", "Stimulus", "Train",
    "TrainShape", "TrainStimulus", "Wave",
    "WaveKind", "WaveStimulus",
]
