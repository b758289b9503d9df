"""``gelrig validate``: the README's quantitative claims, re-measured by a suite of campaigns.

Each campaign file of the suite (``examples/campaigns/validate_*.toml``) is an ordinary
campaign with one more table, ``[validate]``, read and removed here before the campaign
parser sees it::

    [validate]
    claims = ["hold.coverage", "hold.bias", "first_touch"]   # keys of CLAIMS

    [validate.quick]          # --quick: these replace the campaign's own values
    replicates = 5
    simulator = { noise = "0.1 mN" }
    params = { "step[1].hold" = "300 s" }

A campaign without ``[validate.quick]`` is left out of ``--quick``. Each claim is measured on
its campaign's results: the bound it states, the measured distribution (per variant of the
grid), and pass, fail or "not measured" (the columns it needs are not recorded yet: a hook
for a later analysis). One report: ``OUT/validate.html`` with ``validate.json``.
"""

from __future__ import annotations

import copy
import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gelrig.campaign.report import Coverage, variants
from gelrig.campaign.spec import CampaignSpec, parse_campaign
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.fields import read_toml

Row = Mapping[str, Any]
#: Prefix of the suite's campaign files.
PREFIX = "validate_"
#: Relaxation parameters whose intervals and bias a hold claim measures.
HOLD_PARAMS = ("G_e", "G_1", "tau_1", "G_2", "tau_2")
LADDER_PARAMS = ("G_e", "G_1", "tau_1", "mu")


def suite_dir() -> Path:
    """The built-in suite: ``examples/campaigns`` of this checkout or installed tree."""
    return Path(__file__).resolve().parents[2] / "examples" / "campaigns"


@dataclass(frozen=True)
class Verdict:
    """What a claim measured: ``status`` pass, fail or not measured; ``measured`` in one
    line; ``rows`` the distribution per variant (and parameter)."""

    status: str
    measured: str
    rows: list[dict[str, Any]] = field(default_factory=list)


@dataclass(frozen=True)
class Claim:
    """A quantitative claim of the README and how its campaign's rows test it."""

    key: str
    text: str
    bound: str
    evaluate: Callable[[Sequence[Row]], Verdict]


def _num(row: Row, key: str) -> float:
    value = row.get(key)
    return float(value) if isinstance(value, int | float) and value is not None else math.nan


def _terms(row: Row) -> int:
    return sum(1 for k in (1, 2) if math.isfinite(_num(row, f"truth.tau_{k}")))


def _resolved(rows: Sequence[Row]) -> tuple[list[Row], int]:
    """The ok members that resolved as many terms as their truth has, and how many did not.
    A ladder fit records no ``terms_resolved`` (its terms are not tested for resolution): its
    members count as resolved."""
    ok = [r for r in rows if r.get("status") == "ok"]
    good = [r for r in ok if not math.isfinite(_num(r, "terms_resolved"))
            or _num(r, "terms_resolved") >= _terms(r)]
    return good, len(ok) - len(good)


def coverage_band(n: int) -> int:
    """Fewest hits of n honest 95 % intervals not rejected at 2.5 % (binomial)."""
    from scipy.stats import binom

    return int(binom.ppf(0.025, n, 0.95)) if n else 0


def _coverage_rows(rows: Sequence[Row], names: Sequence[str]) -> Verdict:
    """Per variant and parameter: hits of the 95 % interval, the band, sd of the z-score."""
    out, worst, failed = [], math.inf, 0
    unresolved = 0
    for label, group in variants(rows).items():
        good, missing = _resolved(group)
        unresolved += missing
        for name in names:
            have = [r for r in good if math.isfinite(_num(r, f"truth.{name}"))
                    and math.isfinite(_num(r, f"fit.{name}"))]
            if not have:
                continue
            hits = sum(_num(r, f"lo.{name}") <= _num(r, f"truth.{name}") <= _num(r, f"hi.{name}")
                       for r in have)
            cov = Coverage(int(hits), len(have))
            z = np.array([(_num(r, f"fit.{name}") - _num(r, f"truth.{name}"))
                          / _num(r, f"se.{name}") for r in have])
            z = z[np.isfinite(z)]
            floor = coverage_band(cov.n)
            ok = cov.hits >= floor
            failed += not ok
            worst = min(worst, cov.fraction)
            out.append({"variant": label, "parameter": name, "n": cov.n, "hits": cov.hits,
                        "coverage": cov.fraction, "at_least": floor,
                        "z_sd": float(np.std(z, ddof=1)) if z.size > 1 else math.nan,
                        "pass": ok})
    if not out:
        return Verdict("not measured", "no resolved member recorded the fit's intervals "
                       "(fit.*, lo.*, hi.*)")
    status = "fail" if failed else "pass"
    return Verdict(status, f"{len(out) - failed}/{len(out)} (variant, parameter) cells in the "
                   f"band; lowest coverage {worst * 100:.0f} %; {unresolved} member(s) not "
                   "resolved, left out", out)


def _bias_rows(rows: Sequence[Row], names: Sequence[str]) -> Verdict:
    """Per variant and parameter: mean relative error, its sd, and whether the mean is
    inside its spread (|mean| <= t_0.995 sd / sqrt(n))."""
    from scipy.stats import t as student

    out: list[dict[str, Any]] = []
    failed = 0
    for label, group in variants(rows).items():
        good, _ = _resolved(group)
        for name in names:
            err = np.array([(_num(r, f"fit.{name}") - _num(r, f"truth.{name}"))
                            / _num(r, f"truth.{name}") for r in good])
            err = err[np.isfinite(err)]
            if err.size < 3:
                continue
            mean, sd = float(np.mean(err)), float(np.std(err, ddof=1))
            limit = float(student.ppf(0.995, err.size - 1)) * sd / math.sqrt(err.size)
            ok = abs(mean) <= limit
            failed += not ok
            out.append({"variant": label, "parameter": name, "n": int(err.size),
                        "bias": mean, "sd": sd, "limit": limit, "pass": ok})
    if not out:
        return Verdict("not measured", "fewer than 3 resolved members per variant")
    return Verdict("fail" if failed else "pass",
                   f"{len(out) - failed}/{len(out)} (variant, parameter) cells without a "
                   "significant bias", out)


def _first_touch(rows: Sequence[Row]) -> Verdict:
    """The ramp refit's first touch against the truth: bias, sd, worst (um), coverage."""
    out: list[dict[str, Any]] = []
    failed = 0
    for label, group in variants(rows).items():
        have = [r for r in group if r.get("status") == "ok"
                and math.isfinite(_num(r, "fit.first_touch"))]
        if len(have) < 3:
            continue
        err = np.array([_num(r, "fit.first_touch") - _num(r, "truth.first_touch")
                        for r in have])
        hits = sum(_num(r, "lo.first_touch") <= _num(r, "truth.first_touch")
                   <= _num(r, "hi.first_touch") for r in have)
        floor = coverage_band(len(have))
        ok = hits >= floor
        failed += not ok
        out.append({"variant": label, "n": len(have), "bias_um": float(np.mean(err)) * 1e6,
                    "sd_um": float(np.std(err, ddof=1)) * 1e6,
                    "worst_um": float(err[np.argmax(np.abs(err))]) * 1e6, "hits": int(hits),
                    "at_least": floor, "pass": ok})
    if not out:
        return Verdict("not measured", "no member recorded the ramp's first touch "
                       "(fit.first_touch)")
    worst = max(abs(float(r["worst_um"])) for r in out)
    return Verdict("fail" if failed else "pass",
                   f"{len(out) - failed}/{len(out)} variants' intervals in the band; worst "
                   f"error {worst:.2f} um", out)


def _needs(columns: Sequence[str], bound: float, what: str) -> Callable[[Sequence[Row]], Verdict]:
    """A per-pass shear claim: every member's worst pass within ``bound``, from the columns a
    shear member records (``gelrig.campaign.member.pass_columns``); not measured where no
    member recorded them. A recorded NaN (a pass without the figure) fails."""

    def evaluate(rows: Sequence[Row]) -> Verdict:
        ok_rows = [r for r in rows if r.get("status") == "ok"]
        have = [r for r in ok_rows
                if all(isinstance(r.get(c), int | float) for c in columns)]
        if not have:
            return Verdict("not measured", f"needs the per-pass columns {', '.join(columns)} "
                           "(recorded by shear members, gelrig.campaign.member.pass_columns)")
        worst = [max(abs(_num(r, c)) for c in columns) for r in have]
        good = [bool(w <= bound) for w in worst]  # NaN: not within
        bad = len(good) - sum(good)
        median = float(np.median(worst))
        return Verdict("fail" if bad else "pass",
                       f"{len(have) - bad}/{len(have)} members within {what}; worst pass per "
                       f"member: median {median:.4g}, largest "
                       f"{max(worst) if all(map(math.isfinite, worst)) else math.nan:.4g}",
                       [{"seed": r.get("seed"), "variant": r.get("variant"), "worst": w,
                         "outliers": r.get("pass.outliers"), "pass": ok}
                        for r, w, ok in zip(have, worst, good, strict=True)])

    return evaluate


def _fit_claims(prefix: str, what: str, names: Sequence[str], per: str) -> tuple[Claim, ...]:
    """The coverage and bias claims of one fit over ``names``."""
    return (
        Claim(f"{prefix}.coverage", f"every reported 95 % interval of {what} "
              f"({', '.join(names)}) holds its truth in 95 % of members",
              f"per {per}: hits >= the binomial 2.5 % quantile of n at 0.95",
              lambda rows: _coverage_rows(rows, names)),
        Claim(f"{prefix}.bias", f"{what} is unbiased (every bias inside its spread)",
              f"per {per}: |mean relative error| <= t_0.995 sd / sqrt(n)",
              lambda rows: _bias_rows(rows, names)),
    )


#: The claims the suite can measure, by key (a campaign names those it measures).
CLAIMS: dict[str, Claim] = {c.key: c for c in (
    *_fit_claims("hold", "the hold fit", HOLD_PARAMS, "variant"),
    *_fit_claims("ladder", "the ladder fit", LADDER_PARAMS, "parameter"),
    Claim("first_touch", "first touch refitted on the hold's ramp, with an honest interval",
          "per variant: the refit's 95 % interval holds the true touch in the binomial band",
          _first_touch),
    Claim("shear.l_g", "l_g within 0.3 % of the chord, every pass", "|l_g / chord - 1| <= 0.003",
          _needs(["pass.lg_chord_rel_max"], 0.003, "0.3 %")),
    Claim("shear.l_c", "C and AC l_c within 10 um of the fresh-contact model, every pass",
          "|error| <= 10 um", _needs(["pass.lc_error_max_m"], 10e-6, "10 um")),
    Claim("shear.lc_lg", "l_c/l_g within 0.0035 of the fresh-contact model, every pass",
          "|error| <= 0.0035", _needs(["pass.lclg_error_max"], 0.0035, "0.0035")),
    Claim("shear.mu", "mu per pass within 5 %, every pass", "|mu / truth - 1| <= 0.05",
          _needs(["pass.mu_rel_error_max"], 0.05, "5 %")),
)}


@dataclass(frozen=True)
class SuiteCampaign:
    """One campaign of the suite: its file, the claims it measures, the parsed campaign."""

    path: Path
    claims: tuple[str, ...]
    spec: CampaignSpec

    @property
    def name(self) -> str:
        return self.path.stem.removeprefix(PREFIX)


def _override(table: dict[str, Any], quick: Mapping[str, Any], source: str) -> None:
    """Apply a ``[validate.quick]`` table to a campaign table in place."""
    for key, value in quick.items():
        if key in ("replicates", "first_seed"):
            table.setdefault("campaign", {})[key] = value
        elif key in ("simulator", "params", "analysis") and isinstance(value, dict):
            table.setdefault(key, {}).update(value)
        else:
            raise ConfigError("[validate.quick] " + key, value, "allowed: replicates, "
                              "first_seed, simulator, params, analysis", source)


def load_suite_campaign(path: Path, quick: bool) -> SuiteCampaign | None:
    """A suite campaign file, its ``[validate]`` table read off (None: not in ``--quick``)."""
    table = read_toml(path, "campaign file")
    head = table.pop("validate", None)
    source = str(path)
    if not isinstance(head, dict):
        raise ConfigError("[validate]", head if head is not None else "missing",
                          "a table naming the claims this campaign measures", source)
    claims = head.get("claims")
    if not isinstance(claims, list) or not claims or any(c not in CLAIMS for c in claims):
        raise ConfigError("[validate] claims", claims, "a list of: " + ", ".join(CLAIMS),
                          source)
    if quick:
        small = head.get("quick")
        if small is None:
            return None
        if not isinstance(small, dict):
            raise ConfigError("[validate] quick", small, "a table of overrides", source)
        table = copy.deepcopy(table)
        _override(table, small, source)
    return SuiteCampaign(path, tuple(claims), parse_campaign(table, source, path.parent))


def load_suite(directory: Path, quick: bool, only: Sequence[str] = ()) -> list[SuiteCampaign]:
    """The suite's campaigns (``validate_*.toml`` in ``directory``), those named in ``only``
    if given."""
    files = sorted(directory.glob(f"{PREFIX}*.toml"))
    if not files:
        raise ConfigError("--suite", str(directory), f"no {PREFIX}*.toml campaign files there")
    names = [f.stem.removeprefix(PREFIX) for f in files]
    unknown = [n for n in only if n not in names]
    if unknown:
        raise ConfigError("--only", ",".join(unknown), "allowed: " + ", ".join(names))
    out = []
    for path in files:
        if only and path.stem.removeprefix(PREFIX) not in only:
            continue
        loaded = load_suite_campaign(path, quick)
        if loaded is not None:
            out.append(loaded)
    if not out:
        raise ConfigError("--quick", "", "no campaign of the suite has a [validate.quick] "
                          "table")
    return out


@dataclass(frozen=True)
class ClaimResult:
    """A claim measured on one campaign."""

    claim: str
    campaign: str
    text: str
    bound: str
    members: int
    verdict: Verdict


def evaluate(campaign: SuiteCampaign, rows: Sequence[Row]) -> list[ClaimResult]:
    """Every claim the campaign names, measured on its rows."""
    return [ClaimResult(key, campaign.name, CLAIMS[key].text, CLAIMS[key].bound, len(rows),
                        CLAIMS[key].evaluate(rows)) for key in campaign.claims]


def summary_lines(results: Sequence[ClaimResult]) -> list[str]:
    """One line per claim: status, claim, campaign, what was measured."""
    return [f"{r.verdict.status.upper():13s} {r.claim:16s} [{r.campaign}, {r.members} "
            f"members] {r.verdict.measured}" for r in results]


def _coverage_figure(out: Path, results: Sequence[ClaimResult]) -> str | None:
    """Coverage of every (variant, parameter) cell of the coverage claims, with the band."""
    cells = [(r.campaign, row) for r in results for row in r.verdict.rows
             if "coverage" in row]
    if not cells:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(10, max(3.0, 0.22 * len(cells))))
    try:
        y = np.arange(len(cells))
        frac = np.array([row["coverage"] for _, row in cells]) * 100
        floor = np.array([row["at_least"] / row["n"] for _, row in cells]) * 100
        colours = ["tab:green" if row["pass"] else "tab:red" for _, row in cells]
        ax.barh(y, frac, color=colours)
        ax.scatter(floor, y, marker="|", color="k", s=80, label="binomial 2.5 % floor")
        ax.axvline(95.0, color="k", ls="--", lw=1, label="95 %")
        ax.set_yticks(y, [f"{c}: {row['parameter']} {row['variant']}"[:90] for c, row in cells],
                      fontsize=6)
        ax.set_xlim(50, 101)
        ax.set_xlabel("members whose reported 95 % interval holds the truth (%)")
        ax.legend(loc="lower left", fontsize=7)
        fig.tight_layout()
        fig.savefig(out / "validate_coverage.png", dpi=100)
    finally:
        plt.close(fig)
    return "validate_coverage.png"


def write_validate_report(out: Path, title: str, results: Sequence[ClaimResult],
                          commands: Sequence[str]) -> Path:
    """``out/validate.html`` (with ``validate.json`` and the claims' CSV tables)."""
    from gelrig.instrument.reports.document import Column, Section, Table, write_report

    out.mkdir(parents=True, exist_ok=True)
    (out / "validate.json").write_text(json.dumps(
        {"commands": list(commands), "claims": [asdict(r) for r in results]},
        indent=1, default=str))
    claims = [{"claim": r.claim, "campaign": r.campaign, "members": r.members, "text": r.text,
               "bound": r.bound, "measured": r.verdict.measured, "status": r.verdict.status}
              for r in results]
    table = Table("Claims", (Column("status", "status"), Column("claim", "claim"),
                             Column("campaign", "campaign"), Column("members", "members"),
                             Column("text", "what the README says"),
                             Column("bound", "bound"), Column("measured", "measured")),
                  claims, "claims.csv")
    sections = [Section("Claims", ["Each claim of the README, the bound that makes it true, "
                                   "and what the suite measured: " + "; ".join(commands)],
                        [], [table])]
    figure = _coverage_figure(out, results)
    if figure:
        sections.append(Section("Interval coverage", [
            "Every (variant, parameter) cell of the coverage claims: green in the binomial "
            "band of honest 95 % intervals, red below it."], [(figure, "coverage")]))
    for r in results:
        if not r.verdict.rows:
            continue
        keys = list(r.verdict.rows[0])
        sections.append(Section(f"{r.claim} ({r.campaign})", [r.verdict.measured], [], [Table(
            r.claim, tuple(Column(k, k, digits=4) for k in keys), r.verdict.rows,
            f"{r.campaign}_{r.claim.replace('.', '_')}.csv")]))
    return write_report(out, title, "\n".join(summary_lines(results)), sections,
                        name="validate.html")
