"""QUEST+: the expected-entropy shortcut against the entropy computed directly, the threshold
recovered by simulated subjects, replay, stability, stopping and refusals."""

import warnings
from decimal import Decimal, localcontext

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pinarray.adaptive.observer import PsychometricObserver
from pinarray.adaptive.psychometric import Psychometric
from pinarray.adaptive.questplus import QuestPlus, QuestPlusRule, normal_weights
from pinarray.errors import PinArrayError

# Stroke lengths in mm, log-spaced, and a 2AFC task (guess 0.5); thresholds reach past the
# domain's ends so the posterior is not pinned to the grid's edge.
INTENSITIES = tuple(float(v) for v in np.geomspace(0.5, 40.0, 30))
THRESHOLDS = tuple(float(v) for v in np.geomspace(0.4, 50.0, 40))
SLOPES = (1.5, 2.5, 3.5, 4.5)
LAPSES = (0.0, 0.02, 0.05)


def rule(**fields) -> QuestPlusRule:
    return QuestPlusRule(**{"kind": "weibull", "intensities": INTENSITIES, "thresholds": THRESHOLDS,
                            "slopes": SLOPES, "lapses": LAPSES, "guess": 0.5,
                            "stop_after_trials": 80} | fields)


def run(quest: QuestPlus, subject: Psychometric, seed: int):
    observer = PsychometricObserver(subject, seed)
    state, outcomes = quest.start(), []
    while not quest.finished(state):
        intensity = quest.next_intensity(state)
        correct = observer.answer(state.trials + 1, intensity)
        outcomes.append((intensity, correct))
        state = quest.update(state, intensity, correct)
    return state, outcomes


def entropy(w: np.ndarray) -> float:
    w = w[w > 0]
    return float(-(w * np.log(w)).sum())


def test_the_expected_entropies_are_those_of_each_updated_posterior_computed_directly():
    quest = QuestPlus.prepare(rule())
    state = quest.replay([(INTENSITIES[20], True), (INTENSITIES[10], False), (INTENSITIES[15], True)])
    direct = []
    for i in range(len(INTENSITIES)):
        p = quest.probability[i]
        expected = 0.0
        for likelihood in (p, 1.0 - p):
            joint = state.posterior * likelihood
            expected += joint.sum() * entropy(joint / joint.sum())
        direct.append(expected)
    # Sums of ~500 terms of order log(480) nats: rounding stays far below 1e-10.
    np.testing.assert_allclose(quest.expected_entropies(state), direct, rtol=0, atol=1e-10)
    assert quest.next_index(state) == int(np.argmin(direct))


def test_quest_plus_recovers_the_threshold_within_its_credible_interval_most_of_the_time():
    quest = QuestPlus.prepare(rule())
    subject = Psychometric("weibull", threshold=6.0, slope=3.0, guess=0.5, lapse=0.02)
    covered = 0
    for seed in range(20):
        summary = quest.summary(run(quest, subject, seed)[0])
        covered += summary.threshold_ci_low <= 6.0 <= summary.threshold_ci_high
    # A 95 % interval misses 1 in 20 on average; 16 of 20 or more is all but certain (p > 0.99).
    assert covered >= 16


def test_doubling_the_true_threshold_roughly_doubles_the_estimate():
    quest = QuestPlus.prepare(rule())
    means = []
    for threshold in (4.0, 8.0):
        subject = Psychometric("weibull", threshold=threshold, slope=3.0, guess=0.5, lapse=0.02)
        means.append(np.mean([quest.summary(run(quest, subject, seed)[0]).threshold_mean
                              for seed in range(12)]))
    assert 1.7 <= means[1] / means[0] <= 2.3, means


def test_replay_gives_the_identical_state_and_next_intensity():
    quest = QuestPlus.prepare(rule())
    subject = Psychometric("weibull", threshold=6.0, slope=3.0, guess=0.5, lapse=0.02)
    state, outcomes = run(quest, subject, seed=7)
    for cut in (0, 1, 17, len(outcomes) - 1):
        original = quest.replay(outcomes[:cut])
        again = QuestPlus.prepare(rule()).replay(outcomes[:cut])
        assert again.trials == original.trials == cut
        assert np.array_equal(again.posterior, original.posterior)
        assert quest.next_index(again) == quest.next_index(original)
    assert np.array_equal(quest.replay(outcomes).posterior, state.posterior)


def test_the_next_intensity_is_deterministic_and_ties_go_to_the_lowest():
    quest = QuestPlus.prepare(rule())
    state = quest.replay([(INTENSITIES[12], False), (INTENSITIES[18], True)])
    assert len({quest.next_index(state) for _ in range(5)}) == 1
    # Far above every threshold each triple gives 1 - lapse: every intensity teaches alike.
    saturated = QuestPlus.prepare(rule(intensities=(1000.0, 2000.0, 3000.0), thresholds=(1.0, 2.0)))
    assert np.ptp(saturated.expected_entropies(saturated.start())) == 0.0
    assert saturated.next_index(saturated.start()) == 0


def exact_expected_entropy(quest: QuestPlus, posterior: np.ndarray, index: int) -> Decimal:
    """The expected posterior entropy after a trial at ``index``, from the same float64 table
    and posterior (exact binary values) in 40-digit decimal arithmetic."""
    with localcontext() as context:
        context.prec = 40
        w = [Decimal(float(v)) for v in posterior]
        p = [Decimal(float(v)) for v in quest.probability[index]]
        expected = Decimal(0)
        for likelihood in (p, [1 - v for v in p]):
            joint = [a * b for a, b in zip(w, likelihood, strict=True)]
            mass = sum(joint)
            expected -= sum(j * (j / mass).ln() for j in joint if j > 0)
        return expected


def test_a_real_difference_far_inside_the_old_tie_window_is_not_taken_for_a_tie():
    # Two strokes whose expected entropies differ by about 1e-10 nats, the higher one less:
    # a real difference (rounding here is below 1e-14) which the former fixed window of 1e-9
    # nats tied, choosing the lower stroke.
    quest = QuestPlus.prepare(rule(intensities=(1.50097644, 1.59875), thresholds=(1.0, 2.0),
                                   slopes=(3.0,), lapses=(0.0,)))
    state = quest.start()
    lower, higher = (exact_expected_entropy(quest, state.posterior, i) for i in (0, 1))
    assert Decimal("1e-12") < lower - higher < Decimal("1e-9")
    assert quest.next_index(state) == 1
    assert quest.rounding_bound(state).max() < 1e-13


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(0.0, 1.0), min_size=8, max_size=8).filter(lambda w: sum(w) > 0.1),
       st.lists(st.floats(0.3, 30.0), min_size=2, max_size=6, unique=True))
def test_the_chosen_intensity_is_never_measurably_worse_than_the_best(weights, intensities):
    quest = QuestPlus.prepare(rule(intensities=tuple(sorted(intensities)),
                                   thresholds=(1.0, 3.0, 9.0, 27.0), slopes=(1.5, 4.0),
                                   lapses=(0.02,)))
    posterior = np.asarray(weights) / np.sum(weights)
    state = quest.start().__class__(0, posterior)
    exact = [exact_expected_entropy(quest, posterior, i) for i in range(len(intensities))]
    chosen = quest.next_index(state)
    # Worse than the best by no more than what rounding can hide (the bound, twice over).
    assert exact[chosen] - min(exact) <= Decimal(2 * float(quest.rounding_bound(state).max()))
    # And ties go to the lowest: no lower intensity is as good to within rounding.
    assert all(exact[i] - min(exact) > Decimal(0) for i in range(chosen))


def test_the_posterior_stays_finite_over_500_always_correct_answers():
    quest = QuestPlus.prepare(rule(stop_after_trials=500))
    state = quest.start()
    for _ in range(500):
        state = quest.update(state, quest.next_intensity(state), True)
    assert np.all(np.isfinite(state.posterior)) and state.posterior.min() >= 0
    assert state.posterior.sum() == pytest.approx(1.0, abs=1e-12)
    summary = quest.summary(state)
    assert np.isfinite([summary.threshold_mean, summary.threshold_sd]).all()
    assert summary.threshold_ci_high <= THRESHOLDS[2]  # all correct: the lowest thresholds


def test_an_answer_impossible_under_the_whole_grid_is_an_error_naming_the_trial():
    # Detection without false alarms or lapses: nothing is felt at 0 mm.
    quest = QuestPlus.prepare(rule(intensities=(0.0, 1.0, 2.0), guess=0.0, lapses=(0.0,)))
    state = quest.update(quest.start(), 1.0, True)
    with pytest.raises(PinArrayError, match="trial 2: a correct answer at 0.0 is impossible"):
        quest.update(state, 0.0, True)


def test_quest_plus_stops_on_its_trial_limit_or_once_the_interval_is_narrow_enough():
    subject = Psychometric("weibull", threshold=6.0, slope=3.0, guess=0.5, lapse=0.02)
    by_trials = QuestPlus.prepare(rule(stop_after_trials=25))
    assert run(by_trials, subject, seed=1)[0].trials == 25
    narrow = QuestPlus.prepare(rule(stop_after_trials=400, stop_below_width=4.0))
    state, outcomes = run(narrow, subject, seed=1)
    assert state.trials < 400 and narrow.summary(state).threshold_ci_width <= 4.0
    before = narrow.replay(outcomes[:-1])
    assert narrow.summary(before).threshold_ci_width > 4.0
    with pytest.raises(PinArrayError, match="finished after 25 trials"):
        by_trials.update(run(by_trials, subject, seed=1)[0], INTENSITIES[0], True)


def test_a_stated_prior_shapes_the_starting_posterior():
    weights = normal_weights(THRESHOLDS, mean=8.0, sd=1.0)
    quest = QuestPlus.prepare(rule(threshold_prior=weights, lapse_prior=(1.0, 0.0, 0.0)))
    summary = quest.summary(quest.start())
    marginal = np.asarray(weights) / sum(weights)
    assert summary.threshold_mean == pytest.approx(float(marginal @ THRESHOLDS), rel=1e-12)
    assert 7.0 < summary.threshold_mean < 9.0
    assert summary.lapse_mean == 0.0
    assert summary.slope_mean == pytest.approx(np.mean(SLOPES), rel=1e-12)


magnitudes = st.floats(1e-100, 1e100)


@settings(max_examples=200, deadline=None)
@given(values=st.lists(magnitudes, min_size=1, max_size=8, unique=True).map(sorted),
       mean=magnitudes, sd=magnitudes)
def test_a_normal_prior_weighs_the_value_nearest_its_mean_1_and_the_rest_0_to_1_never_nan(
        values, mean, sd):
    # However far the values lie from the mean and however narrow the normal: the weights a
    # protocol may state (numbers within 1e±100) stay usable, and nothing warns on stderr.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        weights = np.asarray(normal_weights(tuple(values), mean, sd))
        QuestPlus.prepare(rule(thresholds=tuple(values), threshold_prior=tuple(weights)))
    assert np.all((weights >= 0) & (weights <= 1))
    nearest = int(np.argmin(np.abs(np.asarray(values) - mean)))
    assert weights[nearest] == 1.0


def test_the_credible_interval_is_read_from_the_threshold_marginal():
    # All the mass on thresholds 1 and 2 (half each) of 1..5: the 2.5 % point is 1, 97.5 % is 2.
    prior = (1.0, 1.0, 0.0, 0.0, 0.0)
    quest = QuestPlus.prepare(rule(thresholds=(1.0, 2.0, 3.0, 4.0, 5.0), threshold_prior=prior))
    summary = quest.summary(quest.start())
    assert (summary.threshold_ci_low, summary.threshold_ci_high) == (1.0, 2.0)
    assert summary.threshold_mean == pytest.approx(1.5, rel=1e-15)
    assert summary.threshold_sd == pytest.approx(0.5, rel=1e-12)


def test_an_intensity_outside_the_domain_is_refused():
    quest = QuestPlus.prepare(rule())
    with pytest.raises(PinArrayError, match="can present only its intensities .* found 3.3"):
        quest.update(quest.start(), 3.3, True)


@pytest.mark.parametrize(("fields", "message"), [
    ({"stop_after_trials": None, "stop_below_width": 1.0}, "needs a trial limit"),
    ({"stop_after_trials": 0}, "whole number of 1 or more, found 0"),
    ({"thresholds": (2.0, 1.0)}, "thresholds must be one finite value or more, strictly ascending"),
    ({"thresholds": (0.0, 1.0)}, "Weibull thresholds must be above 0, found 0.0"),
    ({"slopes": (0.0, 1.0)}, "slopes must be above 0, found 0.0"),
    ({"guess": 0.5, "lapses": (0.0, 0.5)}, "guess \\+ lapse below 1, found guess 0.5"),
    ({"stop_below_width": -1.0}, "stop_below_width must be above 0, found -1.0"),
    ({"slope_prior": (1.0, 1.0)}, "slope prior needs one weight per slope \\(4\\), found 2"),
    ({"lapse_prior": (0.0, 0.0, 0.0)}, "lapse prior's weights must be 0 or more and not all 0"),
    ({"kind": "gumbel"}, "weibull or logistic, found 'gumbel'"),
])
def test_a_bad_quest_plus_rule_is_refused_saying_what_was_found(fields, message):
    with pytest.raises(PinArrayError, match=message):
        rule(**fields)


def test_a_logistic_quest_plus_recovers_an_soa_threshold():
    # Apparent motion's direction: SOA in ms, logistic in ms, 2AFC.
    soas = tuple(float(v) for v in range(10, 210, 10))
    quest = QuestPlus.prepare(rule(kind="logistic", intensities=soas,
                                   thresholds=tuple(float(v) for v in range(20, 201, 5)),
                                   slopes=(0.02, 0.05, 0.1, 0.2), stop_after_trials=120))
    subject = Psychometric("logistic", threshold=90.0, slope=0.08, guess=0.5, lapse=0.02)
    means = [quest.summary(run(quest, subject, seed)[0]).threshold_mean for seed in range(20)]
    # Unbiased to within four standard errors of the mean of 20 subjects.
    assert abs(np.mean(means) - 90.0) <= 4 * np.std(means, ddof=1) / np.sqrt(len(means)), means
