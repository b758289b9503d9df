"""The campaign's HTML report: how well the protocol recovers the hidden truth.

From the results table (one row per member): the bias and spread of each fitted parameter
against the truth, the coverage of the reported 95 % intervals, the error of tau against the
hold length and of G_1 against the speeds used, l_c/l_g against speed per truth variant, and a
table comparing the variants. Written with the project's report layer
(:func:`gelrig.instrument.reports.document.write_report`); figures with matplotlib (Agg).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gelrig.campaign.member import FITTED
from gelrig.instrument.reports.document import Column, Section, Table, write_report

Row = Mapping[str, Any]
#: Two-sided 95 % normal quantile, for the binomial band of a coverage.
Z95 = 1.959963984540054


@dataclass(frozen=True)
class Coverage:
    """How often the reported 95 % interval held the truth: ``hits`` of ``n`` resolved
    members; ``unresolved`` more had a truth but no resolved estimate (left out)."""

    hits: int
    n: int
    unresolved: int = 0

    @property
    def fraction(self) -> float:
        return self.hits / self.n if self.n else math.nan

    def band(self) -> tuple[float, float]:
        """Wilson 95 % interval of the fraction."""
        if not self.n:
            return math.nan, math.nan
        p, n, z = self.fraction, self.n, Z95
        centre = (p + z * z / (2 * n)) / (1 + z * z / n)
        half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
        return centre - half, centre + half


def _num(row: Row, key: str) -> float:
    value = row.get(key)
    return float(value) if isinstance(value, int | float) and value is not None else math.nan


def fitted_names(rows: Sequence[Row]) -> list[str]:
    """Fitted parameters that have a truth to compare with, in :data:`FITTED` order."""
    return [n for n in FITTED
            if any(math.isfinite(_num(r, f"fit.{n}")) and math.isfinite(_num(r, f"truth.{n}"))
                   for r in rows)]


def is_resolved(row: Row, name: str) -> bool:
    """Whether ``row`` has a resolved estimate of ``name`` (a member whose fit the data do not
    resolve, ``resolved`` false, has none; rows from before the column count as resolved)."""
    return row.get("resolved") is not False and math.isfinite(_num(row, f"fit.{name}"))


def unresolved(rows: Sequence[Row], name: str) -> int:
    """Finished rows with a truth of ``name`` but no resolved estimate of it."""
    return sum(r.get("status") == "ok" and math.isfinite(_num(r, f"truth.{name}"))
               and not is_resolved(r, name) for r in rows)


def relative_errors(rows: Sequence[Row], name: str) -> np.ndarray:
    """(fit - truth) / truth of ``name`` over the rows that have both, resolved only."""
    out = [(_num(r, f"fit.{name}") - _num(r, f"truth.{name}")) / _num(r, f"truth.{name}")
           for r in rows if is_resolved(r, name)]
    arr = np.asarray(out, dtype=float)
    return arr[np.isfinite(arr)]


def z_scores(rows: Sequence[Row], name: str) -> np.ndarray:
    """(fit - truth) / reported s.e. of ``name``: spread 1 when the s.e. is honest."""
    out = [(_num(r, f"fit.{name}") - _num(r, f"truth.{name}")) / _num(r, f"se.{name}")
           for r in rows if is_resolved(r, name)]
    arr = np.asarray(out, dtype=float)
    return arr[np.isfinite(arr)]


def coverage(rows: Sequence[Row], name: str) -> Coverage:
    """How many finished, resolved rows' [lo, hi] of ``name`` hold its truth."""
    hits = n = 0
    for r in rows:
        lo, hi, truth = _num(r, f"lo.{name}"), _num(r, f"hi.{name}"), _num(r, f"truth.{name}")
        if r.get("status") == "ok" and math.isfinite(truth) and is_resolved(r, name):
            n += 1
            hits += bool(math.isfinite(lo) and math.isfinite(hi) and lo <= truth <= hi)
    return Coverage(hits, n, unresolved(rows, name))


def variants(rows: Sequence[Row]) -> dict[str, list[Row]]:
    """Rows grouped by protocol variant and truth (not the seed), in first-seen order."""
    groups: dict[str, list[Row]] = {}
    for r in sorted(rows, key=lambda r: int(r.get("index") or 0)):
        groups.setdefault(_label(r), []).append(r)
    return groups


def _label(row: Row) -> str:
    parts = []
    for key in ("variant", "truth_variant"):
        try:
            value = json.loads(str(row.get(key) or "{}"))
        except ValueError:
            value = {}
        parts += [f"{k.split('.')[-1]}={_short(v)}" for k, v in sorted(value.items())]
    return ", ".join(parts) or "all members"


def _short(value: object) -> str:
    if isinstance(value, list):
        return "[" + ",".join(_short(v) for v in value) + "]"
    return str(value)


def variant_rows(rows: Sequence[Row]) -> tuple[list[dict[str, object]], list[str]]:
    """One table row per variant: members, failed, and per fitted parameter its bias, sd
    (relative) and coverage; with the parameter names."""
    names = fitted_names(rows)
    out = []
    for i, (label, group) in enumerate(variants(rows).items()):
        ok = [r for r in group if r.get("status") == "ok"]
        walls = [_num(r, "wall_s") for r in group if math.isfinite(_num(r, "wall_s"))]
        row: dict[str, object] = {
            "variant": f"V{i}", "what": label, "members": len(group), "ok": len(ok),
            "failed": sum(r.get("status") == "failed" for r in group),
            "not_resolved": sum(r.get("resolved") is False for r in ok),
            "wall_median_s": float(np.median(walls)) if walls else math.nan}
        for name in names:
            err = relative_errors(ok, name)
            row[f"bias.{name}"] = float(np.mean(err)) if err.size else math.nan
            row[f"sd.{name}"] = float(np.std(err, ddof=1)) if err.size > 1 else math.nan
            row[f"cov.{name}"] = coverage(ok, name).fraction
        out.append(row)
    return out, names


def summary_lines(rows: Sequence[Row]) -> list[str]:
    """Per fitted parameter over all finished members: bias, sd and the 95 % coverage."""
    ok = [r for r in rows if r.get("status") == "ok"]
    failed = [r for r in rows if r.get("status") == "failed"]
    left_out = sum(r.get("resolved") is False for r in ok)
    lines = [f"{len(rows)} member(s): {len(ok)} ok, "
             f"{sum(r.get('status') == 'incomplete' for r in rows)} incomplete, "
             f"{len(failed)} failed"
             + (f", {left_out} ok but not resolved (left out of bias and coverage)"
                if left_out else "")]
    for name in fitted_names(ok):
        err, cov = relative_errors(ok, name), coverage(ok, name)
        if not err.size:
            lines.append(f"  {name:12s} no resolved member ({cov.unresolved} not resolved)")
            continue
        lo, hi = cov.band()
        sd = float(np.std(err, ddof=1)) if err.size > 1 else math.nan
        z = z_scores(ok, name)
        z_sd = float(np.std(z, ddof=1)) if z.size > 1 else math.nan
        lines.append(f"  {name:12s} bias {np.mean(err) * 100:+.3f} %, sd {sd * 100:.3f} %, "
                     f"95 % interval holds the truth in {cov.hits}/{cov.n} = "
                     f"{cov.fraction * 100:.0f} % (binomial 95 %: {lo * 100:.0f}-{hi * 100:.0f} %)"
                     f"; error / s.e. has sd {z_sd:.2f}"
                     + (f"; {cov.unresolved} member(s) not resolved, left out"
                        if cov.unresolved else ""))
    for r in failed[:3]:
        lines.append(f"  failed {r.get('member_id')} (seed {r.get('seed')}): {r.get('error')}")
        if r.get("safe_stop"):
            lines.append(f"    safe stop {r['safe_stop']}: {r.get('safe_stop_line', '')}")
    unsafe = [r for r in rows if r.get("safe_stop") == "not confirmed"]
    if unsafe:
        lines.append(f"  {len(unsafe)} member(s) whose safe stop was not confirmed, e.g. "
                     f"{unsafe[0].get('member_id')}: {unsafe[0].get('safe_stop_line')}")
    return lines


# -- figures -----------------------------------------------------------------------------------

def _figure(path: Path, draw: Any, size: tuple[float, float] = (9.0, 4.0)) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=size)
    try:
        draw(fig)
        fig.tight_layout()
        fig.savefig(path, dpi=100)
    finally:
        plt.close(fig)
    return path.name


def _bias_figure(out: Path, groups: dict[str, list[Row]], names: list[str]) -> str:
    def draw(fig: Any) -> None:
        for k, name in enumerate(names):
            ax = fig.add_subplot(1, len(names), k + 1)
            data = [relative_errors([r for r in g if r.get("status") == "ok"], name) * 100
                    for g in groups.values()]
            ax.boxplot([d if d.size else np.array([np.nan]) for d in data])
            ax.set_xticks(range(1, len(data) + 1), [f"V{i}" for i in range(len(data))])
            ax.axhline(0.0, color="k", lw=0.8)
            ax.set_title(name)
            ax.set_ylabel("(fit - truth) / truth (%)" if k == 0 else "")
    return _figure(out / "bias_spread.png", draw, (max(6.0, 2.4 * len(names)), 4.0))


def _coverage_figure(out: Path, groups: dict[str, list[Row]], names: list[str]) -> str:
    def draw(fig: Any) -> None:
        ax = fig.add_subplot(1, 1, 1)
        width = 0.8 / max(1, len(groups))
        for i, group in enumerate(groups.values()):
            ok = [r for r in group if r.get("status") == "ok"]
            covs = [coverage(ok, n) for n in names]
            x = np.arange(len(names)) + (i - (len(groups) - 1) / 2) * width
            frac = np.array([c.fraction for c in covs]) * 100
            bands = np.array([c.band() for c in covs]) * 100
            ax.bar(x, frac, width, label=f"V{i}")
            below = np.clip(frac - bands[:, 0], 0.0, None)  # rounding at 0 % and 100 %
            above = np.clip(bands[:, 1] - frac, 0.0, None)
            ax.errorbar(x, frac, yerr=[below, above], fmt="none", ecolor="k", lw=0.8)
        ax.axhline(95.0, color="r", ls="--", lw=1, label="95 %")
        ax.set_xticks(range(len(names)), names)
        ax.set_ylim(0, 105)
        ax.set_ylabel("truth inside the reported 95 % interval (%)")
        ax.legend(loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize=8)
    return _figure(out / "coverage.png", draw)


def _hold_figure(out: Path, rows: Sequence[Row]) -> str | None:
    ok = [r for r in rows if r.get("status") == "ok" and math.isfinite(_num(r, "held_s"))
          and math.isfinite(_num(r, "fit.tau_1"))]
    if not ok:
        return None

    def draw(fig: Any) -> None:
        ax = fig.add_subplot(1, 2, 1)
        held = np.array([_num(r, "held_s") for r in ok])
        err = np.array([(_num(r, "fit.tau_1") - _num(r, "truth.tau_1")) / _num(r, "truth.tau_1")
                        for r in ok]) * 100
        rel_se = np.array([_num(r, "se.tau_1") / _num(r, "fit.tau_1") for r in ok]) * 100
        materials = sorted({str(r.get("truth_variant")) for r in ok})
        for m in materials:
            sel = np.array([str(r.get("truth_variant")) == m for r in ok])
            ax.scatter(held[sel], err[sel], s=10, label=_label({"truth_variant": m}) or "truth")
        ax.axhline(0.0, color="k", lw=0.8)
        ax.set_xlabel("hold (s)")
        ax.set_ylabel("tau_1 error (%)")
        ax.legend(fontsize=7)
        ax2 = fig.add_subplot(1, 2, 2)
        for m in materials:
            sel = np.array([str(r.get("truth_variant")) == m for r in ok])
            ax2.scatter(held[sel], np.abs(err[sel]), s=10, marker="x", label="|error|")
            ax2.scatter(held[sel], rel_se[sel], s=10, marker="o", label="reported s.e.")
        ax2.set_yscale("log")
        ax2.set_xlabel("hold (s)")
        ax2.set_ylabel("tau_1: |error| and reported s.e. (%)")
        ax2.legend(fontsize=7)
    return _figure(out / "tau_vs_hold.png", draw)


def _speeds(row: Row) -> str:
    for key, value in row.items():
        if key.startswith("param.") and key.endswith(".speeds") and isinstance(value, str):
            return ",".join(f"{v * 1e6:.3g}" for v in json.loads(value)) + " um/s"
    speeds = json.loads(str(row.get("lclg_by_speed") or "{}"))
    return ",".join(f"{float(s) * 1e6:.3g}" for s in speeds) + " um/s"


def _speed_figure(out: Path, rows: Sequence[Row]) -> str | None:
    ok = [r for r in rows if r.get("status") == "ok" and math.isfinite(_num(r, "fit.G_1"))
          and r.get("lclg_by_speed")]
    if not ok:
        return None
    sets: dict[str, list[float]] = {}
    for r in ok:
        sets.setdefault(_speeds(r), []).append(
            (_num(r, "fit.G_1") - _num(r, "truth.G_1")) / _num(r, "truth.G_1") * 100)

    def draw(fig: Any) -> None:
        ax = fig.add_subplot(1, 1, 1)
        ax.boxplot(list(sets.values()))
        ax.set_xticks(range(1, len(sets) + 1), list(sets), rotation=15, fontsize=7)
        ax.axhline(0.0, color="k", lw=0.8)
        ax.set_xlabel("speeds of the ladder")
        ax.set_ylabel("G_1 (G_l) error (%)")
    return _figure(out / "g_l_vs_speeds.png", draw)


def lclg_by_truth(rows: Sequence[Row]) -> dict[str, dict[float, np.ndarray]]:
    """l_c/l_g per speed (mean over a member's passes), grouped by truth variant."""
    out: dict[str, dict[float, list[float]]] = {}
    for r in rows:
        if r.get("status") != "ok" or not r.get("lclg_by_speed"):
            continue
        by = out.setdefault(_label({"truth_variant": r.get("truth_variant")}) or "truth", {})
        for s, v in json.loads(str(r["lclg_by_speed"])).items():
            by.setdefault(float(s), []).append(float(v))
    return {k: {s: np.asarray(v) for s, v in sorted(d.items())} for k, d in out.items()}


def _lclg_figure(out: Path, data: dict[str, dict[float, np.ndarray]]) -> str | None:
    if not data:
        return None

    def draw(fig: Any) -> None:
        ax = fig.add_subplot(1, 1, 1)
        for label, by in data.items():
            s = np.array(list(by)) * 1e6
            m = np.array([v.mean() for v in by.values()])
            sd = np.array([v.std(ddof=1) if v.size > 1 else 0.0 for v in by.values()])
            ax.errorbar(s, m, yerr=sd, marker="o", capsize=3, label=label)
        ax.set_xscale("log")
        ax.set_xlabel("sliding speed (um/s)")
        ax.set_ylabel("l_c / l_g (mean +- 1 s.d. over members)")
        ax.legend(fontsize=8)
    return _figure(out / "lclg_vs_speed.png", draw)


def _lclg_table(data: dict[str, dict[float, np.ndarray]]) -> Table | None:
    """Per speed: each truth's mean and sd of l_c/l_g; with two truths, their difference in
    pooled standard deviations (how well one run of the paper's noise tells them apart)."""
    if len(data) < 1:
        return None
    labels = list(data)
    speeds = sorted({s for by in data.values() for s in by})
    rows: list[dict[str, object]] = []
    for s in speeds:
        row: dict[str, object] = {"speed_m_s": s}
        for i, label in enumerate(labels):
            v = data[label].get(s, np.array([]))
            row[f"mean_{i}"] = float(v.mean()) if v.size else math.nan
            row[f"sd_{i}"] = float(v.std(ddof=1)) if v.size > 1 else math.nan
        if len(labels) == 2:
            pooled = math.sqrt((_f(row["sd_0"]) ** 2 + _f(row["sd_1"]) ** 2) / 2)
            row["separation_sd"] = abs(_f(row["mean_1"]) - _f(row["mean_0"])) / pooled \
                if pooled > 0 else math.nan
        rows.append(row)
    cols = [Column("speed_m_s", "speed (um/s)", 1e6)]
    for i, label in enumerate(labels):
        cols += [Column(f"mean_{i}", f"l_c/l_g {label}"), Column(f"sd_{i}", "sd")]
    if len(labels) == 2:
        cols.append(Column("separation_sd", "difference / pooled sd", digits=3))
    return Table("l_c/l_g against speed", tuple(cols), rows, "lclg_by_speed.csv")


def _f(value: object) -> float:
    return float(value) if isinstance(value, int | float) else math.nan


def write_campaign_report(out: str | Path, title: str, rows: Sequence[Row]) -> Path:
    """Write ``out/report.html`` with its figures and CSV tables; returns its path."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    groups = variants(rows)
    table_rows, names = variant_rows(rows)
    sections = []
    cols = [Column("variant", "variant"), Column("what", "parameters and truth"),
            Column("members", "members"), Column("ok", "ok"), Column("failed", "failed"),
            Column("not_resolved", "not resolved (left out)"),
            Column("wall_median_s", "median wall (s)", digits=3)]
    for n in names:
        cols += [Column(f"bias.{n}", f"{n} bias (%)", 100, 3),
                 Column(f"sd.{n}", f"{n} sd (%)", 100, 3),
                 Column(f"cov.{n}", f"{n} 95 % coverage (%)", 100, 3)]
    variant_table = Table("Protocol variants", tuple(cols), table_rows, "variants.csv")
    if names:
        sections.append(Section(
            "Recovery of the hidden truth",
            ["Relative error (fit - truth) / truth of each fitted parameter over the members "
             "of each variant (V0, V1, ... as in the table below). The coverage is the share "
             "of members whose reported 95 % interval holds the truth, with its binomial 95 % "
             "band; honest intervals give 95 %."],
            [(_bias_figure(out, groups, names), "bias and spread against the truth"),
             (_coverage_figure(out, groups, names), "coverage of the reported 95 % intervals")]))
    hold = _hold_figure(out, rows)
    if hold:
        sections.append(Section("tau against the hold length", [
            "Left: the error of tau_1 against the hold; right: its size and the standard "
            "error the fit reported (both relative)."], [(hold, "tau_1 against the hold")]))
    speed = _speed_figure(out, rows)
    if speed:
        sections.append(Section("G_l against the speeds used", [
            "Error of the fitted relaxation modulus G_1 (the paper's G_l) for each set of "
            "ladder speeds."], [(speed, "G_1 error by speed set")]))
    lclg = lclg_by_truth(rows)
    lclg_fig = _lclg_figure(out, lclg)
    if lclg_fig:
        table = _lclg_table(lclg)
        sections.append(Section("l_c/l_g against speed", [
            "Mean and spread over members of l_c/l_g per speed, for each truth variant (e.g. "
            "cutoff against MDR unloading). With two variants, the last column is the "
            "difference of the means in pooled standard deviations: above about 2, one run "
            "with this noise tells them apart."], [(lclg_fig, "l_c/l_g against speed")],
            [table] if table else []))
    sections.append(Section("Variants", [], [], [variant_table]))
    failed = [r for r in rows if r.get("status") != "ok"]
    if failed:
        sections.append(Section("Members not ok", [], [], [Table(
            "Failed or incomplete members",
            (Column("member_id", "member"), Column("seed", "seed"), Column("status", "status"),
             Column("error", "error"), Column("safe_stop", "safe stop"),
             Column("safe_stop_line", "what the safe stop verified")), failed,
            "failed.csv")]))
    return write_report(out, title, "\n".join(summary_lines(rows)), sections)
