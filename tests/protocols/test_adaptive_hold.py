"""The live fit and the adaptive hold of ``ramp_hold``, on fakes of the compression rig
(tests/doubles.py) with the paper's materials and force noise (0.2 mN, the rig file's)."""

from __future__ import annotations

import pytest

from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.physics import paper
from gelrig.protocols.events import Event, EventBus, FitUpdate, RunState
from gelrig.protocols.plan import dry_run
from gelrig.protocols.rig import CompressionLimits
from gelrig.protocols.runner import Runner
from gelrig.protocols.spec import parse_protocol
from tests.doubles import compression_rig

NOISE = 0.2e-3  # N, the rig file's force noise


def protocol(**hold: object) -> object:
    step = {"kind": "ramp_hold", "diameter": "18.63 mm", "first_touch": "6.2 mm",
            "tare_time": "0.5 s", **hold}
    return parse_protocol({"protocol": {"name": "t", "rig": "compression"}, "step": [step]})


def run_hold(material: object, watched: bool = True, **hold: object
             ) -> tuple[dict, list[FitUpdate]]:
    rig, _, _ = compression_rig(material=material, noise=NOISE)  # type: ignore[arg-type]
    bus = EventBus()
    updates: list[FitUpdate] = []

    def keep(e: Event) -> None:
        if isinstance(e, FitUpdate):
            updates.append(e)

    bus.subscribe(keep)
    runner = Runner(rig, protocol(**hold), bus, watched=watched)
    assert runner.run() is RunState.COMPLETED, runner.reason
    return runner.results[0], updates


def test_fixed_hold_publishes_a_live_fit_that_ends_near_the_offline_fit() -> None:
    result, updates = run_hold(paper.PLATES, hold="1000 s", terms=1)
    assert result["hold_end"] == "planned"
    assert result["held_s"] == pytest.approx(1000.0, abs=0.1)
    assert len(updates) >= 10
    assert [u.state.elapsed for u in updates] == sorted(u.state.elapsed for u in updates)
    assert len(result["live_fits"]) == len(updates)
    last, offline = updates[-1].state, result["fits"][0]
    # same data, nominal vs refitted first touch: the time constant agrees within its error
    tau, err = offline["relax"][0]["tau"], offline["stderr"]["tau_1"]
    assert abs(last.tau - tau) < 2 * err
    assert last.stderr["tau_1"] == pytest.approx(err, rel=0.2)
    assert not any(u.met for u in updates)  # no target: never met


def test_plate_adaptive_hold_ends_before_3000_s_within_2_percent() -> None:
    result, updates = run_hold(paper.PLATES, hold="3000 s", terms=1, until=0.02)
    assert result["hold_end"] == "target"
    assert result["held_s"] < 3000.0
    final = updates[-1]
    assert final.ending and final.met and updates[-2].met
    assert final.state.tau_relative <= 0.02
    assert final.state.tau == pytest.approx(1413.0, rel=0.02)


def test_an_unwatched_run_skips_what_only_informs_but_keeps_what_steers() -> None:
    """A rehearsal (``watched=False``): a fixed hold makes no live refits and no fits (they
    inform, they do not change the run's course), an adaptive hold still refits and ends
    where a watched run ends (docs/decisions/0090)."""
    fixed, none = run_hold(paper.PLATES, watched=False, hold="1000 s", terms=1)
    assert none == [] and fixed["fits"] == [] and fixed["hold_end"] == "planned"
    assert fixed["held_s"] == pytest.approx(1000.0, abs=0.1)
    seen, _ = run_hold(paper.PLATES, hold="3000 s", terms=1, until=0.02)
    rehearsed, updates = run_hold(paper.PLATES, watched=False, hold="3000 s", terms=1,
                                  until=0.02)
    assert updates and rehearsed["hold_end"] == "target"
    assert rehearsed["held_s"] == seen["held_s"]


def test_shell_adaptive_hold_waits_for_the_second_term_when_asked() -> None:
    one, _ = run_hold(paper.SHELL, hold="3000 s", terms=2, until=0.02)
    two, updates = run_hold(paper.SHELL, hold="3000 s", terms=2, until=0.02, until_terms=2)
    assert two["hold_end"] == "target"
    assert two["held_s"] > one["held_s"]
    final = updates[-1].state
    assert final.terms_resolved == 2
    assert [r.tau for r in final.relax] == pytest.approx([1898.0, 172.0], rel=0.05)
    # it did not stop while only one term was resolved, though the one-term tau was "pinned"
    assert all(u.state.terms_resolved == 2 for u in updates if u.met)


def test_plan_states_the_range_of_durations() -> None:
    plan = dry_run(protocol(hold="3000 s", until=0.02, min_hold="600 s"),  # type: ignore[arg-type]
                   CompressionLimits())
    text = plan.text()
    assert "adaptive hold: 600 s to 3000 s" in text


@pytest.mark.parametrize(("hold", "field"), [
    ({"hold": "100 s", "min_hold": "200 s", "until": 0.02}, "min_hold"),
    ({"terms": 1, "until_terms": 2, "until": 0.02}, "until_terms"),
    ({"until": 0.0}, "until"),
    ({"until": 2}, "until"),
])
def test_bad_adaptive_values_are_one_line_naming_the_field(hold: dict, field: str) -> None:
    with pytest.raises(ConfigError) as err:
        protocol(**hold)
    message = str(err.value)
    assert field in message and "\n" not in message
