"""Which driver plays a protocol's device: one entry per family of servo.

Feetech STS bus servos (`pinarray.hardware.feetech`) are the family today. A second family
(hobby PWM servos on a PCA9685 board: `pinarray.hardware.pca9685`) implements
`pinarray.hardware.driver.ArrayDriver` in its own package and adds its entry here: how its
setup follows from the device section, and how it opens a port or its simulator. The rig,
the session, the journal and the UI stay as they are.
"""

from __future__ import annotations

from pinarray.clock import Clock
from pinarray.errors import BusError, PinArrayError
from pinarray.hardware.driver import ArrayDriver, ServoSetup
from pinarray.hardware.feetech.base import BusSetup
from pinarray.hardware.feetech.faults import SIM_DEFAULT, is_sim_url
from pinarray.player.simulators import SimulatedArrays
from pinarray.protocol import Device


def bus_setup(device: Device) -> BusSetup:
    """What the STS handshake checks and sets, from a protocol's device section."""
    from pinarray.hardware.feetech.models import servo_model

    servos = tuple(
        ServoSetup(servo_id=c.servo_id, pin=c.pin, rest_steps=c.rest_steps,
                   min_steps=c.min_steps, max_steps=c.max_steps)
        for c in device.pins
    )
    try:
        model = servo_model(device.servo.model)
    except PinArrayError as error:
        raise BusError(f"device: {error}") from None
    return BusSetup(servos=servos, model_number=model.model_number,
                    speed_steps_per_s=device.servo.speed_steps_per_s,
                    acceleration_register=device.servo.acceleration_register)


def sim_url_for(url: str | None, servo_ids: tuple[int, ...]) -> str:
    """A ``sim://`` URL that simulates exactly the protocol's servo ids unless it names its own."""
    url = url or SIM_DEFAULT
    if not is_sim_url(url):
        raise PinArrayError(f"--sim expects a sim:// URL, found {url!r}")
    if "ids=" not in url:
        url += ("&" if "?" in url else "?") + "ids=" + ",".join(map(str, servo_ids))
    return url


def open_array(device: Device, port: str | None, sim_url: str | None,
               clock: Clock, simulators: SimulatedArrays | None = None) -> ArrayDriver:
    """The device's servos on ``port`` (or simulated, as ``sim_url`` says), not yet checked.

    ``simulators``: simulated arrays kept from earlier connections; the simulated servos are
    found there (as they were left) or kept there. The caller runs the handshake
    (`ArrayDriver.check_servos`, then `hold`) and closes the driver if it fails.
    """
    from pinarray.hardware.feetech.sim import SimBus
    from pinarray.hardware.feetech.transport import open_bus

    setup = bus_setup(device)
    url = port or sim_url_for(sim_url, setup.servo_ids)
    kept = None if simulators is None else simulators.find(url, SimBus)
    bus = open_bus(url, None, clock, baud_rate=device.servo.baud_rate, sim=kept)
    if simulators is not None and bus.sim is not None:
        simulators.keep(url, bus.sim)
    bus.setup = setup
    return bus
