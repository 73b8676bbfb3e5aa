"""Volumes from trigger arrivals: numbered, timed from the first counted one, gaps and jitter said."""

from hypothesis import given, settings
from hypothesis import strategies as st

from pinarray.imaging.timeline import MAX_TOLERANCE_NS, VolumeTimeline, tolerance_ns
from pinarray.journal.volumes import VolumeStatus

S = 1_000_000_000
TR = 2 * S


def timeline(arrivals, dummies=0, tr_ns=TR):
    volumes = VolumeTimeline(dummies, tr_ns)
    for at_ns in arrivals:
        volumes.arrive(at_ns)
    return volumes


def statuses(rows):
    return [(row.volume, row.status.value) for row in rows]


def test_a_steady_scanner_gives_every_volume_on_time_with_time_zero_after_the_dummies():
    volumes = timeline([5 * S + k * TR for k in range(6)], dummies=2)
    rows = volumes.rows_until(5 * S + 5 * TR)
    assert volumes.zero_ns == 5 * S + 2 * TR
    assert [(r.volume, r.onset_ns, r.dummy) for r in rows] == [
        (1, -4 * S, True), (2, -2 * S, True), (3, 0, False), (4, 2 * S, False),
        (5, 4 * S, False), (6, 6 * S, False)]
    assert {r.status for r in rows} == {VolumeStatus.RECEIVED}
    assert [r.interval_ns for r in rows] == [None] + [TR] * 5


def test_nothing_is_logged_before_time_zero_and_no_time_zero_before_the_dummies_are_over():
    volumes = timeline([0, TR], dummies=2)
    assert volumes.zero_ns is None and volumes.rows_until(100 * S) == []
    volumes.arrive(2 * TR)
    assert volumes.zero_ns == 2 * TR and len(volumes.rows_until(2 * TR)) == 3


def test_a_volume_without_its_trigger_is_logged_missed_where_the_tr_put_it():
    volumes = timeline([0, TR, 2 * TR, 5 * TR])
    assert statuses(volumes.rows_until(5 * TR)) == [
        (1, "received"), (2, "received"), (3, "received"), (4, "missed"), (5, "missed"),
        (6, "received")]
    missed = [r for r in volumes.rows if r.status is VolumeStatus.MISSED]
    assert [r.onset_ns for r in missed] == [3 * TR, 4 * TR]
    assert volumes.rows[-1].interval_ns == 3 * TR and volumes.rows[-1].deviation_ns == 0


def test_a_trigger_stream_that_stops_leaves_one_missed_volume_per_tr_and_waits_for_nothing():
    volumes = timeline([0, TR, 2 * TR])
    volumes.rows_until(2 * TR)
    # Half a TR past a due volume with no trigger: it is missed (a later one would come after).
    assert volumes.rows_until(3 * TR + TR // 2 - 1) == []
    assert statuses(volumes.rows_until(3 * TR + TR // 2)) == [(4, "missed")]
    assert statuses(volumes.rows_until(10 * TR)) == [(n, "missed") for n in range(5, 11)]
    volumes.arrive(11 * TR)  # the scanner is back: numbered after the gap
    assert statuses(volumes.rows_until(11 * TR)) == [(11, "missed"), (12, "received")]


def test_a_trigger_off_the_tr_by_more_than_the_tolerance_is_irregular():
    late = tolerance_ns(TR) + 1
    volumes = timeline([0, TR, 2 * TR + late, 3 * TR + tolerance_ns(TR)])
    rows = volumes.rows_until(3 * TR)
    assert statuses(rows) == [(1, "received"), (2, "received"), (3, "irregular"), (4, "received")]
    assert rows[2].deviation_ns == late
    assert tolerance_ns(TR) == MAX_TOLERANCE_NS and tolerance_ns(S // 10) == S // 200


def test_a_repeated_character_is_an_extra_trigger_not_a_new_volume():
    volumes = timeline([0, TR, TR + 3_000_000, 2 * TR])
    rows = volumes.rows_until(2 * TR)
    assert statuses(rows) == [(1, "received"), (2, "received"), (2, "extra"), (3, "received")]
    assert rows[3].interval_ns == TR  # measured from the volume, not from the extra trigger


def test_without_a_tr_the_median_interval_is_the_tr():
    volumes = timeline([0, TR, 2 * TR, 3 * TR, 6 * TR], tr_ns=None)
    rows = volumes.rows_until(6 * TR)
    assert volumes.current_tr_ns() == TR
    assert statuses(rows)[-3:] == [(5, "missed"), (6, "missed"), (7, "received")]


def test_locked_onsets_find_a_counted_volume_by_its_arrival_or_by_the_tr():
    volumes = timeline([0, TR, 2 * TR], dummies=1)  # zero at TR
    assert volumes.counted_volume_ns(0) == TR and volumes.counted_volume_ns(1) == 2 * TR
    assert volumes.counted_volume_ns(2) is None and volumes.expected_ns(2) == 3 * TR
    assert volumes.expected_ns(5) == 6 * TR


# -- properties ----------------------------------------------------------------------------------

arrivals = st.lists(
    st.tuples(st.integers(1, 4),  # volumes since the previous trigger (2+: some missed)
              st.integers(-TR // 4, TR // 4),  # jitter of this trigger
              st.booleans()),  # followed by an extra character?
    min_size=1, max_size=40)


def streamed(steps, tr_ns=TR):
    """Arrival times of a scanner with gaps, jitter and repeated characters."""
    times, due = [0], 0
    for gap, jitter, extra in steps:
        due += gap * tr_ns
        times.append(max(times[-1], due + jitter))
        if extra:
            times.append(times[-1] + 1_000_000)
    return times


@settings(max_examples=300, deadline=None)
@given(steps=arrivals, dummies=st.integers(0, 3), given_tr=st.booleans(),
       flushes=st.lists(st.tuples(st.integers(0, 100), st.integers(-TR, TR)), max_size=60))
def test_rows_are_the_same_however_often_the_log_is_written_and_never_change(
        steps, dummies, flushes, given_tr):
    times = streamed(steps)
    end_ns = times[-1] + 10 * TR
    tr_ns = TR if given_tr else None
    whole = timeline(times, dummies, tr_ns).rows_until(end_ns)
    # The same triggers, the log written at other moments in between (time order kept), most
    # of them close to a trigger, where a volume is about to be judged late or missed.
    moments = [times[index % len(times)] + offset for index, offset in flushes]
    events = sorted([(t, 0) for t in times] + [(f, 1) for f in moments if 0 <= f <= end_ns])
    piecewise, volumes = [], VolumeTimeline(dummies, tr_ns)
    for at_ns, kind in events:
        if kind == 0:
            volumes.arrive(at_ns)
        else:
            piecewise += volumes.rows_until(at_ns)
    piecewise += volumes.rows_until(end_ns)
    assert piecewise == whole


@settings(max_examples=300, deadline=None)
@given(steps=arrivals, dummies=st.integers(0, 3))
def test_every_volume_is_logged_once_in_order_and_every_trigger_once(steps, dummies):
    times = streamed(steps)
    volumes = timeline(times, dummies)
    rows = volumes.rows_until(times[-1])
    if len(times) <= dummies:
        assert rows == []
        return
    numbered = [r.volume for r in rows if r.status is not VolumeStatus.EXTRA]
    assert numbered == list(range(1, len(numbered) + 1))
    assert sum(r.status is not VolumeStatus.MISSED for r in rows) == len(times)
    assert [r.dummy for r in rows[:dummies]] == [True] * dummies
    assert not any(r.dummy for r in rows[dummies:])
    zero = times[dummies]
    received = [r for r in rows if r.status is not VolumeStatus.MISSED]
    assert [r.onset_ns + zero for r in received] == times  # arrival times, exactly
    assert all(a.onset_ns <= b.onset_ns for a, b in zip(rows, rows[1:], strict=False))
