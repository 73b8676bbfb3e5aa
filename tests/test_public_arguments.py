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


def test_numpy_numbers_are_numbers_to_every_call_and_numpy_bools_are_not(array, protocol):
    import numpy as np

    condition = pinarray.find_condition(protocol, pin=6, frequency_hz=3)
    assert pinarray.find_condition(protocol, pin=np.int64(6), frequency_hz=np.float64(3.0)) \
        is condition
    assert pinarray.find_condition(protocol, pin=np.uint8(6), frequency_hz=np.int32(3)) \
        is condition
    assert pinarray.plan_trials(protocol, seed=np.uint32(3)) == pinarray.plan_trials(protocol, 3)
    armed = array.arm(condition, at_ns=np.int64(array.now_ns() + 10**8))
    delivery = armed.result(np.float64(30))
    assert delivery.delivered and delivery.stroke(np.int8(6)).pin == 6
    said = refused(pinarray.find_condition, protocol, pin=np.bool_(True))
    assert said.startswith("find_condition: pin: expected a pin number from 1 to 16")


class Unprintable:
    def __repr__(self) -> str:
        raise RuntimeError("its own repr fails")


class Unpathable:
    def __fspath__(self) -> str:
        raise RuntimeError("its own __fspath__ fails")


class Incomparable:
    def __eq__(self, other: object) -> bool:
        raise RuntimeError("its own __eq__ fails")

    __hash__ = object.__hash__


@pytest.mark.parametrize("call", [
    lambda p, a: pinarray.load_protocol(Unprintable()),
    lambda p, a: pinarray.find_condition(p, pin=Unprintable()),
    lambda p, a: pinarray.open_array(p, clock=Unprintable()),
    lambda p, a: a.arm(Unprintable()),
    lambda p, a: pinarray.load_protocol(Unpathable()),
    lambda p, a: pinarray.open_array(p, port=Unpathable()),
    lambda p, a: pinarray.read_results(Unpathable()),
    lambda p, a: pinarray.load_protocol("\0"),
    lambda p, a: pinarray.load_protocol("x" * 10_000),
    lambda p, a: pinarray.read_results("x" * 10_000),
    lambda p, a: pinarray.open_array(p, port="/dev/" + "x" * 300),
    lambda p, a: a.arm(pinarray.find_condition(p, pin=6, frequency_hz=3)).result(2**200),
    lambda p, a: a.present(pinarray.find_condition(p, pin=6, frequency_hz=3)).stroke(
        Incomparable()),
], ids=lambda call: inspect.getsource(call).split("lambda p, a: ")[1].strip().rstrip(","))
def test_values_the_system_or_their_own_methods_cannot_take_are_refused_in_one_line(
        array, protocol, call):
    assert len(refused(call, protocol, array)) < 300
    if array._current is not None and not array._current.done:
        array._current.cancel()


@pytest.mark.parametrize("filters", [{"stimulus": "x" * 10_000}, {"frequency_hz": 1e-320}])
def test_a_condition_not_found_is_said_in_a_line_of_reasonable_length(protocol, filters):
    assert len(refused(pinarray.find_condition, protocol, **filters)) < 600


@pytest.mark.parametrize("model", ["x" * 10_000, "x" * 10_000 + "=1",
                                   "correct_" + "9" * 1000 + "hz=0.5"],
                         ids=["no name=number", "a long name", "a long frequency"])
def test_a_simulated_subject_model_refused_is_said_in_a_line_of_reasonable_length(protocol,
                                                                                   model):
    said = refused(pinarray.simulated_observer, protocol, model)
    assert said.startswith("observer: ") and len(said) < 300


def test_an_onset_that_has_passed_is_said_to_have_passed(array, protocol):
    condition = pinarray.find_condition(protocol, pin=6, frequency_hz=3)
    now_ns = array.now_ns()
    assert f"at_ns {now_ns - 5_000_000} had passed 5.0 ms ago" in refused(
        array.arm, condition, at_ns=now_ns - 5_000_000)
    assert "is only 5.0 ms ahead" in refused(array.arm, condition, at_ns=now_ns + 5_000_000)
    # Just short of the lead: never "20.0 ms ahead: arm it at least 20 ms ahead".
    assert f"is only {array.lead_ns / 1e6 - 0.02:.3f} ms ahead" in refused(
        array.arm, condition, at_ns=now_ns + array.lead_ns - 20_000)


def test_the_array_names_its_port_as_the_script_gave_it(protocol):
    with pinarray.open_array(protocol) as array:
        assert array.url == "sim://" and repr(array).startswith("<PinArray sim:// for ")
    assert refused(array.present, pinarray.find_condition(protocol, pin=6, frequency_hz=3)) \
        == "present: sim://: the array is closed"
    with pinarray.open_array(protocol, sim="sim://?seed=3") as array:
        assert array.url == "sim://?seed=3"


def tiny(tmp_path: Path) -> pinarray.Protocol:
    """One trial: pin 6."""
    from tests.test_library_paths import buzz

    return buzz(tmp_path, 0.4)


@pytest.mark.parametrize(("answer", "found"), [
    (True, "found True (bool)"), (False, "found False (bool)"), (6.7, "found 6.7 (float)"),
    (math.nan, "found nan (float)"), ([6], "found [6] (list)"),
])
def test_run_session_refuses_an_answer_that_is_no_pin_never_recording_another(tmp_path, answer,
                                                                             found):
    # True is 1 to Python and 6.7 rounds down to 6: never pins to a lab.
    said = refused(pinarray.run_session, tiny(tmp_path), lambda question: answer,
                   subject="01", results=tmp_path / "results")
    assert said.startswith("run_session: answer: expected a pin's number") and found in said


def test_run_session_takes_numpy_pins_and_says_an_answer_its_paradigm_refuses(tmp_path):
    import numpy as np

    protocol = tiny(tmp_path)
    run = pinarray.run_session(protocol, lambda question: np.int64(6), subject="01",
                               results=tmp_path / "results")
    assert [row.response for row in run.records] == ["6"]
    said = refused(pinarray.run_session, protocol, lambda question: 17, subject="02",
                   results=tmp_path / "results")
    assert said == ("run_session: answer: expected a pin number from 1 to 16 or 'none', "
                    "found 17")


@pytest.mark.parametrize("subject", ["../x", "", "a_b"])
def test_run_session_refuses_a_label_in_the_librarys_words(tmp_path, subject):
    said = refused(pinarray.run_session, tiny(tmp_path), print, subject=subject,
                   results=tmp_path)
    assert said.startswith("run_session: subject: expected letters and digits only")


def test_every_error_these_public_calls_raise_is_a_public_class(tmp_path):
    # The port lost mid-run; results that are not results; nothing to resume.
    protocol = tiny(tmp_path)
    condition = pinarray.find_condition(protocol, pin=6)
    with pinarray.open_array(protocol, sim="sim://?vanish_after=250") as array:
        with pytest.raises(pinarray.PlaybackAborted):
            while True:
                array.present(condition)
        assert "lost" in refused(array.present, condition)  # PortLost, public
    assert "not a pinarray run file" in refused(pinarray.read_results, protocol.source)
    assert "no unfinished" in refused(pinarray.run_session, protocol, print, subject="01",
                                      results=tmp_path, resume=True)
    said = refused(pinarray.open_array, protocol, sim="sim://?vanish_after=3")
    assert "lost while pinging servo 2" in said
