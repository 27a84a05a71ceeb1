"""HTML reports of :func:`skdelay._analysis.analyze_series` and of the demo.

Self-contained pages (figures inlined as PNG, see :mod:`skdelay._html`):
forecast-error curves, correlation revivals, Lyapunov spectra, histograms
and power spectra of data vs model runs, space-time plots, the tables and,
for the demo, the paper's table and the rescaled-spectrum collapse.
"""

from __future__ import annotations

import html

import numpy as np
import pandas as pd

from ._html import write_html

__all__ = ["analysis_sections", "write_analysis_report", "write_demo_report"]

_COLORS = {1: "#8c564b", 2: "#1f77b4", 3: "#ff7f0e", 4: "#2ca02c", 5: "#d62728", 6: "#9467bd"}


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def _color(m):
    return _COLORS.get(int(m), None)


def _close(fig):
    _plt().close(fig)


# --------------------------------------------------------------------------------- figures
def fig_forecast_error(result):
    """sigma_m(tau) for every m with the dip centre and half-width shaded."""
    from .plotting import plot_forecast_error

    fig = plot_forecast_error(result.forecast_error, logy=True)
    fig.set_size_inches(7.5, 4)
    ax = fig.axes[0]
    for line, m in zip(ax.lines, result.forecast_error.columns):
        row = result.delays.loc[m]
        ax.axvspan(row["delay"] - row["half_width"], row["delay"] + row["half_width"],
                   color=line.get_color(), alpha=0.1)
    ax.set_title("one-step forecast error (shaded: estimated delay +- half width)")
    return fig


def fig_correlations(result):
    """Autocorrelation and mutual information with their revivals and the delay."""
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.2), layout="constrained")
    rev = result.revivals
    for ax, key, label in ((axes[0], "acf", "autocorrelation"),
                           (axes[1], "mi", "mutual information [nats]")):
        curve = rev[key]
        ax.plot(np.arange(curve.size), curve, lw=1, color="#345")
        ax.axvline(result.delay, color="#d62728", lw=1, ls="--", label=f"delay {result.delay}")
        peak = rev.get(f"{key}_strongest")
        if peak is not None:
            ax.axvline(peak, color="#888", lw=1, ls=":", label=f"strongest revival {peak}")
        ax.set_xlabel("lag [samples]")
        ax.set_ylabel(label)
        ax.legend(fontsize=8)
    return fig


def fig_spectra(result, scale=1.0, unit="1/time unit"):
    """Lyapunov spectra of the models of every m."""
    from .plotting import plot_lyapunov_spectrum

    fig = plot_lyapunov_spectrum({f"m = {m}": spec.exponents * scale
                                  for m, spec in result.spectra.items()})
    fig.set_size_inches(7.5, 4)
    ax = fig.axes[0]
    ax.set_ylabel(f"lambda_i [{unit}]")
    ax.set_title("Lyapunov spectra of the fitted models")
    return fig


def _display_m(result):
    """The model shown in the time-series and space-time panels.

    The minimal faithful one if there is one, else the one whose free run
    lasted longest (ties: the largest m).
    """
    if result.minimal_m is not None and result.minimal_m in result.runs:
        return result.minimal_m
    return max(result.runs, key=lambda m: (result.runs[m].size, m))


def _runs(result):
    return {f"model m = {m}": run for m, run in result.runs.items()
            if run.size >= 100 and np.ptp(run) > 0}


def fig_distributions(result, sample_dt):
    """Histograms and power spectra: data against the free runs of the models."""
    from .plotting import plot_histograms, plot_power_spectra

    plt = _plt()
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.8), layout="constrained")
    series = {"data": result.series, **_runs(result)}
    plot_histograms(series, bins=60, ax=ax1)
    plot_power_spectra(series, sample_dt=sample_dt, ax=ax2)
    ax1.set_title("histogram (invariant measure)")
    ax2.set_title("power spectrum")
    ax2.set_xlabel(f"frequency [1/{result.time_unit}]")
    for ax in (ax1, ax2):
        if ax.lines:  # the data in black, *before* the legend is drawn from the lines
            ax.lines[0].set_color("k")
            ax.lines[0].set_linewidth(2)
        ax.legend(fontsize=7)
    return fig


def fig_series(result, sample_dt):
    """The data above every model's whole free run; a collapse is marked where it starts."""
    plt = _plt()
    runs = {m: run for m, run in result.runs.items() if run.size}
    fig, axes = plt.subplots(1 + len(runs), 1, figsize=(10, 1.6 * (1 + len(runs)) + 0.6),
                             sharey=True, layout="constrained", squeeze=False)
    axes = axes[:, 0]
    length = max([result.series.size] + [r.size for r in runs.values()])
    shown = min(result.series.size, length)
    axes[0].plot(np.arange(shown) * sample_dt, result.series[:shown], "k-", lw=0.4)
    axes[0].set_ylabel("data")
    for ax, (m, run) in zip(axes[1:], runs.items()):
        ax.plot(np.arange(run.size) * sample_dt, run, "-", lw=0.4, color=_color(m))
        ax.set_ylabel(f"model m = {m}")
        at = result.validation.loc[m, "collapsed_at"] if m in result.validation.index else None
        if at is not None and np.isfinite(at):
            ax.axvline(at * sample_dt, color="#d62728", lw=1.2, ls="--")
            ax.text(at * sample_dt, 1.0, " collapse", color="#d62728", fontsize=8,
                    va="top", transform=ax.get_xaxis_transform())
    for ax in axes:
        ax.set_xlim(0, length * sample_dt)
    axes[-1].set_xlabel(f"time [{result.time_unit}]")
    return fig


def fig_space_time(result):
    """Space-time representation of data and model run at the best period."""
    from .plotting import plot_space_time
    from .spacetime import best_space_time_period

    plt = _plt()
    d = result.delay
    candidates = np.arange(max(2, d - 2), d + max(4, d // 5) + 0.25, 0.5)
    period, _ = best_space_time_period(result.series[: 60 * (d + 20)], candidates)
    m = _display_m(result)
    run = result.runs.get(m, np.empty(0))
    panels = [("data", result.series)]
    if run.size > 4 * period:
        panels.append((f"model m = {m}", run))
    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 4), squeeze=False,
                             layout="constrained")
    # one colour scale for data and model, from the data's range
    lo, hi = np.percentile(result.series, [0.5, 99.5])
    for ax, (label, x) in zip(axes[0], panels):
        plot_space_time(x[: int(min(x.size, 120 * period))], period, ax=ax, vmin=lo, vmax=hi)
        ax.set_title(f"{label} (period {period:g} samples)")
    return fig


# ----------------------------------------------------------------------------------- pages
def _row_table(result, scale=1.0, unit="1/time unit"):
    r = result.summary_row()
    ge = "" if r["D_KY_closed"] else ">= "
    # without a significant dip the model's tau is the grid minimum, not a measured delay
    any_dip = bool(result.delays["significant"].astype(bool).any())
    measured = "" if r["delay_significant"] else " (no significant dip: the grid minimum)"
    rows = {
        "delay [samples]": (f"{r['delay']} +- {r['delay_error']:.1f}" if not measured
                            else f"{r['delay']}{measured}"),
        f"delay [{result.time_unit}]": f"{r['delay_time']:g}{measured}",
        "window length m of the model": r["m"],
        "positive Lyapunov exponents N": r["N"],
        f"largest exponent lambda_max [{unit}]": f"{r['lambda_max'] * scale:.4g}",
        "Kaplan-Yorke dimension D_KY": f"{ge}{r['D_KY']:.2f}",
        f"KS entropy h_KS [{unit}]": f"{r['h_KS'] * scale:.4g}",
        f"dimension density D_KY/tau [{unit}]": (f"{ge}{r['D_KY/tau'] * scale:.4g}" if any_dip
                                                  else "- (no delay)"),
        "exponents computed": r["n_exponents"],
        "minimal faithful m (m_d)": "none" if r["minimal_m"] is None else r["minimal_m"],
    }
    return pd.Series(rows, name="value").rename_axis("quantity")


#: A revival within this many samples (or this fraction of the delay) of the delay is
#: "at the delay"; up to RESPONSE_FRACTION beyond it, "slightly beyond" (the loop's
#: response time: 3-25 % in the paper's laser and in Mackey-Glass).
AT_DELAY_SAMPLES, AT_DELAY_FRACTION, RESPONSE_FRACTION = 2, 0.03, 0.3


def _noise_clause(result):
    attrs = getattr(getattr(result, "validation", None), "attrs", {}) or {}
    if not attrs.get("denoised"):
        return ""
    level = float(attrs.get("noise_fraction", float("nan")))
    return (f" (the models were fitted on noise-reduced data: the measurement noise, "
            f"{level:.1%} of the standard deviation, would bias the local fits)")


def faithful_sentence(result):
    """The faithful-model verdict in one sentence, following the table."""
    clause = _noise_clause(result)
    if result.minimal_m is not None:
        table = getattr(result, "validation", None)
        marginal = []
        if table is not None and "marginal" in table:
            above = table.loc[table.index > result.minimal_m]
            marginal = [int(m) for m in above.index[above["marginal"].astype(bool)
                                                    & ~above["faithful"].astype(bool)]]
        if marginal:
            ms = ", ".join(map(str, marginal))
            return (f"Minimal faithful window length m_d = {result.minimal_m}: every model from "
                    f"m = {result.minimal_m} on reproduces the data{clause}, except that the "
                    f"runs of m = {ms} sit at a band's edge (marginal: their median's 95 % "
                    f"interval holds the band).")
        return (f"Minimal faithful window length m_d = {result.minimal_m}: every model from "
                f"m = {result.minimal_m} on reproduces the data{clause}.")
    return f"No model up to m = {max(result.runs or [result.m])} is faithful{clause}: " \
        f"{result.minimal_m_reason or 'see the table'}."


def spectrum_caveat(result):
    """Why the reported model's exponents may not describe an attractor ("" when they do).

    The spectrum is computed from the fitted local maps along the data.  When the
    model's own free runs collapse onto a fixed point or periodic orbit, or stop, the
    model has no chaotic attractor, whatever those exponents say (a linear stochastic
    process gives a positive one from its noise): the sentence says so.
    """
    table = getattr(result, "validation", None)
    if table is None or result.m not in table.index or "status" not in table:
        return ""
    status = str(table.loc[result.m, "status"] or "")
    if not any(word in status for word in ("collapsed", "stopped")):
        return ""
    what = status.split(": ", 1)[-1]
    return (f"the free runs of this model do not stay on a chaotic attractor ({what}): these "
            "exponents are those of its local maps along the data, not of an attractor of "
            "the model")


def ordinal(h):
    """``2nd``, ``3rd``, ``4th``, ``11th``, ``22nd`` ..."""
    h = int(h)
    suffix = "th" if 10 <= h % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(h % 10, "th")
    return f"{h}{suffix}"


def step_sentence(result):
    """Which sampling step the analysis used and why, in words that fit how it was chosen
    (empty for a record analysed at its own step without trying others)."""
    step, dt = result.step, result.sample_dt
    tried = list(getattr(result, "steps_tried", (step,)) or (step,))
    where = (f"so the delays below are in steps of {dt:g}; the model's delay is "
             f"{result.delay * step} samples of the record.")

    def every(h):
        return "every sample" if h == 1 else f"every {ordinal(h)} sample"

    if getattr(result, "step_given", False):
        return "" if step == 1 else f"Every {ordinal(step)} sample was analysed, as asked, {where}"
    if step != tried[0]:  # the ladder of coarser steps found the dip
        nor = "" if len(tried) < 3 else (
            f", nor at {', '.join(every(h) for h in tried[1:-1])}")
        return (f"At the step chosen from the measurement noise ({every(tried[0])}) no window "
                f"length showed a significant forecast-error dip{nor}; {every(step)} shows "
                f"one, {where}")
    out = "" if step == 1 else (
        f"The record is oversampled (the part of the next sample that the last samples "
        f"cannot extrapolate, its second difference, is comparable to the measurement "
        f"noise): {every(step)} was analysed, {where}")
    if len(tried) > 1:
        out += (" " if out else "") + (
            f"Coarser steps ({', '.join(every(h) for h in tried[1:])}) showed no significant "
            "forecast-error dip either.")
    return out


def delay_sentence(result):
    """What the forecast-error dip says about the delay, conditioned on its significance."""
    row = result.delays.loc[result.m]
    if bool(row.get("significant", True)):
        return (f"The forecast-error dip of m = {result.m} gives the delay "
                f"{row['delay']:.1f} +- {row['delay_error']:.1f} samples; the model uses "
                f"tau = {result.delay}.")
    others = result.delays[result.delays["significant"].astype(bool)] \
        if "significant" in result.delays else result.delays.iloc[:0]
    if len(others):  # another window length does show the dip: say so, not "cannot tell"
        told = "; ".join(f"m = {m}: {r['delay']:.1f} +- {r['delay_error']:.1f}"
                         for m, r in others.iterrows())
        return (f"The forecast error of m = {result.m} shows no significant dip "
                f"({row.get('reason', '')}), but other window lengths do ({told} samples); the "
                f"model of m = {result.m} uses its own grid minimum tau = {result.delay}.")
    return (f"The forecast error of m = {result.m} shows no significant dip "
            f"({row.get('reason', '')}), nor does any other window length: the data cannot "
            f"tell the delay; the model uses the grid minimum tau = {result.delay}.")


def revival_sentence(name, lag, result):
    """Where a correlation revival lies relative to the delay, in words that fit the numbers."""
    if lag is None:
        return f"The {name} has no revival in the scanned lags."
    delay = float(result.delays.loc[result.m, "delay"])
    if not bool(result.delays.loc[result.m].get("significant", True)):
        return f"Its strongest {name} revival lies at lag {lag}."
    diff = lag - delay
    if abs(diff) <= max(AT_DELAY_SAMPLES, AT_DELAY_FRACTION * delay):
        where = "at the delay"
    elif 0 < diff <= RESPONSE_FRACTION * delay:
        where = f"{diff:.0f} samples beyond the delay (the loop's response time)"
    elif diff > 0:
        where = (f"{lag / delay:.1f} times the delay: too far beyond it to be the delay's "
                 "revival")
    else:
        where = f"{-diff:.0f} samples before the delay: an internal oscillation, not the delay"
    return f"The strongest {name} revival, at lag {lag}, lies {where}."


def _safe(fn, *args):
    """A figure, or a short note when it cannot be drawn (the report is still written)."""
    try:
        return fn(*args)
    except Exception as exc:  # noqa: BLE001 - one figure must not sink the report
        return f"<p><em>figure not available: {html.escape(str(exc))}</em></p>"


def analysis_sections(result, *, scale=1.0, unit="1/time unit", prefix=""):
    """Report sections (heading, items) of one analysis."""
    dt = result.sample_dt
    delays = result.delays.rename(columns={"delay": "dip centre", "half_width": "half width",
                                           "tau_min": "grid minimum", "tau_used": "model tau"})
    val = result.validation.copy()
    for col in ("lambda_1", "h_ks"):  # the same units as the summary table
        if col in val:
            val[col] = val[col] * scale
    val = val.rename(columns={"lambda_1": f"lambda_1 [{unit}]", "h_ks": f"h_KS [{unit}]",
                              "collapsed_at": "collapsed at [step]"}).T
    rev = result.revivals
    intro = (
        f"<p>{html.escape(result.name)}: "
        f"{getattr(result, 'n_record', None) or result.series.size * result.step} samples, "
        f"sampling interval {dt / result.step:g}. "
        + (html.escape(step_sentence(result)) + " " if step_sentence(result) else "")
        + f"Delays in samples; exponents per {html.escape(unit.split('/', 1)[-1])}. "
        f"{html.escape(delay_sentence(result))} "
        f"{html.escape(revival_sentence('autocorrelation', rev.get('acf_strongest'), result))} "
        f"{html.escape(revival_sentence('mutual information', rev.get('mi_strongest'), result))}"
        "</p>"
    )
    items = [
        (f"{prefix}Summary", [intro, _row_table(result, scale, unit)]),
        (f"{prefix}Delay: one-step forecast error",
         [_safe(fig_forecast_error, result), delays, _safe(fig_correlations, result)]),
        (f"{prefix}Lyapunov spectra, Kaplan-Yorke dimension, KS entropy",
         ([f"<p>For m = {result.m}, {html.escape(spectrum_caveat(result))}.</p>"]
          if spectrum_caveat(result) else []) + [_safe(fig_spectra, result, scale, unit)]),
        (f"{prefix}Validation of the iterated models",
         [(f"<p>{html.escape(faithful_sentence(result))} Each model ran from several "
           "histories; a model is faithful when no run escapes or collapses and its "
           "histogram, power spectrum and cross-prediction distances to the data lie within "
           "the band of the same distances between stretches of the data (columns "
           "<code>*_band</code>), and its Lyapunov spectrum has converged in m.</p>"),
          _safe(fig_series, result, dt), _safe(fig_distributions, result, dt), val,
          _safe(fig_space_time, result)]),
    ]
    return items


def _close_all(sections):
    for _, items in sections:
        for item in items if isinstance(items, list) else [items]:
            if hasattr(item, "savefig"):
                _close(item)


def write_analysis_report(result, path):
    """Write the self-contained HTML report of one analysis."""
    sections = analysis_sections(result, unit=f"1/{result.time_unit}")
    try:
        return write_html(path, f"skdelay analysis - {result.name}", sections)
    finally:
        _close_all(sections)


def fig_collapse(demo):
    """Rescaled spectra lambda_i tau vs i / tau of every delay (and the exact ones)."""
    from .plotting import plot_lyapunov_spectrum

    plt = _plt()
    fig, ax = plt.subplots(figsize=(7.5, 4.5), layout="constrained")
    spectra, taus = {}, {}
    for delay, res in demo.results.items():
        if delay in demo.spectrum_models:
            sel, spec, tau_time = demo.spectrum_models[delay][:3]
            label = f"tau0 = {delay}: model m = {sel.m}, step {sel.step}"
            spectra[label], taus[label] = spec, tau_time
            continue
        label = f"tau0 = {delay}: model m = {res.m}"
        spectra[label], taus[label] = res.spectrum, res.delay * res.sample_dt
    plot_lyapunov_spectrum(spectra, tau=taus, rescaled=True, ax=ax)
    colors = {lab.split(":")[0]: line.get_color() for line in ax.lines
              if (lab := line.get_label()) in spectra}
    exact, exact_tau = {}, {}
    for delay, res in demo.results.items():
        if delay in demo.exact:
            exact[f"tau0 = {delay}: exact"] = demo.exact[delay]
            exact_tau[f"tau0 = {delay}: exact"] = res.delay * res.sample_dt
    if exact:
        plot_lyapunov_spectrum(exact, tau=exact_tau, rescaled=True, ax=ax)
        for line in ax.lines:
            lab = line.get_label()
            if lab in exact:
                line.set_color(colors.get(lab.split(":")[0], "k"))
                line.set_marker("")
                line.set_linestyle("--")
    ax.legend(fontsize=7)
    ax.set_title("rescaled Lyapunov spectra: lambda_i tau against i / tau")
    return fig


def write_demo_report(demo, path):
    """Write the demo's report: the paper's table, the collapse, then every analysis."""
    if demo.spectrum_models:
        which = ("the local linear model chosen from the data alone at the estimated delay "
                 "(model step, window, neighbours and ridge by time-series cross-validation "
                 "of free runs; the column 'spectrum model' below, and the 'range' columns: "
                 "the values over every setting whose cross-validated error is within one "
                 "standard error of the best, which the data cannot tell apart)")
    else:
        m_max = max(res.m for res in demo.results.values())
        which = f"the local linear model with m = {m_max} at the estimated delay"
    sections = [
        ("The paper's table on the laser-like data",
         [(f"<p>Exponents and entropies in {html.escape(demo.unit)}. <em>paper</em>: Bünner "
           "et al. (CO<sub>2</sub> laser experiment); <em>exact</em>: "
           f"{html.escape(demo.exact_note)}; <em>this model</em>: {html.escape(which)}. "
           "'&gt;=' marks a lower bound (the spectrum was "
           "too short to close the Kaplan-Yorke sum).</p>"), demo.comparison,
          ("<p>Model details (delay estimate, minimal faithful window length m_d, and the "
           "neighbours and ridge of the m_d models, chosen by time-series cross-validation "
           "of forecasts):</p>"),
          demo.table]),
        ("Delay estimates per m (the paper's second table)",
         [("<p>Dip centre +- error in samples (1 sample = 1 us), and the strongest "
           "revivals of the autocorrelation and the mutual information.</p>"),
          demo.delay_table]),
        ("Cross-prediction errors (the paper's third table)",
         [("<p>chi(X, Y): forecasts of the data X from a model run Y as database (local "
           "constant, 5 + 5 dimensions); row O: the data's own error chi(X, X).</p>"),
          demo.cross_prediction]),
        ("Rescaled-spectrum collapse", [_safe(fig_collapse, demo)]),
    ]
    if demo.takens is not None:
        sections.insert(1, (
            f"Takens cross-check at tau0 = {demo.takens_delay} (the paper's Sec. III)",
            [(f"<p>{html.escape(demo.takens_sentence)} Largest exponents in "
              f"{html.escape(demo.unit)}; Kantz's method on delay embeddings with lag "
              f"{demo.takens.lag} spanning one to two delays; D2 from the Poincaré section "
              "of maxima before and after local projective noise reduction (10 "
              "iterations).</p>"), demo.takens_table]))
    for delay, res in demo.results.items():
        sections += analysis_sections(res, scale=demo.scale, unit=demo.unit,
                                      prefix=f"tau0 = {delay}: ")
    try:
        return write_html(path, "skdelay demo - delayed-feedback laser", sections)
    finally:
        _close_all(sections)
