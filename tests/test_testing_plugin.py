"""The mock array a lab's own tests hold: pytest finds the plugin by entry point, loading it
costs a test run nothing, every array a test opened is closed after it, and a failed
assertion says what was expected and what was found."""

import subprocess
import sys
from importlib.metadata import entry_points

import pytest

import pinarray
from pinarray.testing import (
    ArrayOpener,
    assert_every_goal_confirmed,
    assert_left_safe,
    assert_pin_moved,
)
from tests.test_library import LOCALISATION


def test_pytest_finds_the_plugin_through_its_entry_point():
    (plugin,) = [e for e in entry_points(group="pytest11") if e.name == "pinarray"]
    assert plugin.value == "pinarray.testing.plugin"
    assert callable(plugin.load().simulated_array)


def test_pytest_says_how_closely_the_fixture_simulates_the_array():
    (plugin,) = [e for e in entry_points(group="pytest11") if e.name == "pinarray"]
    header = plugin.load().pytest_report_header(None)
    assert header.startswith("pinarray: simulated_array plays bus servos in virtual time at the "
                             "packet level: exchanges computed whole (the wire's results, byte "
                             "for byte; a URL's fidelity= chooses wire, motion)")


def test_loading_the_plugin_imports_neither_the_array_nor_numpy():
    shown = "import sys; print(*sorted(m for m in sys.modules if m.split('.')[0] in ('numpy', 'pinarray')))"
    loaded = subprocess.run([sys.executable, "-c", f"import pinarray.testing.plugin; {shown}"],
                            capture_output=True, text=True, check=True, timeout=60).stdout.split()
    assert loaded == ["pinarray", "pinarray.testing", "pinarray.testing.plugin", "pinarray.version"]


def test_every_array_opened_is_closed_with_its_opener_pins_at_rest_torque_off():
    with ArrayOpener() as opener:
        first, second = opener(LOCALISATION), opener(LOCALISATION, "sim://?seed=2")
    for array in (first, second):
        report = array.close()  # closed already: the same report again
        assert report.complete and sorted(report.released_ids) == list(range(1, 17))


def test_a_stroke_that_differs_says_how_far_the_pin_moved_of_how_far_it_was_commanded(
        simulated_array):
    array = simulated_array(LOCALISATION, "sim://?speed=1500")
    delivery = array.present(pinarray.find_condition(array.protocol, pin=6, frequency_hz=10))
    assert_every_goal_confirmed(delivery)
    with pytest.raises(AssertionError, match=r"expected pin 6 to move 65 steps \(within 3\), "
                                             r"found \d+ of 65 commanded"):
        assert_pin_moved(delivery, pin=6, steps=65)
    with pytest.raises(AssertionError, match="expected pin 7 to move 65 steps, found no stroke "
                                             r"measured for it \(pins measured: 6\)"):
        assert_pin_moved(delivery, pin=7, steps=65)


@pytest.mark.realtime
@pytest.mark.parametrize("over_serial", [False, True], ids=["in-process", "over a serial port"])
def test_a_labs_test_holds_the_array_either_way_faults_included(simulated_array, tmp_path,
                                                                  over_serial):
    from tests.test_library_paths import buzz

    protocol = buzz(tmp_path, 0.4)
    array = simulated_array(protocol, "sim://?overheat=6", over_serial=over_serial)
    assert array.simulated is not over_serial  # over a serial port it is a device, as real ones
    with pytest.raises(pinarray.PlaybackAborted, match="servo 6 .pin 6. reports overheat") as aborted:
        array.present(pinarray.find_condition(protocol, pin=6))
    assert type(aborted.value) is pinarray.PlaybackAborted  # the public class, on either path
    assert aborted.value.safe_stop.complete
    assert_left_safe(array)


PWM = LOCALISATION.with_name("localisation_pwm.yaml")


@pytest.mark.realtime
@pytest.mark.parametrize(("arguments", "expected"), [
    ((LOCALISATION, 5), "simulated_array: url: expected a sim:// URL"),
    ((LOCALISATION, b"sim://"), "simulated_array: url: expected a sim:// URL"),
    ((LOCALISATION, "sim://pca9685"), "simulated_array: url: protocol 'localisation' takes a "
                                      "sim:// URL of bus servos"),
    ((LOCALISATION, "sim://?bogus=1"), "sim://?bogus=1: unknown key(s) bogus"),
    ((LOCALISATION, "sim://?drop=1.5"), "sim://?drop=1.5: sim URL key drop: expected 0 to 1"),
    ((None,), "simulated_array: protocol: expected a Protocol (pinarray.load_protocol) or a "
              "protocol file's path, found None"),
    ((5,), "simulated_array: protocol: expected a Protocol"),
    ((b"/x",), "simulated_array: protocol: expected a Protocol"),
    ((PWM,), "simulated_array: over_serial: protocol 'localisation_pwm' drives hobby servos on "
             "a PCA9685 board, which sits on an I2C bus, not a serial port: open it without "
             "over_serial"),
])
def test_an_array_over_a_serial_port_checks_its_arguments_as_open_array_does(arguments,
                                                                             expected):
    with ArrayOpener() as opener, pytest.raises(pinarray.PinArrayError) as refused:
        opener(*arguments, over_serial=True)
    said = str(refused.value)
    assert said.startswith(expected), said
    assert "\n" not in said and "ids=1," not in said and "pinarray pwm" not in said
    assert not opener._servers  # refused before a bus was served


@pytest.mark.parametrize("over_serial", [1, "no", None, 0.0])
def test_over_serial_is_true_or_false_never_something_taken_for_either(over_serial):
    with ArrayOpener() as opener, pytest.raises(pinarray.PinArrayError,
                                                match="simulated_array: over_serial: expected "
                                                      "True or False"):
        opener(LOCALISATION, over_serial=over_serial)
