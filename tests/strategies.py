"""Hypothesis strategies shared by the test suite."""

from hypothesis import strategies as st

from pinarray.grid import Grid

# Every character UTF-8 can encode (all but the surrogates), as Hypothesis's own default for
# text and regular expressions, `characters(codec="utf-8")`: the same characters and the same
# examples, but read from Hypothesis's table of Unicode categories (0.2 s of processor to build
# in a fresh clone) rather than by encoding each of the 1.1 million code points (3 s, in every
# test process that draws text before one of them has kept the table in .hypothesis/).
unicode_characters = st.characters(exclude_categories=["Cs"])

grids = st.builds(
    Grid,
    rows=st.integers(1, 12),
    columns=st.integers(1, 12),
    pitch_mm=st.sampled_from([1.0, 2.0, 2.5]),
)


@st.composite
def grid_and_two_pins(draw):
    grid = draw(grids)
    pins = st.integers(1, grid.pin_count)
    return grid, draw(pins), draw(pins)


# -- simulated servo motion (pinarray.hardware.feetech.sim_motion) ------------------------------------------

def servo_drives(lash: bool = True):
    """Speed and acceleration limits of a simulated servo, with or without backlash."""
    from pinarray.hardware.feetech.sim_motion import Drive

    speeds = st.floats(20.0, 4000.0)
    return st.builds(
        lambda v, a, b: Drive(v, v, a, b),
        speeds,
        st.floats(200.0, 400_000.0),
        st.floats(0.0, 25.0) if lash else st.just(0.0),
    )


positions_steps = st.integers(0, 4095).map(float)

# -- protocols: valid documents, then structure-aware mutations of them ------------------------
#
# A document is Python data (dicts, lists, numbers, text) emitted as YAML by `to_yaml`, so
# that a mutation can replace any value with one of another shape, tag or size, delete or
# add keys, or alias one part into another; `Raw` values are emitted exactly as written
# (tags, aliases, exponents that must reach the loader as text). Text-level mutations then
# damage the emitted file (stray characters, a cut, a repeated line, an encoding).


class Raw(str):
    """YAML emitted as written: ``Raw("!!bool maybe")``, ``Raw("1e999999999")``."""


def to_yaml(value, indent: int = 0) -> str:
    """Block mappings, flow lists and scalars; names plain, other text double-quoted (JSON
    strings are valid YAML)."""
    pad = "  " * indent
    if isinstance(value, dict):
        if not value:
            return "{}"
        lines = []
        for key, item in value.items():
            if isinstance(item, dict) and item:
                lines.append(f"{pad}{_scalar(key)}:\n{to_yaml(item, indent + 1)}")
            else:
                lines.append(f"{pad}{_scalar(key)}: {to_yaml(item, indent + 1)}")
        return "\n".join(lines)
    if isinstance(value, list):
        return "[" + ", ".join(_flow(v) for v in value) + "]"
    return _scalar(value)


def _flow(value) -> str:
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_scalar(k)}: {_flow(v)}" for k, v in value.items()) + "}"
    return to_yaml(value)


def _scalar(value) -> str:
    import json
    import re

    if isinstance(value, Raw):
        return str(value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if value is None:
        return "null"
    if isinstance(value, int | float):
        return repr(value)
    text = str(value)
    if re.fullmatch(r"[a-z_][a-z0-9_]*", text) and text not in _YAML_WORDS:
        return text  # plain, as people write names and keys
    return json.dumps(text)


_YAML_WORDS = {"y", "n", "yes", "no", "on", "off", "true", "false", "null"}


def _decimal(low: int, high: int, places: int) -> st.SearchStrategy[Raw]:
    """Exact decimals such as 2.5, written as text the loader reads exactly."""
    return st.integers(low * 10**places, high * 10**places).map(
        lambda n: Raw(f"{n // 10**places}.{n % 10**places:0{places}d}") if places else Raw(str(n))
    )


# The strategies that depend on nothing drawn are built once, here: Hypothesis validates a
# strategy and works out its properties at its first draw, so one built inside a composite for
# every example costs that every time; those that depend on a drawn size are given hashable
# arguments, so that Hypothesis keeps them too. The documents drawn are the same.
_names = st.sampled_from(["fuzz", "lab test", "p1"])
_feasibilities = st.sampled_from(["reject", "scale"])
_frequencies = st.one_of(st.integers(1, 12), _decimal(1, 12, 1))
_durations = _decimal(0, 2, 1).filter(lambda r: float(r) > 0)
_TAP_OPTIONS = (("pulses_per_cycle", st.sampled_from([2, 4, 10])),
                ("duty_cycle", st.sampled_from([Raw("0.5"), Raw("0.25")])),
                ("pulse_width_ms", st.just({"up": Raw("2.0"), "down": Raw("1.5")})),
                ("phase_deg", st.integers(0, 720)))
_localisation_frequencies = st.lists(st.integers(1, 10), min_size=1, max_size=3)
_wave_kinds = st.lists(st.sampled_from(["rightwards", "leftwards", "none"]),
                       min_size=1, max_size=3, unique=True)
_soas = st.sampled_from([Raw("175.3"), 500, 2500])
_DESIGN_OPTIONS = (("repetitions", st.integers(1, 3)), ("blocks", st.integers(1, 3)),
                   ("order", st.sampled_from(["sequential", "random", "full_random",
                                              "latin_square"])),
                   ("constraints", st.just({"no_repeat": ["pin"]})),
                   ("seed", st.integers(0, 2**32)),
                   ("inter_trial_interval_s", _decimal(0, 3, 1)),
                   ("practice_trials", st.integers(0, 3)))


@st.composite
def protocol_documents(draw) -> dict:
    """A protocol as a lab might write it: mostly valid, small, either paradigm."""
    rows, columns = draw(st.integers(1, 6)), draw(st.integers(1, 6))
    pins = list(range(1, rows * columns + 1))
    document: dict = {"protocol": draw(_names)}
    device: dict = {"grid": {"rows": rows, "columns": columns}}
    if draw(st.booleans()):
        device["calibration"] = {"rest_steps": 2048, "positions": {Raw("1.5"): 2048,
                                                                   Raw("2.0"): 2162},
                                 "limits_steps": [2000, 2200]}
    if draw(st.booleans()):
        device["feasibility"] = draw(_feasibilities)
    if draw(st.booleans()):
        device["servo_ids"] = {draw(st.sampled_from(tuple(pins))): draw(st.integers(0, 252))}
    document["device"] = device
    tap = {"frequency_hz": draw(_frequencies), "duration_s": draw(_durations)}
    for key, strategy in _TAP_OPTIONS:
        if draw(st.booleans()):
            tap[key] = draw(strategy)
    stimuli: dict = {"tap": tap}
    design: dict
    if draw(st.booleans()):
        chosen = draw(st.lists(st.sampled_from(tuple(pins)), min_size=1, max_size=4,
                               unique=True))
        design = {"paradigm": "localisation", "stimulus": "tap", "pins": chosen,
                  "frequencies_hz": draw(_localisation_frequencies)}
    else:
        row = draw(st.integers(1, rows))
        row_pins = pins[(row - 1) * columns: row * columns]
        odd = row_pins[: len(row_pins) - (1 - len(row_pins) % 2)] or row_pins
        kinds = draw(_wave_kinds)
        for kind in kinds:
            stimuli[f"wave_{kind}"] = {"wave": kind, "row": row, "pins": odd, "train": "tap",
                                       "soa_ms": draw(_soas)}
        design = {"paradigm": "apparent_motion", "configurations": [f"wave_{k}" for k in kinds]}
    for key, strategy in _DESIGN_OPTIONS:
        if draw(st.booleans()):
            design[key] = draw(strategy)
    document["stimuli"] = stimuli
    document["design"] = design
    return document


# Values of every shape the schema does not expect where it expects them.
_exponents = st.integers(-10**12, 10**12)
nasty_values = st.one_of(
    st.sampled_from([
        Raw("1e999999999"), Raw("-1e999999999"), Raw('"1e-999999999"'), Raw("1.0e400"),
        Raw("1.0e-400"), Raw('"1/0"'), Raw('"1/3"'), Raw(".nan"), Raw("-.inf"), Raw(".inf"),
        Raw("0x1F"), Raw("0o17"), Raw("1_000"), Raw("1:30"), Raw("1:30.5"), Raw("2024-13-45"),
        Raw("2024-01-01"), Raw("!!bool maybe"), Raw("!!timestamp nope"), Raw("!!int 5.5"),
        Raw("!!float x"), Raw("!!null 3"), Raw("!!binary AAAA"), Raw("!!set {a: 1}"),
        Raw("!!omap [a: 1]"), Raw("!!python/name:os.system x"), Raw("!custom 1"),
        Raw("!!str 5"), Raw("~"), Raw("yes"), Raw("''"), Raw('"  "'), Raw("*nowhere"),
        Raw("9" * 60), Raw("1" + "0" * 5000), Raw('"' + "7" * 5000 + '"'), Raw("<<"), Raw("="),
        Raw("-0"), Raw("+5"), Raw(".5"), Raw("5."), Raw('"\\t5\\n"'), Raw('"\\u00e9"'),
        {}, [], [[[]]], {"a": {"b": 1}}, [{"x": 1}], -1, 0, 2**63, -(2**63) - 1,
        "x" * 300, True, None,
    ]),
    _exponents.map(lambda e: Raw(f"1e{e}")),
    _exponents.map(lambda e: Raw(f'"2.5E{e}"')),
    st.integers(-(10**40), 10**40),
    st.fractions().map(lambda f: Raw(f'"{f}"')),
    st.text(unicode_characters, max_size=20),
)


def _paths(value, prefix=()):
    """Every (container path, key or index) in a document, outermost first."""
    items = value.items() if isinstance(value, dict) else enumerate(value)
    for key, item in items:
        yield prefix, key
        if isinstance(item, dict | list):
            yield from _paths(item, (*prefix, key))


def _at(document, path):
    for key in path:
        document = document[key]
    return document


_mutations = st.sampled_from(["replace", "replace", "replace", "delete", "add", "graft", "alias"])
_added_keys = st.sampled_from(["frequncy_hz", "extra", "design", "pins", 7, "wave"])


@st.composite
def mutated_documents(draw) -> dict:
    """A protocol document with one to four structural mutations."""
    import copy

    document = copy.deepcopy(draw(protocol_documents()))
    for _ in range(draw(st.integers(1, 4))):
        places = list(_paths(document))
        if not places:
            break
        path, key = draw(st.sampled_from(places))
        parent = _at(document, path)
        action = draw(_mutations)
        if action == "replace":
            parent[key] = copy.deepcopy(draw(nasty_values))
        elif action == "delete":
            del parent[key]
        elif action == "add" and isinstance(parent, dict):
            parent[draw(_added_keys)] = copy.deepcopy(draw(nasty_values))
        elif action == "add":
            parent.append(copy.deepcopy(draw(nasty_values)))
        elif action == "graft":  # a whole subtree where something else belongs
            other_path, other_key = draw(st.sampled_from(places))
            parent[key] = copy.deepcopy(_at(document, other_path)[other_key])
        else:  # an anchor on one value, an alias to it elsewhere
            other_path, other_key = draw(st.sampled_from(places))
            target = _at(document, other_path)
            if isinstance(target[other_key], dict | list):
                continue
            target[other_key] = Raw(f"&shared {to_yaml(target[other_key]) or '~'}")
            parent[key] = Raw("*shared")
    return document


_text_actions = st.sampled_from(["none", "none", "insert", "cut", "repeat", "tab"])
_stray_characters = st.sampled_from(
    ["\0", "\x07", "\ufeff", "\u2028", "\x85", ":", "-", "[", "{", "'", '"', "&a ", "*a",
     "!", "%", "@", "`", "\t", "\r", "#", ">", "|", "é", "😀"])
_encodings = st.sampled_from(
    ["utf-8", "utf-8", "utf-8", "utf-8-sig", "utf-16", "utf-16-le", "utf-32", "latin-1", "crlf"])


def _text_mutation(draw, text: str) -> str:
    action = draw(_text_actions)
    if action == "none" or not text:
        return text
    at = draw(st.integers(0, len(text)))
    if action == "insert":
        return text[:at] + draw(_stray_characters) + text[at:]
    if action == "cut":
        return text[:at]
    if action == "tab":
        return text.replace("  ", "\t", 1)
    lines = text.split("\n")
    line = draw(st.integers(0, len(lines) - 1))
    return "\n".join(lines[: line + 1] + lines[line:])


_documents = st.one_of(protocol_documents(), mutated_documents(), mutated_documents())


@st.composite
def protocol_files(draw) -> bytes:
    """The bytes of a protocol file: a mutated document, damaged as text, in some encoding."""
    document = draw(_documents)
    text = _text_mutation(draw, to_yaml(document) + "\n")
    encoding = draw(_encodings)
    if encoding == "crlf":
        return text.replace("\n", "\r\n").encode("utf-8", errors="surrogatepass")
    return text.encode(encoding, errors="replace")


def alias_bomb(levels: int, width: int) -> str:
    """The 'billion laughs': each level a list of ``width`` aliases of the level below."""
    lines = ["a0: &a0 [lol]"]
    for level in range(1, levels + 1):
        lines.append(f"a{level}: &a{level} [" + ", ".join([f"*a{level - 1}"] * width) + "]")
    return "\n".join(lines) + f"\nprotocol: *a{levels}\nstimuli: *a{levels}\ndesign: *a{levels}\n"
