"""Protocol files: YAML text -> a validated, frozen `Protocol`, or every problem at file:line:col.

The sections are read by their own modules (`device`, `stimuli`, `design`); this one reads
the file, with a size cap, and puts them together. The schema is documented for lab members
in ``protocols/README.md``.
"""

from __future__ import annotations

import hashlib
import unicodedata
from pathlib import Path
from typing import TYPE_CHECKING

from pinarray.errors import ProtocolError, ProtocolErrors
from pinarray.protocol.design import read_design
from pinarray.protocol.device import read_device
from pinarray.protocol.imaging import read_sync
from pinarray.protocol.model import Protocol, Stimulus
from pinarray.protocol.stimuli import read_stimuli
from pinarray.protocol.yaml_nodes import Node, Reader, shown
from pinarray.text_files import NotText, decode_text, read_bounded

if TYPE_CHECKING:
    from pinarray.protocol.seam import Rehearse

# The seed's protocols are about 1 KiB; a 64x64 grid calibrated pin by pin stays well below.
MAX_PROTOCOL_BYTES = 1 << 20
# The protocol's name is its runs' task label: sub-<subject>_ses-<session>_task-<label>_run-<k>
# begins every file name of a run, and a file name holds at most 255 bytes. The longest (the
# motion recording's sidecar as it is written, `pinarray.journal.paths.RunPaths`) holds 66
# beside the label with one-character subject and session labels: a longer label no run writes.
MAX_TASK_LABEL_CHARS = 255 - 66


def load_protocol(path: str | Path, *, long_trials: bool = False,
                  rehearse: Rehearse | None = None) -> Protocol:
    """Read and validate a protocol file; raise `ProtocolErrors` listing every problem.

    ``long_trials``: read to be compiled to a file, never played, so a trial may hold more
    pulses than one may play (see `pinarray.protocol.design`). ``rehearse``: every condition
    is also played on the model it stands for, and refused where it is not delivered there
    (`pinarray validate` gives it the simulated array: `pinarray.player.rehearsal`).
    """
    try:
        text = decode_text(read_bounded(path, MAX_PROTOCOL_BYTES, "protocol"))
    except NotText as problem:
        raise ProtocolErrors(
            [ProtocolError(problem.message, str(path), problem.line, problem.col)]
        ) from None
    return parse_protocol(text, str(path), long_trials=long_trials, rehearse=rehearse)


def parse_protocol(
    text: str, source: str = "<protocol>", *, long_trials: bool = False,
    rehearse: Rehearse | None = None,
) -> Protocol:
    reader = Reader(source)
    root = reader.compose(text, "a protocol mapping (protocol:, stimuli:, design:)")
    _refuse_a_response_file(reader, root)
    none: dict[str, Node] = {}
    top = reader.attempt(
        lambda: reader.mapping(
            root,
            {"protocol", "description", "device", "stimuli", "design", "sync"},
            {"protocol", "stimuli", "design"},
            "protocol",
        ),
        none,
    )
    name = reader.optional(top, "protocol", lambda n: _name(reader, n), "")
    description = reader.optional(
        top, "description", lambda n: reader.string(n, "the description"), ""
    )
    before = reader.harmless
    device = read_device(reader, top.get("device"))
    reader.guessing = reader.harmless > before
    nothing: tuple[tuple[Stimulus, ...], dict[str, Node]] = ((), {})
    stimuli, declared = reader.optional(
        top, "stimuli", lambda n: read_stimuli(reader, n, device), nothing
    )
    design = None
    if device is not None:
        design = reader.optional(
            top, "design", lambda n: read_design(reader, n, device, stimuli, declared, long_trials,
                                  rehearse),
            None,
        )
    sync = reader.optional(top, "sync", lambda n: read_sync(reader, n), None)
    reader.raise_if_errors()
    assert device is not None and design is not None
    return Protocol(
        name,
        description,
        device,
        stimuli,
        design,
        source,
        hashlib.sha256(text.encode("utf-8")).hexdigest(),
        sync,
    )


# The keys a `pinarray servos response` file holds and a protocol never does at its top.
_RESPONSE_FILE_KEYS = frozenset({"pin", "points"})


def _refuse_a_response_file(reader: Reader, root: Node) -> None:
    """A servo response file (written beside the protocol, so `validate protocols/*.yaml`
    meets it) is said to be one, in one line, not taken for a protocol missing every key."""
    from yaml import MappingNode, ScalarNode

    if not isinstance(root, MappingNode):
        return
    keys = {key.value for key, _ in root.value if isinstance(key, ScalarNode)}
    if _RESPONSE_FILE_KEYS <= keys and not keys & {"protocol", "stimuli", "design"}:
        reader.error(root, "expected a protocol (protocol:, stimuli:, design:), found a servo "
                           "response file (`pinarray servos response` writes it; a protocol names it "
                           "under device: response)")
        reader.raise_if_errors()


def task_label(name: str) -> str:
    """The BIDS task label a protocol's name gives its runs' files: its letters and digits,
    spaces and punctuation dropped."""
    return "".join(ch for ch in name if ch.isalnum())


def _name(reader: Reader, node: Node) -> str:
    """The protocol's name, refused where its runs' files could not carry it as their label."""
    name = reader.string(node, "the protocol name")
    label = task_label(name)
    # One rule for every character: what the task label keeps (ASCII letters and digits) or
    # drops (ASCII spaces and punctuation); anything else (a letter of another script, an
    # accent, an emoji, a zero-width or control character) is refused, not silently dropped.
    odd = next((ch for ch in name if not " " <= ch <= "~"), None)
    if odd is not None or not label:
        why = ("no letter nor digit" if odd is None else
               f"U+{ord(odd):04X} ({unicodedata.name(odd, 'a control character')}) is none "
               "of them")
        raise reader.error(node, "expected a protocol name of ASCII letters and digits (they make "
                                 "the BIDS task label in its runs' file names) and ASCII spaces "
                                 f"and punctuation (dropped from it), found {shown(name)}: {why}")
    if len(label) > MAX_TASK_LABEL_CHARS:
        raise reader.error(node, f"expected a protocol name of at most {MAX_TASK_LABEL_CHARS} "
                                 "letters and digits (its runs' task label, in file names of at "
                                 f"most 255 bytes), found {len(label)}")
    return name


def protocol_warnings(protocol: Protocol) -> list[str]:
    """What a valid protocol may still get wrong, one line each (e.g. a duration cue)."""
    from pinarray.protocol.cues import cut_lifts, duration_cues

    return (duration_cues(protocol) + cut_lifts(protocol)
            + protocol.design.paradigm.warnings(protocol))


def validate_file(path: str | Path, rehearse: Rehearse | None = None,
                  ) -> tuple[Protocol | None, list[str]]:
    """(protocol, problem lines) for the CLI: problems are ``file:line:col: message`` lines
    (``rehearse``: as `load_protocol`'s)."""
    try:
        return load_protocol(path, rehearse=rehearse), []
    except ProtocolErrors as problems:
        return None, [e.located() for e in problems.errors]
    except ProtocolError as problem:
        return None, [problem.located()]
