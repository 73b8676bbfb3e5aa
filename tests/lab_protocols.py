"""The ready protocols of each paradigm (protocols/), shortened for tests: the same
patterns, comparisons and SOAs, with brief stimuli and few repetitions, so that a whole run
costs the simulator little."""

from pathlib import Path

PROTOCOLS = Path(__file__).resolve().parents[1] / "protocols"
# What each copy changes, as (text in the file, text in the copy).
SHORTER = {
    "shapes": (("duration_s: 2", "duration_s: 0.2"), ("repetitions: 4", "repetitions: 2"),
               ("practice_trials: 3", "practice_trials: 1")),
    "flutter_2ifc": (("duration_s: 1\n", "duration_s: 0.5\n"),
                     ("repetitions: 4", "repetitions: 1"), ("blocks: 2", "blocks: 1"),
                     ("interval_gap_ms: 500 ", "interval_gap_ms: 200 "),
                     ("practice_trials: 4", "practice_trials: 1")),
    "toj": (("repetitions: 6", "repetitions: 1"), ("blocks: 2", "blocks: 1"),
            ("practice_trials: 4", "practice_trials: 1")),
    "localisation": (("duration_s: 10", "duration_s: 0.4"),
                     ("inter_trial_interval_s: 3", "inter_trial_interval_s: 0.1")),
    "apparent_motion": (("repetitions: 2 ", "repetitions: 1 "), ("blocks: 2", "blocks: 1")),
    "two_point": (("repetitions: 10", "repetitions: 1"), ("duration_s: 1\n", "duration_s: 0.5\n"),
                  ("practice_trials: 4", "practice_trials: 1")),
}


def short_copy(name: str, folder: Path, *more: tuple[str, str]) -> Path:
    """``protocols/NAME.yaml`` shortened (and changed by ``more``), written into ``folder``."""
    text = (PROTOCOLS / f"{name}.yaml").read_text(encoding="utf-8")
    for old, new in (*SHORTER[name], *more):
        assert old in text, (name, old)
        text = text.replace(old, new)
    path = folder / f"{name}.yaml"
    path.write_text(text, encoding="utf-8")
    return path
