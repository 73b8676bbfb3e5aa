"""A library's manners: every public call checks its arguments at the door. A wrong one is a
one-line `PinArrayError` (of a class `import pinarray` names) in the library's words, raised
before anything is opened or moved; never a `TypeError` from deep inside, never a hang, and
the array it was given stays usable and closes safely."""

import inspect
import math
from fractions import Fraction
from pathlib import Path

import pytest

import pinarray
import pinarray.testing

LOCALISATION = Path(__file__).resolve().parents[1] / "protocols" / "localisation.yaml"


@pytest.fixture(scope="module")
def protocol():
    return pinarray.load_protocol(LOCALISATION)


@pytest.fixture
def array(protocol):
    array = pinarray.open_array(protocol)
    yield array
    pinarray.testing.assert_left_safe(array)  # whatever was refused, it closes safely


def refused(call, *args, **kwargs) -> str:
    """The call is refused with one line, of a public class; that line."""
    with pytest.raises(pinarray.PinArrayError) as raised:
        call(*args, **kwargs)
    kind = type(raised.value)
    assert getattr(pinarray, kind.__name__, None) is kind, f"{kind} is not a public class"
    message = str(raised.value)
    assert message and "\n" not in message, message
    return message


def test_a_float_onset_is_refused_and_the_array_still_plays_and_closes(array, protocol):
    condition = pinarray.find_condition(protocol, pin=6, frequency_hz=3)
    said = refused(array.arm, condition, at_ns=array.now_ns() + 5e7)
    assert said.startswith("arm: at_ns: expected a time in integer nanoseconds (as an int: ")
    assert array.present(condition).delivered  # the clock was not poisoned


def test_an_onset_beyond_the_horizon_is_refused_at_once_not_waited_for(array, protocol):
    condition = pinarray.find_condition(protocol, pin=6, frequency_hz=3)
    said = refused(array.arm, condition, at_ns=2**62)
    assert "at most 60 s ahead (is it in ns?)" in said
    refused(array.present, condition, at_ns=array.now_ns() + 3600 * 10**9)


@pytest.mark.parametrize(("at_ns", "expected"), [
    (True, "expected a time in integer nanoseconds"),
    ("soon", "expected a time in integer nanoseconds"),
    (-1, "arm it at least 20 ms ahead"),
])
def test_onsets_that_are_not_times_ahead_are_refused(array, protocol, at_ns, expected):
    condition = pinarray.find_condition(protocol, pin=6, frequency_hz=3)
    assert expected in refused(array.arm, condition, at_ns=at_ns)


@pytest.mark.parametrize("filters", [
    {"pin": True}, {"pin": 17}, {"pin": "6"}, {"pin": 6.0},
    {"frequency_hz": math.nan}, {"frequency_hz": math.inf}, {"frequency_hz": -3},
    {"frequency_hz": "10"}, {"stimulus": 5},
])
def test_find_condition_refuses_filters_of_the_wrong_kind(protocol, filters):
    (name,) = filters
    assert refused(pinarray.find_condition, protocol, **filters).startswith(
        f"find_condition: {name}: expected ")


@pytest.mark.parametrize(("settings", "expected"), [
    ({"sim": 5}, "open_array: sim: expected a sim:// URL"),
    ({"sim": "fast"}, "open_array: sim: expected a sim:// URL"),
    ({"port": 5}, "open_array: port: expected a serial device's path"),
    ({"port": "sim://"}, "open_array: port: 'sim://' is a simulated array: give it as sim="),
    ({"clock": "fast"}, "open_array: clock: expected a Clock"),
    ({"clock": pinarray.MonotonicClock}, "open_array: clock: expected a Clock"),
    ({"sim": "sim://?drop=lots"}, "sim://?drop=lots: sim URL key drop: expected a number"),
    ({"sim": "sim://pca9685"}, "protocol 'localisation' takes a sim:// URL of bus servos"),
    ({"port": "/dev/x", "sim": "sim://"}, "give a port (real servos) or a sim URL, not both"),
])
def test_open_array_refuses_wrong_settings_in_the_scripts_own_words(protocol, settings,
                                                                     expected):
    said = refused(pinarray.open_array, protocol, **settings)
    assert expected in said and "--sim" not in said and "ids=1," not in said


def test_a_session_refuses_a_sim_url_in_the_scripts_own_words(protocol, tmp_path):
    said = refused(pinarray.run_session, protocol, print, subject="01", results=tmp_path,
                   sim="sim://?drop=lots")
    assert said == "sim://?drop=lots: sim URL key drop: expected a number, found 'lots'"


@pytest.mark.parametrize("call", [
    lambda p: pinarray.load_protocol(5),
    lambda p: pinarray.load_protocol(None),
    lambda p: pinarray.plan_trials(str(LOCALISATION)),
    lambda p: pinarray.plan_trials(p, seed=-1),
    lambda p: pinarray.plan_trials(p, seed=1.5),
    lambda p: pinarray.open_array(str(LOCALISATION)),
    lambda p: pinarray.find_servo_ports("/dev/ttyUSB0"),
    lambda p: pinarray.find_servo_ports([5]),
    lambda p: pinarray.read_results(),
    lambda p: pinarray.read_results(5),
    lambda p: pinarray.simulated_observer(None),
    lambda p: pinarray.simulated_observer(p, 5),
    lambda p: pinarray.simulated_observer(p, seed="7"),
    lambda p: pinarray.run_session(p, 5, subject="01"),
    lambda p: pinarray.run_session(p, print, subject=1),
    lambda p: pinarray.run_session(p, print, subject="01", results=None),
    lambda p: pinarray.run_session(p, print, subject="01", seed="7"),
    lambda p: pinarray.run_session(p, print, subject="01", resume="yes"),
    lambda p: pinarray.run_session(p, print, subject="01", clock=5),
    lambda p: pinarray.run_session(p, print, subject="01", sim="sim://pca9685"),
    lambda p: pinarray.testing.assert_delivered(5),
    lambda p: pinarray.testing.assert_not_delivered(None, because="late"),
    lambda p: pinarray.testing.assert_left_safe("array"),
    lambda p: pinarray.testing.ArrayOpener()(5),
    lambda p: pinarray.testing.ArrayOpener()(p, 5),
    lambda p: pinarray.testing.ArrayOpener()(p, over_serial=True,
                                             clock=pinarray.VirtualClock()),
], ids=lambda call: inspect.getsource(call).split("lambda p: ")[1].strip().rstrip(","))
def test_wrong_arguments_to_the_public_calls_are_refused_in_one_line(protocol, call):
    refused(call, protocol)


def test_the_arrays_own_calls_refuse_what_is_not_theirs(array, protocol):
    condition = pinarray.find_condition(protocol, pin=6, frequency_hz=3)
    assert refused(array.present, "pin 6").startswith("present: stimulus: expected a planned "
                                                      "trial or a condition")
    refused(array.prepare, 6)
    armed = array.arm(condition)
    for timeout in ("1", math.nan, -1, Fraction(-1)):
        refused(armed.result, timeout)
    armed.cancel()
    delivery = array.present(condition)
    refused(delivery.stroke, "6")


def test_every_parameter_of_every_public_function_given_a_stranger_is_refused(protocol):
    # object() is no valid value of any parameter: whichever it is given to, a public call
    # refuses it in one line (each other argument a valid one).
    valid = {"protocol": protocol, "path": LOCALISATION, "answer": lambda q: "none",
             "subject": "01", "text": LOCALISATION.read_text()}
    functions = [getattr(pinarray, name) for name in pinarray.__all__
                 if inspect.isfunction(getattr(pinarray, name))]
    assert {f.__name__ for f in functions} >= {"open_array", "find_condition", "run_session"}
    for function in functions:
        parameters = inspect.signature(function).parameters
        for name, parameter in parameters.items():
            arguments = {n: valid[n] for n in parameters if n in valid and n != name}
            if parameter.kind is parameter.VAR_POSITIONAL:
                refused(function, object())
            elif parameter.kind is parameter.KEYWORD_ONLY:
                refused(function, **arguments, **{name: object()})
            else:
                refused(function, **{**arguments, name: object()})
