"""Servo models and variants as data: speed, voltage, stroke, backlash, factory control table.

Pure data with its sources named beside each number, so the simulator (and bring-up tools)
never hide a guess inside code. A number marked *estimate* has no published source; change it
when someone measures it.
"""

from __future__ import annotations

from dataclasses import dataclass

from pinarray.errors import PinArrayError
from pinarray.hardware.feetech.registers import (
    STS3215_MODEL_NUMBER,
    STS3250_MODEL_NUMBER,
    Register,
)

STEPS_PER_TURN = 4096  # 12-bit magnetic encoder on the output shaft (STS3215 memory table v3.6)


@dataclass(frozen=True)
class ServoModel:
    """One servo model/variant.

    Attributes
    ----------
    name : str
        Catalogue name, e.g. ``"STS3215-C001"``.
    model_number : int
        What the model-number register (address 3) reads.
    firmware : tuple of int
        Firmware major and minor version (addresses 0 and 1).
    nominal_voltage_v : float
        Supply voltage the speed figure is given at, in volts.
    seconds_per_60deg : float
        No-load time to turn 60 degrees at the nominal voltage, in seconds (datasheet style).
    gear_ratio : int
        Motor turns per output turn.
    stall_torque_kgcm : float
        Stall torque at the nominal voltage, in kg.cm.
    backlash_deg : float
        Free play of the output shaft, in degrees.
    spin_up_s : float
        Time the motor needs from standstill to no-load speed when the acceleration register
        is 0 ("the servo's maximum"), in seconds.
    max_voltage_limit_dv, min_voltage_limit_dv : int
        Factory values of the voltage-limit registers (14, 15), in 0.1 V.
    """

    name: str
    model_number: int
    firmware: tuple[int, int]
    nominal_voltage_v: float
    seconds_per_60deg: float
    gear_ratio: int
    stall_torque_kgcm: float
    backlash_deg: float
    spin_up_s: float
    max_voltage_limit_dv: int
    min_voltage_limit_dv: int
    steps_per_turn: int = STEPS_PER_TURN

    @property
    def speed_steps_per_s(self) -> float:
        """No-load speed at the nominal voltage, in steps per second."""
        return self.steps_per_turn / 6.0 / self.seconds_per_60deg

    def speed_at(self, supply_v: float) -> float:
        """No-load speed at ``supply_v`` volts, in steps per second.

        A DC motor's no-load speed is proportional to its supply voltage.
        """
        return self.speed_steps_per_s * supply_v / self.nominal_voltage_v

    @property
    def backlash_steps(self) -> float:
        return self.backlash_deg * self.steps_per_turn / 360.0

    @property
    def max_acceleration_steps_per_s2(self) -> float:
        """What acceleration register 0 ("maximum") means here, in steps/s^2."""
        return self.speed_steps_per_s / self.spin_up_s


# Backlash measured on STS3215 servos of SO-ARM100 arms: "Encoder Backlash (Free Play) ... ~1 deg"
# against a datasheet "<= 0.5 deg" (github.com/TheRobotStudio/SO-ARM100 issue 134).
MEASURED_BACKLASH_DEG = 1.0
# Estimate: Feetech documents acceleration 0 only as "maximum" (and a factory multiplier,
# LeRobot tables.py "Acceleration_Multiplier"); a small iron-core motor reaches no-load speed
# in a few mechanical time constants, taken here as 20 ms.
SPIN_UP_ESTIMATE_S = 0.020

STS3215_C001 = ServoModel(
    name="STS3215-C001",
    model_number=STS3215_MODEL_NUMBER,
    # Firmware 3.6: Feetech's STS3215 memory table v3.6 (addresses 0/1 initial values 3 and 6).
    firmware=(3, 6),
    # 7.4 V, 1:345, 19.5 kg.cm: DFRobot/Little Bird "ST3215 Serial Bus Servo 19.5kg.cm 7.4V";
    # the C001 code: a Feetech seller in github.com/roboninecom/SO-ARM100-101-Parallel-Gripper
    # issue 5 ("STS3215-C001 is 7.4V 19kg 1/345").
    nominal_voltage_v=7.4,
    # STS3215 datasheet: 0.222 s/60 deg at 7.4 V (REFERENCE.md; about 3075 steps/s). The memory
    # table's "no load speed 3400 step/s" is the firmware's figure, about 10 % faster.
    seconds_per_60deg=0.222,
    gear_ratio=345,
    stall_torque_kgcm=19.5,
    backlash_deg=MEASURED_BACKLASH_DEG,
    spin_up_s=SPIN_UP_ESTIMATE_S,
    # Factory voltage limits 8.0 V / 4.0 V: memory table v3.6, registers 14 and 15.
    max_voltage_limit_dv=80,
    min_voltage_limit_dv=40,
)

STS3215_C018 = ServoModel(
    name="STS3215-C018",
    model_number=STS3215_MODEL_NUMBER,  # LeRobot drives 12 V SO-101 followers as "sts3215" (777)
    firmware=(3, 6),
    # 12 V, 1:345, 30 kg.cm, 45 rpm (0.22 s/60 deg) datasheet values quoted, and ~46 rpm measured,
    # in SO-ARM100 issue 134 ("Feetech STS3215 C018 (reduction ratio 1:345, 12V, 30 kg.cm)").
    nominal_voltage_v=12.0,
    seconds_per_60deg=0.222,
    gear_ratio=345,
    stall_torque_kgcm=30.0,
    backlash_deg=MEASURED_BACKLASH_DEG,
    spin_up_s=SPIN_UP_ESTIMATE_S,
    # Estimate: the issue quotes an operating range of 4-14 V; the factory registers of this
    # variant were not published.
    max_voltage_limit_dv=140,
    min_voltage_limit_dv=40,
)

STS3250 = ServoModel(
    name="STS3250",
    model_number=STS3250_MODEL_NUMBER,
    firmware=(3, 6),  # estimate: not published; LeRobot uses the STS3215 control table for it
    # 12 V, 50 kg.cm, 0.133 s/60 deg, backlash <= 0.5 deg: Feetech's specification sheet as
    # quoted by robonine.com ("Feetech STS3250 Smart Actuator: Evaluation of Accuracy...").
    nominal_voltage_v=12.0,
    seconds_per_60deg=0.133,
    gear_ratio=345,
    stall_torque_kgcm=50.0,
    backlash_deg=0.5,
    spin_up_s=SPIN_UP_ESTIMATE_S,
    # Estimate from the quoted operating range 6-12.6 V.
    max_voltage_limit_dv=140,
    min_voltage_limit_dv=60,
)

# Names a ``sim://?model=...`` URL accepts.
MODELS: dict[str, ServoModel] = {
    "sts3215": STS3215_C001,
    "sts3215-c001": STS3215_C001,
    "sts3215-12v": STS3215_C018,
    "sts3215-c018": STS3215_C018,
    "sts3250": STS3250,
}
DEFAULT_MODEL = "sts3215"


def servo_model(name: str) -> ServoModel:
    """The model a name (case-insensitive) stands for; `PinArrayError` naming the known ones."""
    try:
        return MODELS[name.lower()]
    except KeyError:
        raise PinArrayError(
            f"servo model: expected one of {', '.join(MODELS)}, found {name!r}"
        ) from None


# The factory control table: Feetech's STS3215 memory table v3.6, column "Initial value".
# ID, baud rate and return delay are set by whoever builds the servo (the simulator's URL).
_FACTORY_TABLE: dict[Register, int] = {
    Register.STATUS_RETURN_LEVEL: 1,
    Register.MIN_ANGLE_LIMIT: 0,
    Register.MAX_ANGLE_LIMIT: 4095,
    Register.MAX_TEMPERATURE_LIMIT: 70,
    Register.MAX_TORQUE: 1000,
    # Phase 12 = bit 2 (speed unit 1 step/s instead of 50) + bit 3 (speed 0 means maximum):
    # "Magnetic Encoded STS Servo - Memory Table Parsing", section 3.1 Servo Phase.
    Register.PHASE: 12,
    Register.UNLOADING_CONDITION: 44,
    Register.LED_ALARM_CONDITION: 47,
    Register.P_GAIN: 32,
    Register.D_GAIN: 32,
    Register.I_GAIN: 0,
    Register.MIN_STARTUP_FORCE: 16,
    Register.CW_DEAD_ZONE: 1,
    Register.CCW_DEAD_ZONE: 1,
    Register.PROTECTION_CURRENT: 500,
    Register.ANGULAR_RESOLUTION: 1,
    Register.POSITION_OFFSET: 0,
    Register.OPERATING_MODE: 0,
    Register.PROTECTIVE_TORQUE: 20,
    Register.PROTECTION_TIME: 200,
    Register.OVERLOAD_TORQUE: 80,
    Register.SPEED_P_GAIN: 10,
    Register.OVERCURRENT_TIME: 200,
    Register.SPEED_I_GAIN: 10,
    # RAM at power-on: torque off, acceleration 0, goal 0 (an STS3215 read after power-on shows
    # Goal Position 0 wherever the horn is), torque limit = max torque, lock 0.
    Register.TORQUE_ENABLE: 0,
    Register.ACCELERATION: 0,
    Register.GOAL_POSITION: 0,
    Register.GOAL_TIME: 0,
    Register.GOAL_SPEED: 0,
    Register.TORQUE_LIMIT: 1000,
    Register.LOCK: 0,
}

# The factory return delay: 250 x 2 us = 500 us, as LeRobot's configure_motors comment and
# REFERENCE.md state for shipped servos (the v3.6 table's column says 0).
FACTORY_RETURN_DELAY_US = 500


def factory_table(model: ServoModel) -> dict[Register, int]:
    """Every register's factory value for ``model`` except ID, baud rate and return delay."""
    table = dict(_FACTORY_TABLE)
    table[Register.FIRMWARE_MAJOR], table[Register.FIRMWARE_MINOR] = model.firmware
    table[Register.MODEL_NUMBER] = model.model_number
    table[Register.MAX_VOLTAGE_LIMIT] = model.max_voltage_limit_dv
    table[Register.MIN_VOLTAGE_LIMIT] = model.min_voltage_limit_dv
    return table
