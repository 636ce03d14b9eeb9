"""What the tests could have seen (bayes_update.core.detectability), checked by the
workflow itself: for each candidate effect of a user's model (the Duffing of
tests/test_user_discrepancy.py: a quadratic spring k2 and a quadratic damper c2),
the detectability limit computed on records without any effect is checked by
running the whole discrepancy workflow on records holding the effect at twice the
limit (named) and at half of it (not named)."""
import pytest

from bayes_update.core.discrepancy import DiscrepancySettings, find_discrepancy
from test_user_discrepancy import Duffing, make_dataset


def _run(hidden=None, detectability=False):
    return find_discrepancy(make_dataset(hidden), Duffing(),
                            settings=DiscrepancySettings.quick(detectability=detectability), workers=2,
                            log=lambda *a: None)


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
