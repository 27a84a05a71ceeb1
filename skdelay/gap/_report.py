"""GapReport: the result of :func:`diagnose_gap` (tables, lab-book summary, figure, HTML)."""

from __future__ import annotations

import html
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ._effects import EFFECTS, _fmt
from ._signature import mean_std

_PANELS = ("spectrum", "histogram", "autocorrelation", "forecast_error", "segment")


@dataclass
class GapReport:
    """Outcome of a sim-to-real gap diagnosis.

    Attributes
    ----------
    best_effect : str or None
        Effect that explains the gap; None when real and simulated data are
        indistinguishable within the sim-vs-sim spread (``significance``) or
        when no candidate removes a substantial part of the gap.
    effects : pandas.DataFrame
        One row per candidate, best first: ``effect``, ``params`` (fitted
        values), ``gap_before``, ``gap_after``, ``shrink``
        (``1 - gap_after / gap_before``), ``status`` (``"ok"`` or
        ``"failed"``), ``reason`` (why it failed), ``target``, ``description`` (fitted parameters in
        physical units), ``n_evals``, ``seconds``.
    where : pandas.DataFrame
        Localised discrepancies, largest first: ``indicator``, ``feature``,
        ``low``, ``high`` (frequency in cycles per time unit, values in units
        of the real data, lags/times in time units), ``peak`` (centre of the
        most discrepant bin), ``unit``, ``excess``
        (share of the gap), ``z`` (peak z-score vs the sim ensemble),
        ``real_value``, ``sim_value``, ``sim_std``, ``note``.
    residual_where : pandas.DataFrame or None
        The same after the best effect (or the combination).
    gap_before : float
        Gap between real data and the simulator (sum over indicators of the
        mean squared z-score in excess of 1).
    gap_after, shrink : float
        Gap left by the best effect (or combination) and the fraction removed.
    significance : dict
        ``gap_before``, ``null_median``, ``null_max`` (leave-one-out gaps of
        the simulator runs among themselves), ``threshold``, ``significant``.
    combined : dict or None
        Second effect fitted on top of the best: ``effects``, ``params``,
        ``gap_after``, ``shrink``, ``table``.
    profiles : dict of DataFrame
        Per indicator: bin bounds, ``real``, ``sim_mean``, ``sim_std`` and
        ``fitted_mean`` (simulator + best effect) — what :meth:`plot` draws.
    explained : {"fully", "partly", "not explained", "no gap"}
        ``"fully"`` only when, with the best effect (or combination) added, no
        indicator stays significantly off, the real data have no forecast-error
        dip the simulator lacks and the fitted parameters agree with the
        independent evidence (``checks``); ``"partly"`` when an effect removes
        part of the gap but not all of it.
    reasons : list of str
        Why the gap is not fully explained (what remains).
    checks : list of (effect, bool, str)
        The independent-evidence checks of the fitted parameters.
    """

    best_effect: str | None
    effects: pd.DataFrame
    where: pd.DataFrame
    gap_before: float
    gap_after: float
    shrink: float
    significance: dict
    combined: dict | None = None
    residual_where: pd.DataFrame | None = None
    profiles: dict = field(default_factory=dict, repr=False)
    info: dict = field(default_factory=dict)
    explained: str = "no gap"
    reasons: list = field(default_factory=list)
    checks: list = field(default_factory=list)

    @classmethod
    def from_problem(cls, problem, *, table, where, significance, best_effect, combined, after,
                     explained="no gap", reasons=(), checks=()):
        """Assemble the report from a solved :class:`GapProblem`."""
        from ._where import localise

        profiles = {}
        for name, ind in problem.indicators.items():
            lo, hi = ind.bounds()
            df = pd.DataFrame({"low": lo, "high": hi, "label": ind.labels(),
                               "real": problem.real_features[name],
                               "sim_mean": problem.before.mean[name],
                               "sim_std": problem.before.std[name]})
            if after is not None:
                df["fitted_mean"] = after.mean[name]
                df["fitted_std"] = after.std[name]
            profiles[name] = df
        gap_before = float(problem.before.gap)
        gap_after = float(after.gap) if after is not None else gap_before
        sim = problem.simulator
        info = {"n_samples": problem.n_samples, "sample_dt": problem.sample_dt,
                "time_unit": problem.time_unit,
                "real_mean": mean_std(problem.real)[0], "real_std": mean_std(problem.real)[1],
                "simulator": type(sim).__name__, "simulator_params": dict(sim.params),
                "n_sims": len(problem.base), "dip_real": problem.dip_real,
                "dip_sim": problem.dip_sim, "dip_spread": problem.dip_spread,
                "dip_curves": problem.dip_curves}
        return cls(best_effect=best_effect, effects=table, where=where, gap_before=gap_before,
                   gap_after=gap_after, shrink=1.0 - max(gap_after, 0.0) / gap_before
                   if gap_before > 0 else 0.0, significance=significance, combined=combined,
                   residual_where=localise(problem, after) if after is not None else None,
                   profiles=profiles, info=info, explained=explained, reasons=list(reasons),
                   checks=list(checks))

    # ---------------------------------------------------------------- text
    def _where_phrase(self, df, k=3):
        parts = []
        for _, r in df.head(k).iterrows():
            parts.append(f"{r['indicator']} {r['feature']} at {_fmt(r['low'])}-{_fmt(r['high'])} "
                         f"{r['unit']} (z = {r['z']:.1f}; {r['note']})")
        return "; ".join(parts)

    def summary(self):
        """A paragraph for a lab book: where, which effect (fitted values, units), shrink, residual."""
        s = self.significance
        i = self.info
        unit = f" {i['time_unit']}" if i.get("time_unit") else ""
        head = (f"Real data ({i['n_samples']} samples, sample_dt = {_fmt(i['sample_dt'])}{unit}) "
                "versus "
                f"{i['simulator']} ({', '.join(f'{k}={_fmt(v)}' for k, v in i['simulator_params'].items())}; "
                f"{i['n_sims']} runs): gap {self.gap_before:.3g} against a no-gap level of "
                f"{s['null_median']:.2g} (runs among themselves; threshold {s['threshold']:.3g}).")
        if not s["significant"]:
            return (head + " Real and simulated data are indistinguishable within the sim-vs-sim "
                    "spread; no effect is needed to explain them.")
        text = [head]
        if len(self.where):
            text.append("Largest discrepancies: " + self._where_phrase(self.where) + ".")
        ok = self.effects[self.effects.status == "ok"]
        if self.best_effect is None:
            best = ok.iloc[0] if len(ok) else None
            text.append(
                "No candidate effect explains the gap"
                + (f" (best: {best['effect']}, removes {100 * best['shrink']:.0f}%)"
                   if best is not None else "")
                + "; the cause lies outside the effect library or in the model itself.")
            if self.reasons[1:] or len(self.where):
                text.append(self._remaining())
            return " ".join(text)
        row = self.effects.iloc[0]
        desc = EFFECTS[row["effect"]].description if row["effect"] in EFFECTS else row["effect"]
        names = [row["effect"]] + ([self.combined["effects"][1]] if self.combined else [])
        if self.explained == "fully":
            text.append(f"Best explanation: {row['effect']} ({desc}): {row['description']}. "
                        f"It removes {100 * row['shrink']:.0f}% of the gap "
                        f"({row['gap_before']:.3g} -> {row['gap_after']:.3g}).")
        else:
            text.append(f"Partly explained ({100 * self.shrink:.0f} %) by "
                        f"{' + '.join(names)} ({row['description']}); the rest lies outside "
                        "the effect library.")
        if len(ok) > 1:
            nxt = ok.iloc[1]
            text.append(f"Runner-up: {nxt['effect']} ({100 * nxt['shrink']:.0f}%).")
        if self.combined is not None:
            c = self.combined
            t = c["table"].iloc[0]
            text.append(f"A second effect on top, {c['effects'][1]} ({t['description']}), brings "
                        f"the gap to {c['gap_after']:.3g} ({100 * c['shrink']:.0f}% removed in "
                        "total).")
        resid = "within" if self.gap_after <= s["threshold"] else "above"
        text.append(f"Residual gap {self.gap_after:.3g}, {resid} the no-gap threshold.")
        if self.explained != "fully":
            text.append(self._remaining())
        return " ".join(text)

    def _remaining(self):
        """What the effects leave unexplained: the reasons and the residual discrepancies."""
        parts = list(self.reasons)
        where = self.residual_where if self.residual_where is not None else self.where
        if where is not None and len(where):
            parts.append(self._where_phrase(where, 2))
        return "What remains: " + "; ".join(parts) + "." if parts else ""

    def __str__(self):
        return self.summary()

    # ---------------------------------------------------------------- figure
    def plot(self, *, figsize=(13, 8)):
        """Indicator panels (real, simulator +- 2 std, simulator + best effect) and shrink bars."""
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(2, 3, figsize=figsize)
        for ax, name in zip(axes.flat, _PANELS):
            df = self.profiles.get(name)
            if df is None:
                ax.set_visible(False)
                continue
            self._panel(ax, name, df)
        ax = axes.flat[-1]
        ok = self.effects[self.effects.status == "ok"]
        ax.barh(ok["effect"][::-1], 100 * ok["shrink"][::-1].clip(lower=0), color="#4477aa")
        ax.set_xlabel("gap removed (%)")
        ax.set_title("candidate effects")
        title = f"sim-to-real gap: {self.gap_before:.3g}"
        if self.best_effect:
            title += f" -> {self.gap_after:.3g} with {self.best_effect}"
        fig.suptitle(title)
        fig.tight_layout()
        return fig

    def _panel(self, ax, name, df):
        if name == "segment":
            x = np.arange(len(df))
        else:
            x = 0.5 * (df["low"].to_numpy() + df["high"].to_numpy())
            if name == "histogram":
                x = np.clip(x, df["low"].iloc[1], df["high"].iloc[-2])
        ax.plot(x, df["real"], color="k", lw=1.2, label="real")
        m, s = df["sim_mean"].to_numpy(), df["sim_std"].to_numpy()
        ax.plot(x, m, color="#4477aa", lw=1, label="simulator")
        ax.fill_between(x, m - 2 * s, m + 2 * s, color="#4477aa", alpha=0.25, lw=0)
        if "fitted_mean" in df:
            ax.plot(x, df["fitted_mean"], color="#cc6677", lw=1, ls="--",
                    label=f"+ {self.best_effect}")
        ax.set_title(name)
        units = {"spectrum": "frequency (cycles / time unit)", "histogram": "value (real units)",
                 "autocorrelation": "lag (time units)", "forecast_error": "tau (time units)",
                 "segment": "segment statistic (index)"}
        ax.set_xlabel(units[name])
        if name == "spectrum":
            ax.set_ylabel("log10 PSD")
        ax.legend(fontsize=7)

    def to_html(self, path):
        """Write a self-contained HTML report (atomic) and return its path."""
        import matplotlib.pyplot as plt

        from .._html import write_html

        effects = self.effects.copy()
        effects["params"] = effects["params"].map(
            lambda p: ", ".join(f"{k}={_fmt(v) if not isinstance(v, str) else v}"
                                for k, v in (p or {}).items()))
        fig = self.plot()
        try:
            sections = [("Summary", f"<p>{html.escape(self.summary())}</p>"),
                        ("Where real and simulated data differ", self.where),
                        ("Candidate effects", effects),
                        ("Indicators", fig)]
            if self.residual_where is not None:
                sections.insert(3, ("Residual discrepancies", self.residual_where))
            return write_html(path, "Sim-to-real gap diagnosis", sections)
        finally:
            plt.close(fig)
