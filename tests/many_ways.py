"""An apparent-motion protocol whose waves go every way a lab can write: along a row, up and
down a column, along a diagonal sequence of pins, and the no-wave control."""

from pathlib import Path

MANY_WAYS = """\
protocol: many_ways
stimuli:
  tap: {frequency_hz: 5, duration_s: 0.4}
  rightwards: {wave: rightwards, row: 2, pins: [5, 6, 7], train: tap, soa_ms: 200}
  leftwards: {wave: leftwards, row: 2, pins: [5, 6, 7], train: tap, soa_ms: 200}
  upwards: {wave: upwards, pins: [2, 6, 10, 14], train: tap, soa_ms: 200}
  downwards: {wave: downwards, pins: [15, 11, 7, 3], train: tap, soa_ms: 200}
  diagonal: {wave: sequence, pins: [1, 6, 11, 16], direction: up-right, train: tap, soa_ms: 200}
  still: {wave: none, row: 2, pins: [5, 6, 7], train: tap, soa_ms: 200}
design:
  paradigm: apparent_motion
  configurations: [diagonal, upwards, downwards, rightwards, leftwards, still]
  inter_trial_interval_s: 1
  practice_trials: 1
"""


def write_many_ways(folder: Path, text: str = MANY_WAYS) -> Path:
    path = folder / "many_ways.yaml"
    path.write_text(text)
    return path
