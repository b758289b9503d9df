"""The dry run of a protocol before anything moves: steps, lab duration, travel, limit checks.

Each step kind's ``plan()`` summed up as data: ``gelrig plan`` prints it, the GUI's protocol
panel shows it and uses it for the ETA and for enabling Run.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from gelrig.instrument.core.units import lab_time
from gelrig.protocols.bounds import Beyond, run_bound_error
from gelrig.protocols.rig import CompressionLimits, ShearLimits
from gelrig.protocols.spec import ProtocolSpec, effective_params


@dataclass
class PlanSummary:
    """Per-step lab durations (s), total travel (m), the printable lines, failed checks."""

    durations: list[float]
    travel: float
    lines: list[str]
    failed: list[str] = field(default_factory=list)
    #: samples (rows) the run records at most
    samples: float = 0.0
    #: the bound of protocols/bounds.py the protocol exceeds, if any
    beyond: Beyond | None = None

    @property
    def total(self) -> float:
        return sum(self.durations)

    def text(self) -> str:
        return "\n".join(self.lines)


def dry_run(protocol: ProtocolSpec, limits: CompressionLimits | ShearLimits) -> PlanSummary:
    """Plan every step against the rig's limits."""
    durations: list[float] = []
    travel = 0.0
    lines = [f"{protocol.name}  ({protocol.rig} rig)"]
    failed: list[str] = []
    plans = []
    for i, step in enumerate(protocol.steps):
        plan = step.definition.plan(step.params, limits)
        plans.append((f"step {i} ({step.name})", plan))
        durations.append(plan.duration)
        travel += plan.travel
        lines.append(f"{i}. {step.name} [{step.kind}]: ~{lab_time(plan.duration)} lab time, "
                     f"travel up to {plan.travel * 1e3:.1f} mm")
        lines.extend(f"   - {line}" for line in plan.lines)
        lines.append(f"   - uses {', '.join(effective_params(step))}")
        for check in plan.checks:
            lines.append(f"   {'ok  ' if check.ok else 'FAIL'} {check.name}: {check.message}")
            if not check.ok:
                failed.append(f"step {i} ({step.name}): {check.message}")
    verdict = "all passed" if not failed else f"{len(failed)} FAILED"
    lines.append(f"Total: ~{lab_time(sum(durations))} lab time, travel up to "
                 f"{travel * 1e3:.1f} mm; limit checks {verdict}")
    return PlanSummary(durations, travel, lines, failed, sum(p.samples for _, p in plans),
                       run_bound_error(plans))
