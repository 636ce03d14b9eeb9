"""What the tests could have seen (bayes_update.core.detectability), checked by the
workflow itself: for each candidate effect of a user's model (the Duffing of
tests/test_user_discrepancy.py: a quadratic spring k2 and a quadratic damper c2),
the detectability limit computed on records without any effect is checked by
running the whole discrepancy workflow on records holding the effect at twice the
limit (named) and at half of it (not named)."""

import pytest
from test_user_discrepancy import Duffing, make_dataset

from bayes_update.core.discrepancy import DiscrepancySettings, find_discrepancy


def _run(hidden=None, detectability=False):
    return find_discrepancy(
        make_dataset(hidden),
        Duffing(),
        settings=DiscrepancySettings.quick(detectability=detectability),
        workers=2,
        log=lambda *a: None,
    )


@pytest.fixture(scope="module")
def limits():
    res = _run(detectability=True)
    assert res.named == []
    doc = res.to_json()
    assert set(doc["detectable_from"]) == {"k2", "c2"}
    return {e: d["detectable_from"][e] for e, d in res.detectability.items()}


@pytest.mark.parametrize("effect", ["k2", "c2"])
def test_the_limit_holds_for_the_whole_workflow(limits, effect):
    limit = limits[effect]
    above, below = _run({effect: 2.0 * limit}), _run({effect: 0.5 * limit})
    assert above.named == [effect], (effect, limit, above.rounds[0]["candidates"])
    assert below.named == [], (effect, limit, below.rounds[0]["candidates"])


def test_a_limit_below_the_ladder_is_said_to_be_an_upper_bound():
    """Where the ladder's lowest rung is already named, the limit is only an upper
    bound and must read so; an interior limit is interpolated between the rungs
    around it (in log magnitude, where the smaller margin crosses zero)."""
    from types import SimpleNamespace

    from bayes_update.core.detectability import _limit, limit_text

    p = [SimpleNamespace(name="c2")]
    named_everywhere = [(1e-3, 50.0, 9.0), (1e-2, 400.0, 30.0)]
    rec = _limit(named_everywhere, p, [0.0], [2.0])
    assert rec["below_ladder"] and rec["detectable_from"] == {"c2": 2e-3}
    assert limit_text(rec).startswith("at most c2 = 0.002")
    # 2 ln B = 6 * e^-1 at 1e-3 and 6 * e at 1e-2: the margin crosses zero half way (in log m)
    inside = [(1e-3, 6.0 / 2.718281828, 50.0), (1e-2, 6.0 * 2.718281828, 50.0)]
    rec = _limit(inside, p, [0.0], [2.0])
    assert not rec["below_ladder"] and abs(rec["magnitude"] - 10**-2.5) < 1e-9
    assert limit_text(rec) == f"c2 = {2 * 10**-2.5:.3g}"
    assert limit_text(_limit([(1.0, 2.0, 0.1)], p, [0.0], [2.0])) == "not even at its prior's bound"
