"""Scripts as protocols (protocols/script.py) on fakes of the instrument contracts: steps in the
script's order through the one Runner, replay on resume, a script's errors, refusals and trips.
"""

from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass
from typing import Any, ClassVar

import pytest

from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.fields import Field, param
from gelrig.protocols.context import StepContext
from gelrig.protocols.events import Event, EventBus, Finished, SafeStopped, StepStarted
from gelrig.protocols.rig import CompressionLimits, CompressionRig
from gelrig.protocols.runner import Runner
from gelrig.protocols.script import Run, Script, load_script, protocol
from gelrig.protocols.spec import parse_protocol
from gelrig.protocols.steps import BUILT_IN, KINDS, register
from gelrig.protocols.steps.base import StepDefinition, StepParams, StepPlan, StepResult
from gelrig.protocols.steps.compression_search import SearchResult
from gelrig.protocols.steps.ramp_hold import RampHoldResult
from tests.doubles import compression_rig

SEARCH = {"start": "3 mm", "confirm": 1, "tare_time": "0.5 s"}
HOLD = {"diameter": "18.63 mm", "hold": "20 s", "terms": 1, "strain_rate": "0.02 /s",
        "rate": "100 Hz"}


def events(bus: EventBus) -> list[Event]:
    seen: list[Event] = []
    bus.subscribe(seen.append)
    return seen


@protocol(rig="compression", name="two holds")
def two_holds(run: Run) -> None:
    """A contact search, then holds at two strains."""
    found = run.step("compression_contact_search", name="find", **SEARCH)
    assert isinstance(found, SearchResult)
    for strain in (0.02, 0.04):
        held = run.step("ramp_hold", name=f"hold {strain:.0%}", strain=strain, **HOLD)
        assert isinstance(held, RampHoldResult)
        run.log(f"held {held.depth_m * 1e3:.3f} mm")


def test_a_script_runs_its_steps_in_order_with_typed_results() -> None:
    rig, _stage, _ = compression_rig()
    bus = EventBus()
    seen = events(bus)
    runner = Runner(rig, two_holds, bus)
    assert runner.run().value == "completed", runner.reason
    started = [e for e in seen if isinstance(e, StepStarted)]
    assert [(e.index, e.name, e.kind) for e in started] == [
        (0, "find", "compression_contact_search"), (1, "hold 2%", "ramp_hold"),
        (2, "hold 4%", "ramp_hold")]
    assert started[2].params["strain"] == pytest.approx(0.04)
    assert runner.results[2]["depth_m"] == pytest.approx(0.04 * 18.63e-3)
    assert two_holds.table["protocol"]["script"].endswith("test_script.py")
    assert two_holds.description == "A contact search, then holds at two strains."


def test_a_resumed_script_replays_completed_steps_without_running_them() -> None:
    rig, _stage, _ = compression_rig()
    first = Runner(rig, two_holds)
    assert first.run().value == "completed"
    rig2, _stage2, _ = compression_rig()
    done = {0: first.results[0], 1: first.results[1]}
    runner = Runner(rig2, two_holds, completed=done)
    runner.recorded = {0: ("find", "compression_contact_search"), 1: ("hold 2%", "ramp_hold")}
    bus_seen = events(runner.bus)
    assert runner.run().value == "completed", runner.reason
    started = [e.index for e in bus_seen if isinstance(e, StepStarted)]
    assert started == [2]  # only the step not done before ran
    assert runner.results[2]["first_touch_m"] == pytest.approx(first.results[0]["first_touch_m"])


def test_a_resumed_script_that_asks_for_other_steps_is_refused_before_moving() -> None:
    rig, _stage, _ = compression_rig()
    first = Runner(rig, two_holds)
    assert first.run().value == "completed"
    rig2, stage2, _ = compression_rig()
    runner = Runner(rig2, two_holds, completed={0: first.results[0]})
    runner.recorded = {0: ("another search", "compression_contact_search")}
    assert runner.run().value == "failed"
    assert "step 0: the run recorded 'another search'" in runner.reason
    assert not any(c.startswith("move") for c in stage2.calls)


def test_a_script_cannot_swallow_the_end_of_a_run_and_go_on_moving() -> None:
    @protocol(rig="compression")
    def stubborn(run: Run) -> None:
        run.step("compression_contact_search", **SEARCH)
        with contextlib.suppress(Exception):  # a trip is not an Exception: not caught
            run.step("ramp_hold", **HOLD)
        run.step("ramp_hold", name="again", **HOLD)

    rig, stage, _ = compression_rig(limits=CompressionLimits(max_force=0.05))
    bus = EventBus()
    seen = events(bus)
    runner = Runner(rig, stubborn, bus)
    assert runner.run().value == "aborted"
    assert runner.reason.startswith("interlock force")
    assert [e.name for e in seen if isinstance(e, StepStarted)] == ["contact search",
                                                                     "ramp and hold"]
    assert not stage.is_moving()


def test_a_script_that_raises_between_steps_ends_failed_after_a_safe_stop() -> None:
    @protocol(rig="compression")
    def broken(run: Run) -> None:
        run.step("compression_contact_search", **SEARCH)
        raise ValueError("no such strain")

    rig, _stage, _ = compression_rig()
    bus = EventBus()
    seen = events(bus)
    runner = Runner(rig, broken, bus)
    assert runner.run().value == "failed"
    assert runner.reason.startswith("ValueError: no such strain (at test_script.py:")
    assert any(isinstance(e, SafeStopped) for e in seen)
    assert isinstance(seen[-1], Finished)
    assert runner.results[0]["first_touch_m"] > 0  # the completed step's result stands


def test_a_bad_parameter_names_the_script_the_step_and_the_field() -> None:
    @protocol(rig="compression")
    def typo(run: Run) -> None:
        run.step("compression_contact_search", **SEARCH)
        run.step("ramp_hold", diameter="18.63 mm", strain="50 %")

    rig, _stage, _ = compression_rig()
    runner = Runner(rig, typo)
    assert runner.run().value == "refused"  # a bad value is refused before it moves
    assert runner.reason.startswith('step 1 (ramp and hold): strain = "50 %": allowed ')
    assert "(at test_script.py:" in runner.reason
    assert "refused before it moved (the data of the 1 step before it are kept)" in \
        runner.reason


def test_a_script_step_beyond_a_cap_is_refused_before_it_moves() -> None:
    @protocol(rig="compression")
    def too_deep(run: Run) -> None:
        run.step("compression_contact_search", **SEARCH)
        run.step("ramp_hold", strain=0.2, **HOLD)  # 3.7 mm, beyond max_overlap 2.5 mm

    rig, stage, _ = compression_rig()
    runner = Runner(rig, too_deep)
    calls = len(stage.calls)
    assert runner.run().value == "refused"
    assert "step 1 (ramp and hold): depth 3.7260 mm beyond the overlap limit" in runner.reason
    assert "refused before it moved" in runner.reason
    assert len(stage.calls) > calls  # the search ran, and the safe stop retracted


def test_the_watchdog_does_not_count_a_script_thinking_between_steps() -> None:
    @protocol(rig="compression")
    def slow_thinker(run: Run) -> None:
        run.step("compression_contact_search", **SEARCH)
        time.sleep(3.0)  # wall time between steps: the script computing what to do next
        run.step("ramp_hold", **HOLD)

    rig, _stage, _ = compression_rig(limits=CompressionLimits(watchdog=1.5))
    runner = Runner(rig, slow_thinker)
    assert runner.run().value == "completed", runner.reason


# -- step kinds a user registers ----------------------------------------------------------

@dataclass(frozen=True)
class WaitParams(StepParams):
    duration: float = param(Field("duration", "s", 1.0, 0.0, 3600.0))


@dataclass(frozen=True)
class WaitResult(StepResult):
    waited_s: float


class Wait(StepDefinition[CompressionRig, WaitParams, WaitResult]):
    kind: ClassVar[str] = "test_wait"
    rig = CompressionRig
    Params, Result = WaitParams, WaitResult
    columns: ClassVar[dict[str, str]] = {}

    def plan(self, params: WaitParams, limits: Any) -> StepPlan:
        return StepPlan(params.duration, 0.0, [f"wait {params.duration:g} s"])

    def run(self, ctx: StepContext[CompressionRig], params: WaitParams) -> WaitResult:
        start = ctx.clock.now()
        ctx.clock.sleep(params.duration)
        return WaitResult(ctx.clock.now() - start)


def test_a_registered_kind_runs_from_a_script_and_a_protocol_file(tmp_path) -> None:
    register(Wait)
    try:
        register(Wait)  # the same class again (a module loaded twice): allowed

        class Other(Wait):
            pass

        with pytest.raises(ConfigError, match="already registered"):
            register(Other)

        @protocol(rig="compression")
        def waits(run: Run) -> None:
            assert run.step("test_wait", duration="2 min").waited_s == pytest.approx(120.0)
            assert run.step(Wait, name="class").waited_s == pytest.approx(1.0)

        rig, _, _ = compression_rig()
        assert Runner(rig, waits).run().value == "completed"
        spec = parse_protocol({"protocol": {"name": "t", "rig": "compression"},
                               "step": [{"kind": "test_wait", "duration": "3 s"}]})
        assert spec.steps[0].params.duration == 3.0
    finally:
        KINDS.pop("test_wait", None)


def test_a_built_in_kind_cannot_be_replaced() -> None:
    class Fake(Wait):
        kind: ClassVar[str] = "ramp_hold"

    with pytest.raises(ConfigError, match="built-in step kind"):
        register(Fake)
    assert "ramp_hold" in BUILT_IN and type(KINDS["ramp_hold"]).__name__ == "RampHold"


MODULE = '''
from dataclasses import dataclass
from typing import ClassVar
import gelrig


@dataclass(frozen=True)
class NapParams(gelrig.StepParams):
    nap: float = gelrig.param(gelrig.Field("nap", "s", 1.0, 0.0, 60.0))


@dataclass(frozen=True)
class NapResult(gelrig.StepResult):
    slept_s: float


@gelrig.register_step
class Nap(gelrig.StepDefinition):
    kind: ClassVar[str] = "nap_TAG"
    rig = gelrig.CompressionRig
    Params, Result = NapParams, NapResult

    def plan(self, params, limits):
        return gelrig.StepPlan(params.nap, 0.0)

    def run(self, ctx, params):
        ctx.clock.sleep(params.nap)
        return NapResult(params.nap)
'''


def test_a_protocol_file_loads_step_kinds_from_a_module_next_to_it(tmp_path) -> None:
    (tmp_path / "nap_steps.py").write_text(MODULE.replace("TAG", "a"))
    file = tmp_path / "naps.toml"
    file.write_text('[protocol]\nname = "naps"\nrig = "compression"\n'
                    'step_kinds = ["nap_steps.py"]\n\n[[step]]\nkind = "nap_a"\nnap = "5 s"\n')
    try:
        from gelrig.protocols.spec import load_protocol

        spec = load_protocol(file)
        assert spec.steps[0].kind == "nap_a" and spec.steps[0].params.nap == 5.0
        rig, _, _ = compression_rig()
        runner = Runner(rig, spec)
        assert runner.run().value == "completed"
        assert runner.results[0] == {"slept_s": 5.0}
    finally:
        KINDS.pop("nap_a", None)


def test_a_missing_step_kind_module_is_one_line(tmp_path) -> None:
    file = tmp_path / "p.toml"
    file.write_text('[protocol]\nname = "p"\nrig = "compression"\nstep_kinds = ["gone.py"]\n'
                    '[[step]]\nkind = "x"\n')
    from gelrig.protocols.spec import load_protocol

    with pytest.raises(ConfigError, match=r"\[protocol\] step_kinds\[0\].*no such Python file"):
        load_protocol(file)


def test_load_script_finds_the_one_protocol_and_names_what_is_wrong(tmp_path) -> None:
    good = tmp_path / "one.py"
    good.write_text("import gelrig\n\n@gelrig.protocol(rig='shear', name='x')\n"
                    "def body(run):\n    pass\n")
    assert isinstance(load_script(good), Script) and load_script(good).rig == "shear"
    none = tmp_path / "none.py"
    none.write_text("x = 1\n")
    with pytest.raises(ConfigError, match="defines none protocols"):
        load_script(none)
    broken = tmp_path / "broken.py"
    broken.write_text("import gelrig\n\nx = 1 / 0\n")
    with pytest.raises(ConfigError, match=r"broken\.py:3.*ZeroDivisionError"):
        load_script(broken)
    bad = tmp_path / "bad.py"
    bad.write_text("def (:\n")
    with pytest.raises(ConfigError, match="not valid Python"):
        load_script(bad)
    with pytest.raises(ConfigError, match="allowed: compression, shear"):
        protocol(rig="tensile")


def test_a_step_name_with_a_unit_names_a_safe_data_file(tmp_path) -> None:
    from gelrig.instrument.core.fields import Where
    from gelrig.instrument.core.store import RunDirectory
    from gelrig.protocols.spec import make_step

    step = make_step("ramp_hold", "cycle at 1 um/s ../x", {"diameter": "12 mm"}, "compression",
                     Where("step[0]"))
    path = RunDirectory(tmp_path).step_path(3, step.name)
    assert path.parent == tmp_path / "steps" and path.name == "03_cycle_at_1_um_s_.._x.h5"


def test_script_parameters_are_checked_kept_and_given_back_on_resume(tmp_path) -> None:
    from gelrig.protocols.script import script_from_table

    file = tmp_path / "series.py"
    file.write_text("import gelrig\n\n@gelrig.protocol(rig='compression', name='s')\n"
                    "def series(run, strains=(0.02,), hold='60 s'):\n"
                    "    for strain in strains:\n"
                    "        run.step('ramp_hold', strain=strain, hold=hold, first_touch='6.2 mm',"
                    " diameter='18.63 mm', strain_rate='0.02 /s', rate='100 Hz', terms=1)\n")
    script = load_script(file)
    assert script.parameters() == {"strains": (0.02,), "hold": "60 s"}
    with pytest.raises(ConfigError, match=r"series\.py takes strains, hold"):
        script.with_params(strain=0.1)
    given = script.with_params(strains=[0.01, 0.03], hold="20 s")
    assert given.table["protocol"]["params"] == {"strains": [0.01, 0.03], "hold": "20 s"}
    rig, _, _ = compression_rig()
    bus = EventBus()
    seen = events(bus)
    assert Runner(rig, given, bus).run().value == "completed"
    assert [e.params["strain"] for e in seen if isinstance(e, StepStarted)] == [0.01, 0.03]
    again, _ = script_from_table(given.table, str(file), tmp_path)
    assert again.params == {"strains": [0.01, 0.03], "hold": "20 s"}
