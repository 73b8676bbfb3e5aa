"""Protocols: the validated model (`model`), read from YAML (`load`, over `yaml_nodes`), with
the drive and feasibility checks a protocol must pass (`drives`, `feasibility`).

The model's names are importable from here (``from pinarray.protocol import Protocol``);
loading is ``from pinarray.protocol.load import load_protocol``.
"""

from pinarray.protocol.model import (
    BAUD_RATES,
    DIRECTION_OF_WAVE,
    NOTHING_FELT,
    NS_PER_S,
    Condition,
    Constraints,
    Design,
    Device,
    Direction,
    HobbyServos,
    LocalisationCondition,
    MotionAnswer,
    MotionCondition,
    Ordering,
    Paradigm,
    Pca9685Board,
    PinCalibration,
    PinDrive,
    Protocol,
    Servos,
    ServoSettings,
    Stimulus,
    Train,
    TrainStimulus,
    Wave,
    WaveKind,
    WaveStimulus,
)

__all__ = [
    "BAUD_RATES", "DIRECTION_OF_WAVE", "NOTHING_FELT", "NS_PER_S", "Condition", "Constraints", "Design", "Device", "Direction",
    "HobbyServos", "LocalisationCondition", "MotionAnswer", "Pca9685Board", "Servos", "MotionCondition", "Ordering", "Paradigm", "PinCalibration",
    "PinDrive", "Protocol", "ServoSettings", "Stimulus", "Train", "TrainStimulus", "Wave",
    "WaveKind", "WaveStimulus",
]
