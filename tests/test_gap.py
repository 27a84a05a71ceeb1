"""diagnose_gap on Mackey-Glass data carrying one withheld effect (short series, few seeds).

Each case hides one effect of moderate strength in a simulator run, lets
``diagnose_gap`` rank every registered effect, and checks that the right one
comes first with parameters within 20 % (hum frequency within one spectral
bin, delay within one sample), that it removes most of the gap, and that the
localisation table points at the right place.  The seeds and strengths here
differ from those of benchmarks/gap_withheld.py.
"""

import numpy as np
import pytest

from skdelay.gap import GapReport, diagnose_gap, get_effect
from skdelay.systems import MackeyGlass

N = 8000
MG = MackeyGlass()
_CACHE = {}


def make_real(effect, params, seed, n=N):
    eff = get_effect(effect)
    if effect == "timebase_mismatch":  # a real clock: the record sampled at the true step
        return MG.simulate(n, sample_dt=params["factor"], random_state=seed)
    if eff.target == "simulation":
        return MG.simulate(n, random_state=seed, **eff.overrides(params, MG))
    x = MG.simulate(int(n * params.get("factor", 1.0)) + 2, random_state=seed)
    return eff.apply(x, params, sample_dt=1.0, random_state=seed + 1)[:n]


def report(effect, params, seed, **kw):
    key = (effect, tuple(sorted(params.items())), seed, tuple(kw.get("effects") or ()))
    if key not in _CACHE:
        real = MG.simulate(N, random_state=seed) if effect is None else make_real(
            effect, params, seed)
        _CACHE[key] = (real, diagnose_gap(real, MG, random_state=seed % 97, n_jobs=2,
                                          combine=False, **kw))
    return _CACHE[key]


def fitted(rep, name):
    return rep.effects.set_index("effect").loc[name, "params"]


def assert_explained(rep, name):
    assert rep.best_effect == name, rep.effects[["effect", "gap_after", "shrink"]]
    assert rep.effects.effect.iloc[0] == name
    assert rep.significance["significant"]
    assert rep.effects.shrink.iloc[0] >= 0.7
    assert rep.shrink == pytest.approx(rep.effects.shrink.iloc[0])


# ------------------------------------------------------------------ withheld effects
def test_hum_found_with_frequency_and_localised():
    f0, amp = 0.0831, 0.06
    _, rep = report("periodic_interference", {"frequency": f0, "amplitude": amp, "phase": 0.4},
                    seed=2101)
    assert_explained(rep, "periodic_interference")
    p = fitted(rep, "periodic_interference")
    bin_width = 1.0 / 1024
    assert abs(p["frequency"] - f0) < bin_width
    assert p["amplitude"] == pytest.approx(amp, rel=0.2)
    spec = rep.where[rep.where.indicator == "spectrum"]
    assert ((spec.low <= f0) & (spec.high >= f0)).any(), spec
    rows = spec[(spec.low <= f0) & (spec.high >= f0)]
    # the Welch bin and the whole-record line (a row of its own since the line search)
    assert rows.z.max() > 10 and (rows.unit == "cycles per time unit").all()
    assert "spectral line" in set(rows.feature)
    # the fitted hum removes the line: nothing left at f0 after the best effect
    res = rep.residual_where
    assert not ((res.indicator == "spectrum") & (res.low <= f0) & (res.high >= f0)).any()


def test_report_summary_plot_and_html(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    _, rep = report("periodic_interference",
                    {"frequency": 0.0831, "amplitude": 0.06, "phase": 0.4}, seed=2101)
    assert isinstance(rep, GapReport)
    text = rep.summary()
    assert "periodic_interference" in text and "cycles per time unit" in text
    assert "removes" in text and "%" in text
    for col in ("effect", "params", "gap_before", "gap_after", "shrink", "status"):
        assert col in rep.effects.columns
    assert (rep.effects.gap_before == rep.gap_before).all()
    ok = rep.effects[rep.effects.status == "ok"]
    assert np.allclose(ok.shrink, 1 - ok.gap_after.clip(lower=0) / ok.gap_before)
    assert list(ok.gap_after) == sorted(ok.gap_after)
    for col in ("indicator", "low", "high", "excess"):
        assert col in rep.where.columns
    assert list(rep.where.excess) == sorted(rep.where.excess, reverse=True)
    fig = rep.plot()
    assert len([ax for ax in fig.axes if ax.get_visible()]) >= 5
    path = rep.to_html(tmp_path / "gap" / "report.html")
    page = path.read_text()
    assert page.startswith("<!DOCTYPE html>") and "data:image/png;base64," in page
    assert "periodic_interference" in page
    assert not list((tmp_path / "gap").glob(".*.tmp"))


def test_clipping_found_and_localised_at_the_clipped_end():
    real, rep = report("clipping", {"low": -np.inf, "high": 1.4}, seed=2202)
    assert_explained(rep, "clipping")
    p = fitted(rep, "clipping")
    assert p["high"] == pytest.approx(1.4, rel=0.2) and not np.isfinite(p["low"])
    hist = rep.where[rep.where.indicator == "histogram"]
    top = real.max()
    assert ((hist.high >= top - 0.02 * real.std()) & (hist.low <= top + 0.5 * real.std())).any()
    assert "saturates above" in rep.summary()


def test_parameter_drift_found_and_localised_late():
    _, rep = report("parameter_drift", {"parameter": "b", "start": 0.1, "end": 0.114},
                    seed=2303)
    assert_explained(rep, "parameter_drift")
    p = fitted(rep, "parameter_drift")
    assert p["parameter"] == "b"
    assert p["end"] - p["start"] == pytest.approx(0.014, rel=0.2)
    seg = rep.where[rep.where.indicator == "segment"]
    assert len(seg)
    # the segments deviate most at the end of the record (the drift started at the model's b)
    assert seg.iloc[0].peak >= 0.75 * N and seg.iloc[0].high == N


def test_delay_mismatch_found_and_dip_shift_localised():
    _, rep = report("delay_mismatch", {"tau": 19.0}, seed=2404)
    assert_explained(rep, "delay_mismatch")
    assert abs(fitted(rep, "delay_mismatch")["tau"] - 19.0) <= 1.0
    dip = rep.where[(rep.where.indicator == "forecast_error")
                    & (rep.where.feature == "dip position")]
    assert len(dip) == 1
    row = dip.iloc[0]
    assert row.sim_value == pytest.approx(17.0, abs=1.0)
    assert row.real_value == pytest.approx(19.0, abs=1.0)
    assert row.low < row.high and "delay differs" in row.note


# The cases below rank the withheld effect against its plausible confusers only (the full
# ranking of every effect is exercised above and in benchmarks/gap_withheld.py).
NOISES = ["measurement_noise", "dynamical_noise", "outliers", "quantization", "lowpass",
          "periodic_interference"]


@pytest.mark.parametrize("effect, params, seed, check, candidates", [
    ("measurement_noise", {"noise": 0.04}, 2505, {"noise": 0.04}, NOISES),
    ("quantization", {"step": 0.06, "phase": 0.6}, 2606, {"step": 0.06}, NOISES),
    ("lowpass", {"cutoff": 0.06}, 2707, {"cutoff": 0.06},
     ["lowpass", "timebase_mismatch", "measurement_noise", "dynamical_noise", "clipping"]),
    ("dynamical_noise", {"dynamical_noise": 0.008}, 2909, {"dynamical_noise": 0.008},
     ["dynamical_noise", "measurement_noise", "outliers", "lowpass", "quantization"]),
])
def test_withheld_effect_ranked_first_with_parameters(effect, params, seed, check, candidates):
    _, rep = report(effect, params, seed, effects=candidates)
    assert_explained(rep, effect)
    p = fitted(rep, effect)
    for key, value in check.items():
        assert p[key] == pytest.approx(value, rel=0.2), (key, p)


def test_outliers_rate_and_size():
    real, rep = report("outliers", {"rate": 0.006, "size": 7.0}, 2808,
                       effects=["outliers", "measurement_noise", "quantization", "clipping",
                                "periodic_interference"])
    assert_explained(rep, "outliers")
    p = fitted(rep, "outliers")
    clean = MG.simulate(N, random_state=2808)
    hit = real != clean  # the spikes are random: compare with the realised ones
    assert p["rate"] == pytest.approx(hit.mean(), rel=0.2)
    assert p["size"] == pytest.approx(np.median(np.abs(real - clean)[hit]) / clean.std(), rel=0.2)
    assert p["size"] == pytest.approx(7.0, rel=0.2)


def test_timebase_mismatch_factor():
    _, rep = report("timebase_mismatch", {"factor": 1.08}, seed=3010,
                    effects=["timebase_mismatch", "delay_mismatch", "lowpass", "parameter_drift"])
    assert_explained(rep, "timebase_mismatch")
    assert fitted(rep, "timebase_mismatch")["factor"] - 1 == pytest.approx(0.08, rel=0.2)


def test_no_effect_control_is_not_significant():
    _, rep = report(None, {}, seed=3111)
    assert rep.best_effect is None
    assert not rep.significance["significant"]
    assert rep.gap_before < rep.significance["threshold"]
    assert "indistinguishable" in rep.summary()


# ------------------------------------------------------------------ model vs data
class ModelSimulator:
    """Adapter: a fitted two-window model run by ``iterate`` as a simulator.

    Each seed starts the free run from another segment of the training data.
    """

    def __init__(self, model, data, tau):
        self.model, self.data = model, data
        self.params = {"tau": float(tau)}

    def simulate(self, n_samples, *, sample_dt=1.0, random_state=None, dynamical_noise=0.0,
                 **overrides):
        from skdelay.dynamics import iterate

        rng = np.random.default_rng(random_state)
        tau = round(float(overrides.pop("tau", self.params["tau"])))
        if overrides:
            raise TypeError(f"the model has no parameters {sorted(overrides)}")
        start = rng.integers(0, len(self.data) - 200)
        run = iterate(self.model, self.data[start:start + 100], n_samples + 300, tau=tau,
                      noise=dynamical_noise, random_state=int(rng.integers(2**31)),
                      on_escape="raise")
        return np.asarray(run)[300:]


def test_model_versus_data_with_hum_finds_the_hum():
    """The paper's situation: a model fitted on clean data, data with a 50 Hz-like hum."""
    from sklearn.pipeline import make_pipeline

    from skdelay._embedding import TwoWindowEmbedding
    from skdelay._local_linear import LocalLinearDelayMap
    from skdelay._windows import lagged_windows

    train = MG.simulate(12000, random_state=3212)
    X, y = lagged_windows(train, n_lags=20)
    model = make_pipeline(TwoWindowEmbedding(m=3, tau=17),
                          LocalLinearDelayMap(n_neighbors=20)).fit(X, y)
    sim = ModelSimulator(model, train, 17)
    f0 = 0.1
    real = get_effect("periodic_interference").apply(
        MG.simulate(N, random_state=3213), {"frequency": f0, "amplitude": 0.05, "phase": 0.0})
    rep = diagnose_gap(real, sim, random_state=5, combine=False,
                       effects=["periodic_interference", "measurement_noise", "dynamical_noise",
                                "outliers", "lowpass", "quantization"])
    assert rep.best_effect == "periodic_interference"
    assert abs(fitted(rep, "periodic_interference")["frequency"] - f0) < 1.0 / 1024
    spec = rep.where[rep.where.indicator == "spectrum"]
    assert ((spec.low <= f0) & (spec.high >= f0)).any()


# ------------------------------------------------------------------ failures and errors
class FragileMG:
    """Mackey-Glass that diverges whenever the delay is changed."""

    params = MG.params

    def simulate(self, n_samples, *, sample_dt=1.0, random_state=None, **overrides):
        if "tau" in overrides:
            raise FloatingPointError("integration diverged")
        return MG.simulate(n_samples, sample_dt=sample_dt, random_state=random_state,
                           **overrides)


def test_failing_candidate_is_reported_and_others_go_on():
    real = make_real("measurement_noise", {"noise": 0.05}, seed=3314)
    rep = diagnose_gap(real, FragileMG(), effects=["delay_mismatch", "measurement_noise"],
                       random_state=1, combine=False)
    table = rep.effects.set_index("effect")
    assert table.loc["delay_mismatch", "status"] == "failed"
    assert "diverged" in table.loc["delay_mismatch", "reason"]
    assert table.loc["measurement_noise", "reason"] == ""
    assert np.isnan(table.loc["delay_mismatch", "gap_after"])
    assert rep.effects.effect.iloc[-1] == "delay_mismatch"
    assert rep.best_effect == "measurement_noise"


def test_input_errors():
    x = MG.simulate(3000, random_state=0)
    bad = x.copy()
    bad[10] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        diagnose_gap(bad, MG)
    with pytest.raises(ValueError, match="shorter than the simulator's delay"):
        diagnose_gap(x, MackeyGlass(tau=4000.0))
    with pytest.raises(ValueError, match="at least"):
        diagnose_gap(x[:1500], MG)
    with pytest.raises(ValueError, match="unknown effect 'hum'"):
        diagnose_gap(x, MG, effects=["hum"])
    with pytest.raises(TypeError, match="simulate"):
        diagnose_gap(x, object())
