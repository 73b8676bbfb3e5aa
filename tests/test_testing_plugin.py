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
