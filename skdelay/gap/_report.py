"""GapReport: the result of :func:`diagnose_gap` (tables, lab-book summary, figure, HTML)."""

from __future__ import annotations

import html
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ._effects import EFFECTS, fmt_value
from ._range import RANGE_ALPHA
from ._signature import mean_std
from ._units import format_frequency, frequency_unit, time_unit_name

_PANELS = ("spectrum", "histogram", "autocorrelation", "forecast_error", "segment")
#: which panel shows a fitted effect best (the one figure of the report's head)
KEY_PANEL = {"periodic_interference": "spectrum", "measurement_noise": "spectrum",
             "dynamical_noise": "spectrum", "lowpass": "spectrum",
             "timebase_mismatch": "spectrum", "clipping": "histogram",
             "quantization": "histogram", "outliers": "histogram",
             "parameter_drift": "segment", "delay_mismatch": "forecast_error"}


@dataclass
class GapReport:
    """Outcome of a sim-to-real gap diagnosis.

    Attributes
    ----------
    best_effect : str or None
        Effect that explains the gap; None when real and simulated data are
        indistinguishable within the sim-vs-sim spread (``significance``) or
        when no candidate removes a substantial part of the gap.  Where the
        forecast-error dip is the only significant discrepancy
        (``significance["dip_only"]``), only a fit that moves the model's dip
        onto the record's explains it, whatever share of the (no-gap level)
        gap it removes; ``info["dip_led"]`` is then True.  Likewise where the
        record's excursions beyond the runs' range are (``significance["spikes_only"]``):
        only a fit whose runs the record no longer leaves explains them
        (``info["spike_led"]``).
    effects : pandas.DataFrame
        One row per candidate, best first: ``effect``, ``params`` (fitted
        values), ``gap_before``, ``gap_after``, ``shrink``
        (``1 - gap_after / gap_before``), ``status`` (``"ok"`` or
        ``"failed"``), ``reason`` (why it failed), ``target``, ``gap_after_fit`` /
        ``shrink_fit`` (in-sample, whole record), ``cv_gap_before`` /
        ``cv_gap_after`` (held-out half).  With cross-validation (records of at
        least 4000 samples) ``shrink`` is the held-out half's
        ``1 - cv_gap_after / cv_gap_before``, never above the in-sample share,
        and ``gap_after = gap_before * (1 - shrink)``; the in-sample share
        stands where the held-out half cannot test the effect (its gap within
        the no-gap level of its clean runs with and without the effect) or is
        left within that level by it (``cross_validated`` is False only in
        the first case);
        ``params`` are fitted on the whole record.  Also ``description``
        (fitted parameters in physical units), ``consistent`` (do the
        parameters agree with independent evidence; None: no check),
        ``n_evals``, ``seconds``.
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
        Gap left by the best effect (or combination) and the fraction removed
        (cross-validated when ``info["cross_validated"]``; the in-sample
        fraction is ``info["shrink_fit"]``).
    significance : dict
        ``gap_before``, ``null_median``, ``null_max`` (leave-one-out gaps of
        the simulator runs among themselves), ``threshold``, ``significant``.
    combined : dict or None
        Second effect fitted on top of the best: ``effects``, ``params``,
        ``gap_after``, ``shrink``, ``table``, and ``joint`` (True when the
        two were fitted in turn, each beneath / on top of the other: then the
        best's own row is its value in the pair, and its share alone may be
        negative).
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
    tie : dict or None
        When the two best candidates each explain the record in-sample, their
        gaps on fresh noise realisations (:func:`skdelay.gap._diagnose.tie_test`):
        ``effects``, ``gaps``, ``difference``, ``se``, ``t``, ``critical``,
        ``n_realisations``, ``decided`` (False: the record cannot tell the
        two apart at this length) and ``runner_up_world`` (when the paired
        differences separate them: the same difference on records simulated
        with either candidate as the truth).  None when the test was not needed.
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
    tie: dict | None = None

    @classmethod
    def from_problem(cls, problem, *, table, where, significance, best_effect, combined, after,
                     lacking=(),
                     explained="no gap", reasons=(), checks=(), cv_shrink=None,
                     cross_validated=False, tie=None, small_rest=False, dip_led=False,
                     spike_led=False):
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
        info_cv = {"shrink_fit": 1.0 - max(gap_after, 0.0) / gap_before if gap_before > 0
                   else 0.0, "cross_validated": bool(cross_validated)}
        if cv_shrink is not None:
            gap_after = gap_before * (1.0 - cv_shrink)
        sim = problem.simulator
        info = {"n_samples": problem.n_samples, "sample_dt": problem.sample_dt,
                "time_unit": problem.time_unit,
                "real_mean": mean_std(problem.real)[0], "real_std": mean_std(problem.real)[1],
                "simulator": type(sim).__name__, "simulator_params": dict(sim.params),
                "n_sims": len(problem.base), "dip_real": problem.dip_real,
                "dip_sim": problem.dip_sim, "dip_spread": problem.dip_spread,
                "dip_curves": problem.dip_curves, "spectrum_view": problem.spectrum_view,
                "lines": [(ln.frequency, ln.amplitude, ln.z) for ln in problem.lines],
                # of those, the lines found only against the runs of the best effect
                "masked_lines": [ln.frequency for ln in getattr(problem, "masked_lines", ())],
                "masked_by": getattr(problem, "masked_by", None),
                "sim_dip_centres": [d.centre for d in problem.sim_dips],
                "second_dips": [d.centre for d in problem.second_dips],
                "small_rest": bool(small_rest), "dip_led": bool(dip_led),
                "spike_led": bool(spike_led), **info_cv}
        return cls(best_effect=best_effect, effects=table, where=where, gap_before=gap_before,
                   gap_after=gap_after, shrink=1.0 - max(gap_after, 0.0) / gap_before
                   if gap_before > 0 else 0.0, significance=significance, combined=combined,
                   residual_where=(localise(problem, after, lacking=lacking)
                                   if after is not None else None),
                   profiles=profiles, info=info, explained=explained, reasons=list(reasons),
                   checks=list(checks), tie=tie)

    # ---------------------------------------------------------------- text
    def _where_phrase(self, df, k=3):
        parts = []
        for _, r in df.head(k).iterrows():
            parts.append(f"{r['indicator']} {r['feature']} at {fmt_value(r['low'])}-{fmt_value(r['high'])} "
                         f"{r['unit']} (z = {r['z']:.1f}; {r['note']})")
        return "; ".join(parts)

    def summary(self):
        """Three sentences (where / which / how far), then a paragraph with the details.

        Each sentence is conditioned on the numbers: "explains" only when the
        gap is fully explained (:attr:`explained`), "part of it" with the
        percentage otherwise.
        """
        return self.headline() + "\n\n" + self._details()

    # ------------------------------------------------------------ headline
    def _freq(self, f):
        return format_frequency(f, self.info.get("time_unit"))

    def _time_unit(self):
        return time_unit_name(self.info.get("time_unit"))

    def _where_words(self, r):
        """One row of ``where`` in plain words."""
        tu = self._time_unit()
        side = "higher" if r["z"] > 0 else "lower"
        feature, ind = r["feature"], r["indicator"]
        if feature == "spectral line":
            f = r["peak"] / (frequency_unit(self.info.get("time_unit"))[0])
            return f"a spectral line at {self._freq(f)} that the simulator lacks"
        if feature == "dip position":
            return (f"the position of the forecast-error dip ({fmt_value(r['real_value'])} {tu} in the "
                    f"real data, {fmt_value(r['sim_value'])} {tu} simulated)")
        if feature == "second dip":
            return f"a second forecast-error dip at {fmt_value(r['peak'])} {tu} that the simulator lacks"
        if ind == "spectrum":
            return (f"the power spectrum between {fmt_value(r['low'])} and {fmt_value(r['high'])} "
                    f"{r['unit']} (real power {side})")
        if ind == "histogram":
            return (f"the distribution of values between {fmt_value(r['low'])} and {fmt_value(r['high'])} "
                    f"(units of the data; real {side})")
        if ind == "segment":
            return (f"the {feature.replace('segment ', '')} between t = {fmt_value(r['low'])} and "
                    f"{fmt_value(r['high'])} {tu} (real {side}: the record is not stationary)")
        if ind == "increments":
            return f"the distribution of one-step increments (real {side})"
        if ind == "levels":
            return f"the number of distinct values (real {side}: another resolution)"
        if ind == "pile_ups":
            end = "lowest" if "lowest" in feature else "highest"
            return (f"the samples held at the {end} value, {fmt_value(r['peak'])} (units of the "
                    f"data; real {side}: a clipped end)")
        return f"the {feature} between {fmt_value(r['low'])} and {fmt_value(r['high'])} {r['unit']}"

    def _local_evidence(self):
        """Why a gap under the threshold is significant (a clause; empty above the threshold)."""
        s = self.significance
        if self.gap_before > s["threshold"]:
            return ""
        if s.get("lines"):
            what = "the record has a spectral line that the simulator runs lack"
        elif s.get("far_bin", s.get("max_z", 0.0) > s.get("z_local", np.inf)):
            what = f"one bin lies {s['max_z']:.3g} spreads off"
        elif s.get("dip_shift"):
            what = "the forecast-error dip lies outside the runs' scatter"
        elif s.get("beyond_range_p", 1.0) < RANGE_ALPHA:
            what = (f"the record leaves the simulator runs' range {s['beyond_range']} times "
                    f"(chance {s['beyond_range_p']:.1g} at the rate of {self._range_runs()})")
        elif s.get("jumps_p", 1.0) < RANGE_ALPHA:
            what = (f"{s['jumps']} times a sample jumps off both neighbours farther than the simulator "
                    f"runs ever do (spikes, or turns sharper than theirs; chance "
                    f"{s['jumps_p']:.1g} at the rate of {self._range_runs()})")
        else:
            return ""
        return (f", significant although the gap {self.gap_before:.3g} is within the no-gap "
                f"threshold {s['threshold']:.3g}: {what}")

    def _only_excursions(self):
        """The record's only evidence is its excursions beyond the runs' range of values or
        of jumps: the gap within the no-gap threshold, no line, bin, or dip beyond chance."""
        s = self.significance
        return bool(self.gap_before <= s["threshold"] and not s.get("lines")
                    and not s.get("far_bin", s.get("max_z", 0.0) > s.get("z_local", np.inf))
                    and not s.get("dip_shift")
                    and (s.get("beyond_range_p", 1.0) < RANGE_ALPHA
                         or s.get("jumps_p", 1.0) < RANGE_ALPHA))

    def _range_runs(self):
        """The runs the range tests were calibrated on, in words."""
        n = self.significance.get("range_runs")
        return f"{n} clean simulator runs among themselves" if n else "the runs among themselves"

    def _joint(self):
        """Were the two effects fitted in turn, each beneath / on top of the other (so the
        first one's share alone says nothing)?"""
        return bool(self.combined and self.combined.get("joint"))

    def _pair_description(self, row):
        """The best's fitted values, and its second effect's when there is one (``a; b``)."""
        text = row["description"]
        if not self.combined:
            return text
        table = self.combined.get("table")
        second = self.combined["effects"][1]
        if table is None or "description" not in table or not (table["effect"] == second).any():
            return text
        return f"{text}; {table.loc[table['effect'] == second, 'description'].iloc[0]}"

    def _why_second(self, best, nxt):
        """Why a runner-up that removes more of the gap than the best ranks second (a clause,
        empty when it removes less)."""
        if not nxt["shrink"] > best["shrink"]:
            return ""
        if self._joint():
            return ", more alone; the best is fitted together with its second effect"
        if self.tie and self.tie.get("decided") and nxt["effect"] in self.tie["effects"]:
            return ", more, but fresh noise realisations prefer the best (see below)"

        def checked(row):  # None: no independent check; else whether it agreed
            flag = row.get("consistent")
            return None if flag is None or pd.isna(flag) else bool(flag)

        if checked(best) and not checked(nxt):
            if checked(nxt) is False:
                return ", more, but its parameters contradict independent evidence in the data"
            return (", more, but only the best's parameters are confirmed by independent "
                    "evidence in the data")
        return ""

    def _tie_words(self):
        """A sentence on the tie test (empty when it was not run)."""
        t = self.tie
        if not t:
            return ""
        (a, b), (ga, gb) = t["effects"], t["gaps"]
        if t.get("with"):  # two pairs: each with the same second effect
            a, b = f"{a} + {t['with']}", f"{b} + {t['with']}"
        if t.get("on"):  # two pairs: the same first effect, two second effects
            a, b = f"{t['on']} + {a}", f"{t['on']} + {b}"
        pair = bool(t.get("with") or t.get("on"))
        n = t["n_realisations"]
        kind = "effects" if pair else "effect"
        gaps = (f"over {n} noise realisations {a} leaves a gap of {np.mean(ga):.3g} on "
                f"average and {b} {np.mean(gb):.3g} (difference {t['difference']:.3g} +- "
                f"{t['se']:.2g}")
        world = t.get("runner_up_world")
        seen = ("" if world is None else
                f"; on records simulated with {b} as the truth the difference is "
                f"{np.mean(world['runner_up']):.2g} on average, at most "
                f"{world['bound']:.2g} on one more such record")
        held = t.get("held_out")
        if held:  # only one of the two explained the record in-sample (_held_out_tie)
            (sa, ga0), (sb, gb0) = held[a], held[b]
            why_asked = (f"{a} and {b} remove about as much of the held-out halves "
                         f"({100 * sa:.0f} % and {100 * sb:.0f} %), while in-sample they "
                         f"leave gaps of {ga0:.3g} and {gb0:.3g}, against a no-gap threshold of "
                         f"{self.significance['threshold']:.3g}")
            if t["decided"]:
                return (f"The effect {a} is preferred to {b}: {why_asked}; {gaps}, t = "
                        f"{t['t']:.2g} above {t['critical']:.2g}){seen}.")
            return (f"The effect {b} cannot be ruled out: {why_asked}; {gaps}, "
                    f"{GapReport._undecided_why(t, a, b)}, so this record cannot tell {a} from "
                    f"{b}; a longer record may.")
        if t["decided"]:
            return (f"The {kind} {a} are preferred to {b}, which also explain"
                    if pair else
                    f"The effect {a} is preferred to {b}, which also explains") + (
                f" the record in-sample: {gaps}, t = {t['t']:.2g} above "
                f"{t['critical']:.2g}){seen}.")
        return (f"The {kind} {b} {'do' if pair else 'does'} as well: {gaps}, "
                f"{GapReport._undecided_why(t, a, b)}, so this record cannot tell {a} from {b}; "
                "a longer record may.")

    @staticmethod
    def _undecided_why(t, a, b):
        """Why an undecided tie test could not separate ``a`` (ahead) from ``b``."""
        world = t.get("runner_up_world")
        if world is None:
            return f"t = {t['t']:.2g} within {t['critical']:.2g})"
        # the paired test separated them (a first); the candidates' worlds did not
        diff = world["difference"]
        return (f"t = {t['t']:.2g} above {t['critical']:.2g}), but "
                + (f"records simulated with {b} as the truth show differences up to "
                   f"{world['bound']:.2g} in favour of {a}"
                   if diff <= world["bound"] else
                   f"records simulated with {a} as the truth favour it by at least "
                   f"{world['better_bound']:.2g}, more than this record's {diff:.2g}"))

    def _fresh_words(self):
        """The record's gaps against the fresh ensembles (``significance["replicated"]``)."""
        rep = self.significance.get("replicated") or [self.gap_before]
        fresh = " and ".join(f"{g:.3g}" for g in rep[1:])
        return f"{fresh} (median with the first runs' {float(np.nanmedian(rep)):.3g})"

    def _no_gap_words(self):
        """Why a record is no gap, in words that follow its numbers."""
        thr = self.significance["threshold"]
        if self.gap_before <= thr:
            return (f"the gap {self.gap_before:.3g} is within the no-gap threshold {thr:.3g} of "
                    "simulator runs among themselves")
        # above the threshold against the record's own runs, but not against fresh ones
        # (significance's replication): that excess was one ensemble's draw
        return (f"the gap {self.gap_before:.3g} exceeds the no-gap threshold {thr:.3g} against "
                f"the first simulator runs, but against fresh runs it is {self._fresh_words()}, "
                "within the threshold, so the excess was those runs' draw")

    def headline(self):
        """Where the data differ, which effect explains it (or how much of it), how far."""
        s = self.significance
        thr = s["threshold"]
        if not s["significant"]:
            return (f"Real and simulated data are indistinguishable: {self._no_gap_words()}. "
                    "No effect is needed. Nothing remains to be explained.")
        if self._only_excursions():
            # the binned profiles lie within the runs' own scatter: their largest difference
            # is not where the data differ
            where = "Real and simulated data differ in a few isolated samples."
        elif len(self.where):
            top = self._where_words(self.where.iloc[0])
            where = f"Real and simulated data differ most in {top}."
        else:
            where = (f"Real and simulated data differ (gap {self.gap_before:.3g}), spread over "
                     "many "
                     "bins with none far off on its own.")
        where = f"{where[:-1]}{self._local_evidence()}."
        ok = self.effects[self.effects.status == "ok"]
        row = self.effects.iloc[0]
        cv = " cross-validated" if self.info.get("cross_validated") else ""
        if self.best_effect is None and s.get("dip_only"):
            which = (f"None of the library's effects moves {self._dip_words()}, the only "
                     "discrepancy beyond chance.")
            far = (f"The gap, {self.gap_before:.3g}, is within the no-gap threshold {thr:.3g}, "
                   "so the share of it an effect removes is no evidence either way.")
            return f"{where} {which} {far}"
        if self.best_effect is None:
            best = (f" (the best, {ok.iloc[0]['effect']}, removes "
                    f"{100 * max(ok.iloc[0]['shrink'], 0):.0f} %)") if len(ok) else ""
            which = f"None of the library's effects accounts for it{best}."
            far = (f"The gap is {self.gap_before:.3g}, {self.gap_before / thr:.3g} times the "
                   f"no-gap threshold {thr:.3g}.")
            return f"{where} {which} {far}"
        names = [row["effect"]] + ([self.combined["effects"][1]] if self.combined else [])
        label = (f"The effects {names[0]} and {names[1]}" if len(names) > 1
                 else f"The effect {names[0]}")
        if self.explained == "fully":
            verb = "explain" if len(names) > 1 else "explains"
            which = f"{label} {verb} it: {self._pair_description(row)}."
        elif self._only_unchecked():
            # nothing is left over; only the independent evidence fails to back the fit
            failed = "; ".join(text for _, ok, text in self.checks if not ok)
            which = (f"{label} remove{'' if len(names) > 1 else 's'} "
                     f"{100 * self.shrink:.0f} % of it and leave{'' if len(names) > 1 else 's'} "
                     "no indicator off, but the data's own evidence does not confirm the "
                     f"fitted values: {failed}.")
        elif self._small_rest():
            n_off = len(self.reasons)
            which = (f"{label} account{'' if len(names) > 1 else 's'} for "
                     f"{100 * self.shrink:.0f} % of it; the rest would not be called a gap, "
                     f"too little to name a second cause, though {n_off} "
                     f"indicator{'s' if n_off > 1 else ''} still "
                     f"differ{'' if n_off > 1 else 's'} (details below).")
        else:
            which = (f"{label} account{'' if len(names) > 1 else 's'} for part of it "
                     f"({100 * self.shrink:.0f} %); the rest lies outside the effect library.")
        if self.tie and not self.tie["decided"]:
            which = f"{which} {self._tie_words()}"
        if self.info.get("dip_led") or self.info.get("spike_led"):
            if self.explained != "fully":
                n = len(self.reasons)
                what = "the dip" if self.info.get("dip_led") else "the excursions"
                which = (f"{label} ({row['description']}) accounts for {what}, but {n} "
                         f"check{'s' if n > 1 else ''} still fail{'' if n > 1 else 's'} "
                         "(details below).")
            return f"{where} {which} {self._dip_led_words(thr)}"
        state = "within" if self.gap_after <= thr else "still above"
        far = (f"With {'them' if len(names) > 1 else 'it'} the gap falls from "
               f"{self.gap_before:.3g} to {self.gap_after:.3g} ({100 * self.shrink:.0f} % "
               f"removed{cv}), {state} the no-gap threshold {thr:.3g}.")
        return f"{where} {which} {far}"

    def _dip_words(self):
        """The model's and the record's forecast-error dip, in time units (a phrase)."""
        dt, tu = self.info["sample_dt"], self._time_unit()
        return (f"the model's forecast-error dip (at {fmt_value(self.info['dip_sim'] * dt)} "
                f"{tu}) onto the record's (at {fmt_value(self.info['dip_real'] * dt)} {tu})")

    def _dip_led_words(self, thr):
        """How a fit explains a record whose only evidence is the dip (a fit that moves it)
        or its excursions beyond the runs' range (a fit whose runs make them)."""
        state = "stays within" if self.gap_after <= thr else "rises above"
        if self.info.get("spike_led"):
            how, what, verb = ("Against its runs the record's excursions are within chance "
                               "(values and jumps off their neighbours)"), "excursions", "are"
        else:
            how, what, verb = f"Its fit moves {self._dip_words()}", "dip", "is"
        return (f"{how}; the gap, {self.gap_before:.3g} before and {self.gap_after:.3g} "
                f"after, {state} the no-gap threshold {thr:.3g}, so the {what}, not the share "
                f"of the gap removed ({100 * self.shrink:.0f} %), {verb} the evidence.")

    def _small_rest(self):
        """Is what the effects leave too small to be called a gap, with only broadband
        indicators off (the diagnosis sought no second cause for it)?"""
        return bool(self.info.get("small_rest") and self.explained == "partly"
                    and self.gap_after <= self.significance["threshold"])

    def _only_unchecked(self):
        """Is every reason against "fully" a failed independent-evidence check (no indicator
        still off, no dip the simulator lacks)?"""
        failed = {text for _, ok, text in self.checks if not ok}
        return bool(failed) and set(self.reasons) <= failed

    def _details(self):
        """The lab-book paragraph: data, discrepancies, fitted values, runner-up, residual."""
        s = self.significance
        i = self.info
        unit = f" {i['time_unit']}" if i.get("time_unit") else ""
        params = ", ".join(f"{k}={fmt_value(v)}" for k, v in i["simulator_params"].items())
        head = (f"Real data ({i['n_samples']} samples, sample_dt = {fmt_value(i['sample_dt'])}{unit}) "
                "versus "
                f"{i['simulator']} ({params}; "
                f"{i['n_sims']} runs): gap {self.gap_before:.3g} against a no-gap level of "
                f"{s['null_median']:.2g} (runs among themselves; threshold {s['threshold']:.3g}).")
        if not s["significant"]:
            if self.gap_before > s["threshold"]:
                head += f" Against fresh runs: {self._fresh_words()}."
            return (head + " Real and simulated data are indistinguishable within the sim-vs-sim "
                    "spread; no effect is needed to explain them.")
        text = [head]
        if len(self.where):
            text.append("Largest discrepancies: " + self._where_phrase(self.where) + ".")
        masked = i.get("masked_lines") or []
        if masked:
            freqs = ", ".join(self._freq(f) for f in masked)
            text.append(
                f"The spectral line{'s' if len(masked) > 1 else ''} at {freqs} stood out only "
                f"against runs with {i.get('masked_by')} fitted (the clean runs' own sharp "
                f"peaks hid {'them' if len(masked) > 1 else 'it'}); the candidates were "
                f"fitted again with {'them' if len(masked) > 1 else 'it'} measured.")
        ok = self.effects[self.effects.status == "ok"]
        if self.best_effect is None and s.get("dip_only"):
            text.append(f"No candidate effect moves {self._dip_words()}, the record's only "
                        "discrepancy beyond chance; the cause lies outside the effect library "
                        "or in the model itself.")
            if self.reasons[1:] or len(self.where):
                text.append(self._remaining(said=1))
            return " ".join(text)
        if self.best_effect is None:
            best = ok.iloc[0] if len(ok) else None
            text.append(
                "No candidate effect explains the gap"
                + (f" (best: {best['effect']}, removes {100 * best['shrink']:.0f}%)"
                   if best is not None else "")
                + "; the cause lies outside the effect library or in the model itself.")
            if self.reasons[1:] or len(self.where):
                text.append(self._remaining(said=1))
            return " ".join(text)
        row = self.effects.iloc[0]
        desc = EFFECTS[row["effect"]].description if row["effect"] in EFFECTS else row["effect"]
        names = [row["effect"]] + ([self.combined["effects"][1]] if self.combined else [])
        if self.info.get("dip_led") or self.info.get("spike_led"):
            text.append(f"{'Best explanation' if self.explained == 'fully' else 'Partly explained by'}"
                        f": {row['effect']} ({desc}): {row['description']}. "
                        + self._dip_led_words(s["threshold"]))
        elif self.explained == "fully" and self._joint():
            alone = (f"removes {100 * row['shrink']:.0f}% of the gap" if row["shrink"] >= 0
                     else "widens the gap")
            text.append(f"Best explanation: {row['effect']} ({desc}): {row['description']}; "
                        f"fitted in turn with {names[1]}, it explains the gap together with "
                        f"it (alone it {alone}: {row['gap_before']:.3g} -> "
                        f"{row['gap_after']:.3g}).")
        elif self.explained == "fully":
            text.append(f"Best explanation: {row['effect']} ({desc}): {row['description']}. "
                        f"It removes {100 * row['shrink']:.0f}% of the gap "
                        f"({row['gap_before']:.3g} -> {row['gap_after']:.3g}).")
        elif self._small_rest():
            text.append(f"Explained up to a rest within the no-gap threshold "
                        f"({100 * self.shrink:.0f} % removed) by {' + '.join(names)} "
                        f"({row['description']}); no second cause is named for so small a "
                        "rest.")
        else:
            text.append(f"Partly explained ({100 * self.shrink:.0f} %) by "
                        f"{' + '.join(names)} ({row['description']}); the rest lies outside "
                        "the effect library.")
        if len(ok) > 1:
            nxt = ok.iloc[1]
            text.append(f"Runner-up: {nxt['effect']} ({100 * nxt['shrink']:.0f}%"
                        f"{self._why_second(row, nxt)}).")
        if self.tie:
            text.append(self._tie_words())
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

    def _remaining(self, said=0):
        """What the effects leave unexplained: the reasons (but the first ``said``, which the
        text has given already) and the residual discrepancies."""
        parts = list(self.reasons[said:])
        where = self.residual_where if self.residual_where is not None else self.where
        if where is not None and len(where):
            parts.append(self._where_phrase(where, 2))
        return "What remains: " + "; ".join(parts) + "." if parts else ""

    def __str__(self):
        return self.summary()

    # ---------------------------------------------------------------- figure
    def key_panel(self):
        """Name of the panel that shows the diagnosis: the best effect's, else the top
        discrepancy's indicator (``spectrum`` when nothing stands out)."""
        if self.best_effect in KEY_PANEL:
            return KEY_PANEL[self.best_effect]
        if len(self.where):
            top = self.where.iloc[0]
            if top["indicator"] in ("spectrum", "histogram", "segment", "forecast_error"):
                return top["indicator"]
        return "spectrum"

    def plot(self, *, figsize=(13, 11)):
        """The figure that shows the diagnosis on top, the indicator panels below.

        Top: the key panel (:meth:`key_panel`): the whole-record spectrum on a
        log-frequency axis with the lines marked, the histogram with the
        clipped end marked, the segment statistics against time, or the
        forecast-error curves with the dips marked.  Below: spectrum,
        histogram, autocorrelation, forecast error and segment statistics
        (real, simulator +- 2 spreads, simulator + fitted effect) and the gap
        each candidate removes.
        """
        import matplotlib.pyplot as plt

        fig = plt.figure(figsize=figsize)
        grid = fig.add_gridspec(3, 3, height_ratios=(1.3, 1, 1))
        self._draw(fig.add_subplot(grid[0, :]), self.key_panel(), key=True)
        axes = [fig.add_subplot(grid[1 + k // 3, k % 3]) for k in range(6)]
        for ax, name in zip(axes, _PANELS):
            self._draw(ax, name)
        ax = axes[-1]
        ok = self.effects[self.effects.status == "ok"]
        ax.barh(ok["effect"][::-1], 100 * ok["shrink"][::-1].clip(lower=0), color="#4477aa")
        # candidates removing little in-sample are not cross-validated (their shrink is
        # the in-sample one)
        ax.set_xlabel("gap removed (%; held-out half where cross-validated)"
                      if self.info.get("cross_validated") else "gap removed (%)")
        ax.set_title("candidate effects")
        fig.suptitle(self.headline().split(". ")[0] + ".", fontsize=10)
        fig.tight_layout()
        return fig

    # units of the axes
    def _funit(self):
        return frequency_unit(self.info.get("time_unit"))

    def _draw(self, ax, name, key=False):
        if name == "spectrum" and key and self.info.get("spectrum_view") is not None:
            return self._spectrum_panel(ax)
        if name == "forecast_error" and key and self.info.get("dip_curves") is not None:
            return self._dip_panel(ax)
        df = self.profiles.get(name)
        if df is None:
            ax.set_visible(False)
            return None
        if name == "segment":
            return self._segment_panel(ax, df)
        return self._profile_panel(ax, name, df, key)

    def _bands(self, ax, x, df, label_fit=True):
        ax.plot(x, df["real"], color="k", lw=1.2, label="real data")
        m, s = df["sim_mean"].to_numpy(), df["sim_std"].to_numpy()
        ax.plot(x, m, color="#4477aa", lw=1, label="simulator")
        ax.fill_between(x, m - 2 * s, m + 2 * s, color="#4477aa", alpha=0.25, lw=0,
                        label="simulator +- 2 spreads")
        if "fitted_mean" in df and label_fit and self.best_effect:
            ax.plot(x, df["fitted_mean"], color="#cc6677", lw=1, ls="--",
                    label=f"simulator + {self.best_effect}")

    def _profile_panel(self, ax, name, df, key):
        factor, funit = self._funit()
        tu = self._time_unit()
        x = 0.5 * (df["low"].to_numpy() + df["high"].to_numpy())
        if name == "histogram":
            x = np.clip(x, df["low"].iloc[1], df["high"].iloc[-2])
        if name == "spectrum":
            x = x * factor
        self._bands(ax, x, df)
        per = "time unit" if self.info.get("time_unit") is None else tu
        labels = {
            "spectrum": (f"frequency ({funit})",
                         f"log10 power density (signal std squared per cycle per {per})",
                         "power spectrum (Welch)"),
            "histogram": ("value (units of the real data)", "sqrt(probability per bin)",
                          "distribution of values"),
            "autocorrelation": (f"lag ({tu})", "autocorrelation", "autocorrelation"),
            "forecast_error": (f"delay tau ({tu})", "log10 forecast error (m = 2)",
                               "forecast error against the delay"),
        }
        xl, yl, title = labels[name]
        if name == "spectrum":
            ax.set_xscale("log")
        if name == "histogram" and key:
            for level, word in self._clip_levels():
                ax.axvline(level, color="#cc6677", lw=1.5)
                ax.annotate(f"clipped {word} {fmt_value(level)}", (level, ax.get_ylim()[1]),
                            color="#cc6677", fontsize=8, ha="right", va="top", rotation=90)
        ax.set_xlabel(xl)
        ax.set_ylabel(yl)
        ax.set_title(title)
        ax.legend(fontsize=7)

    def _clip_levels(self):
        """Clipped ends in units of the real data: from the clipping fit, else the histogram's
        discrepant end bins."""
        out = []
        i = self.info
        for names, params in self._fitted():
            if names == "clipping":
                for key, word in (("high", "above"), ("low", "below")):
                    if np.isfinite(params.get(key, np.inf)):
                        out.append((i["real_mean"] + i["real_std"] * params[key], word))
        return out

    def _fitted(self):
        if self.best_effect is None:
            return []
        out = [(self.effects.iloc[0]["effect"], dict(self.effects.iloc[0]["params"]))]
        if self.combined:
            out.append((self.combined["effects"][1], dict(self.combined["params"][1])))
        return out

    def _spectrum_panel(self, ax):
        factor, funit = self._funit()
        f, real, sim = self.info["spectrum_view"]
        # densities per cycle per time unit -> per Hz when the time unit is known
        shift = np.log10(factor)
        ax.plot(f * factor, real - shift, color="k", lw=1, label="real data")
        ax.plot(f * factor, sim - shift, color="#4477aa", lw=1, label="simulator (mean of runs)")
        ax.set_xscale("log")
        for freq, _, z in self.info.get("lines", []):
            ax.axvline(freq * factor, color="#cc6677", lw=1.2, ls="--")
            ax.annotate(f"line at {self._freq(freq)} (z = {z:.0f})", (freq * factor, 1.0),
                        xycoords=("data", "axes fraction"), color="#cc6677", fontsize=8,
                        ha="left", va="top")
        ax.set_xlabel(f"frequency ({funit}, log scale)")
        ax.set_ylabel(f"log10 power density (signal std squared per {funit.replace('cycles ', 'cycle ')})")
        ax.set_title("whole-record spectrum (multitaper)")
        ax.legend(fontsize=8, loc="lower left")

    def _dip_panel(self, ax):
        taus, real, sim = self.info["dip_curves"]
        dt = self.info["sample_dt"]
        tu = self._time_unit()
        ax.plot(taus * dt, real, color="k", lw=1.2, marker=".", label="real data")
        ax.plot(taus * dt, sim, color="#4477aa", lw=1, marker=".", label="simulator")
        ax.set_yscale("log")
        if self.info.get("dip_real") is not None:
            ax.axvline(self.info["dip_real"] * dt, color="k", ls="--", lw=1)
            ax.axvline(self.info["dip_sim"] * dt, color="#4477aa", ls="--", lw=1)
        for c in self.info.get("second_dips", []):
            ax.axvline(c * dt, color="#cc6677", lw=1.5)
            ax.annotate(f"second dip at {fmt_value(c * dt)} {tu}", (c * dt, 1.0),
                        xycoords=("data", "axes fraction"), color="#cc6677", fontsize=8,
                        va="top")
        ax.set_xlabel(f"delay tau ({tu})")
        ax.set_ylabel("forecast error sigma_2 (relative to the std)")
        ax.set_title("forecast error against the delay (dips marked)")
        ax.legend(fontsize=8)

    def _segment_panel(self, ax, df):
        tu = self._time_unit()
        t = 0.5 * (df["low"].to_numpy() + df["high"].to_numpy())
        colours = ("k", "#cc6677", "#228833")
        for colour, (label, part) in zip(colours, df.groupby("label", sort=False)):
            x = t[part.index]
            m, s = part["sim_mean"].to_numpy(), part["sim_std"].to_numpy()
            name = label.replace("segment ", "")
            ax.plot(x, part["real"], color=colour, lw=1.2, marker="o", ms=3,
                    label=f"{name} (real)")
            ax.fill_between(x, m - 2 * s, m + 2 * s, color=colour, alpha=0.15, lw=0)
        ax.axhline(0.0, color="0.5", lw=0.8)
        ax.set_xlabel(f"time ({tu})")
        ax.set_ylabel("change from the first segment (standard units)")
        ax.set_title("statistics per segment against time (bands: simulator +- 2 spreads)")
        ax.legend(fontsize=7)

    @staticmethod
    def figure_caption(fig):
        """The top panel's title and axes in words (read off the figure itself), so that a
        reader of the page -- or a screen reader -- knows what the one figure shows."""
        ax = fig.axes[0]
        return (f"Top panel: {ax.get_title()}; horizontal axis: {ax.get_xlabel()}; vertical "
                f"axis: {ax.get_ylabel()}. Below: each indicator, real data against the "
                "simulator's runs (band: +- 2 spreads).")

    def to_html(self, path):
        """Write a self-contained HTML report (atomic) and return its path."""
        import matplotlib.pyplot as plt

        from .._html import write_html

        effects = self.effects.copy()
        effects["params"] = effects["params"].map(
            lambda p: ", ".join(f"{k}={fmt_value(v) if not isinstance(v, str) else v}"
                                for k, v in (p or {}).items()))
        fig = self.plot()
        try:
            sections = [("Summary", f"<p><b>{html.escape(self.headline())}</b></p>"),
                        ("What shows it", [fig, f"<p>{html.escape(self.figure_caption(fig))}</p>"]),
                        ("Details", f"<p>{html.escape(self._details())}</p>"),
                        ("Where real and simulated data differ", self.where),
                        ("Candidate effects", effects)]
            if self.residual_where is not None:
                sections.append(("Residual discrepancies", self.residual_where))
            return write_html(path, "Sim-to-real gap diagnosis", sections)
        finally:
            plt.close(fig)
