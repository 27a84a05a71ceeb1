"""The ``skdelay`` command: analyze, demo, gap and simulate.

A thin shell over :func:`skdelay._analysis.analyze_series`,
:func:`skdelay._demo.run_demo`, :func:`skdelay.gap.diagnose_gap` and the
simulators.  Each subcommand first *prepares* (parses the arguments, reads and
checks the input, checks the output path) and then *runs*; a problem found
while preparing is a usage/input error (exit status 2), one while running is
a failure (exit status 1).  Either way a single line on stderr says what to
fix, and nothing is written: outputs are built in a temporary file or
directory next to the target and renamed into place at the end.  A run killed
with ``kill -9`` leaves only such a hidden ``.NAME.skd<pid>...tmp``, which the
next run into the same directory removes (once its owner process is gone).
Every output directory holds a ``.skdelay-output`` marker, and ``--force``
replaces only directories that have it.
"""

from __future__ import annotations

import argparse
import math
import re
import signal
import sys
import time
from contextlib import contextmanager
from pathlib import Path

from ._atomic import remove_own_temporaries

EXIT_OK, EXIT_FAILURE, EXIT_USAGE = 0, 1, 2
#: shell convention 128 + signal number
EXIT_INTERRUPTED, EXIT_TERMINATED = 130, 143


class _Terminated(BaseException):
    """Raised by the SIGTERM handler so that ``finally`` blocks remove temporaries."""


def _on_sigterm(signum, frame):
    raise _Terminated


@contextmanager
def _sigterm_unwinds():
    """Turn SIGTERM into an exception for the duration of a run (main thread only).

    The default action kills the process on the spot, leaving the hidden
    temporary output behind until the next run; unwinding removes it now.
    """
    try:
        previous = signal.signal(signal.SIGTERM, _on_sigterm)
    except (ValueError, OSError, AttributeError):  # not the main thread / no SIGTERM
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


class UsageError(ValueError):
    """Bad command-line usage or input (exit status 2)."""


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line on stderr and exit status 2."""

    def error(self, message):
        raise UsageError(f"{message} (see `{self.prog} --help`)")


def _one_line(exc):
    if isinstance(exc, KeyError) and exc.args:
        text = str(exc.args[0])
    else:
        text = str(exc) or type(exc).__name__
    return " ".join(text.split())


# --------------------------------------------------------------------- parsing helpers
def _positive_float(text):
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def _nonneg_float(text):
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}") from None
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}")
    return value


def _int_at_least(minimum):
    def parse(text):
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"expected an integer >= {minimum}, got {value}")
        return value

    return parse


#: numpy's legacy seeding (used by sklearn's check_random_state) takes 0 <= seed < 2**32
_MAX_SEED = 2**32 - 1


def _seed(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer seed, got {text!r}") from None
    if not 0 <= value <= _MAX_SEED:
        raise argparse.ArgumentTypeError(
            f"the seed must be between 0 and 2**32 - 1 = {_MAX_SEED}, got {value}")
    return value


def _n_jobs(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected an integer number of workers (-1 = all cores), got {text!r}") from None
    if value == 0:
        # joblib: positive = that many workers, -1 = all cores, -2 = all but one, ...
        raise argparse.ArgumentTypeError(
            "0 workers cannot run anything; use 1 (serial), J > 1, or -1 for all cores")
    return value


def parse_m(text):
    """Parse an embedding-window list: ``"3"``, ``"2,4"`` or ``"2..5"`` -> tuple of ints."""
    text = str(text).strip()
    match = re.fullmatch(r"(\d+)\s*(?:\.\.|-|:)\s*(\d+)", text)
    try:
        if match:
            lo, hi = int(match.group(1)), int(match.group(2))
            values = tuple(range(lo, hi + 1))
        else:
            values = tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--m expects a window length like 3, a list 2,3,5 or a range 2..5; got {text!r}"
        ) from None
    if not values or min(values) < 1 or max(values) > 20:
        raise argparse.ArgumentTypeError(
            f"--m needs window lengths between 1 and 20 (e.g. 2..5); got {text!r}"
        )
    return tuple(sorted(set(values)))


def _parse_delays(text):
    try:
        values = tuple(int(v) for v in str(text).split(",") if v.strip())
    except ValueError:
        values = ()
    if not values:
        raise argparse.ArgumentTypeError(f"expected delays like 50,150,400; got {text!r}")
    return values


def parse_params(items):
    """Parse ``k=v`` pairs: a number, or ``start:end`` for a linear drift."""
    params = {}
    for item in items or ():
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key.isidentifier():
            raise UsageError(f"--param expects NAME=VALUE (e.g. --param tau=30), got {item!r}")
        try:
            if ":" in value:
                start, end = value.split(":", 1)
                params[key] = (float(start), float(end))
            else:
                params[key] = float(value)
        except ValueError:
            raise UsageError(
                f"--param {key} needs a number (or start:end for a drift), got {value!r}"
            ) from None
    return params


# --------------------------------------------------------------------------- parser
def build_parser():
    """Return the argparse parser of the ``skdelay`` command."""
    parser = _Parser(
        prog="skdelay",
        description="Find, model and check systems with delayed feedback from time series.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    common_out = argparse.ArgumentParser(add_help=False)
    common_out.add_argument("--force", action="store_true",
                            help="replace the output directory if it exists and skdelay "
                                 "wrote it (atomically)")
    common_out.add_argument("--quiet", "-q", action="store_true",
                            help="no progress display, only the summary")
    common_out.add_argument("--n-jobs", type=_n_jobs, default=None, metavar="J",
                            help="parallel workers (joblib; -1 = all cores; default: all "
                                 "cores for big scans)")
    common_out.add_argument("--seed", type=_seed, default=0,
                            help="random seed, 0..2**32-1 (default 0)")

    an = sub.add_parser(
        "analyze", parents=[common_out],
        help="delay scan, model, Lyapunov spectrum, validation and report for one series",
        description="Run the two-window analysis of one time series and write results and "
                    "an HTML report to --out.",
    )
    an.add_argument("file", metavar="FILE", help=".npy, .csv/.txt/.dat or .parquet file")
    an.add_argument("--column", "-c", default=None,
                    help="column name or 0-based index (needed when the file has several)")
    an.add_argument("--dt", type=_positive_float, default=None,
                    help="sampling interval in your time unit (default: the step in seconds "
                         "of the file's time index, if it has one, else 1)")
    an.add_argument("--m", type=parse_m, default=(2, 3, 4, 5), metavar="M",
                    help="window lengths: 3, 2,3,5 or 2..5 (default 2..5)")
    an.add_argument("--tau-min", type=_int_at_least(1), default=1, metavar="N",
                    help="smallest delay of the scan, in samples (default 1)")
    an.add_argument("--tau-max", type=_int_at_least(2), default=None, metavar="N",
                    help="largest delay of the scan in samples (default: from the "
                         "autocorrelation revival, at most 500)")
    an.add_argument("--n-queries", type=_int_at_least(100), default=None, metavar="Q",
                    help="query points per scan cell (default: automatic)")
    an.add_argument("--neighbors", type=_int_at_least(2), default=None, metavar="K",
                    help="neighbours of the local linear models (default: cross-validated, "
                         "or 4 (2 m + 1) with --no-select-model or --quick)")
    an.add_argument("--ridge", type=_positive_float, default=None,
                    help="relative ridge of the local fits (default: cross-validated, or 1e-3 "
                         "with --no-select-model or --quick)")
    an.add_argument("--flow", action="store_true",
                    help="the data sample a continuous-time flow: pin one exponent to zero")
    an.add_argument("--time-unit", default="time unit", metavar="NAME",
                    help="name of the unit of --dt used in every label, e.g. us or s")
    an.add_argument("--select-model", action=argparse.BooleanOptionalAction, default=None,
                    help="choose each m's neighbours and ridge by time-series cross-validation "
                         "of one-step and iterated forecasts on the series its model is fitted "
                         "on (default: on, off with --quick or when --neighbors/--ridge are "
                         "given; --select-model overrides those)")
    an.add_argument("--step", type=_int_at_least(1), default=None, metavar="H",
                    help="analyse every H-th sample (default: chosen from the data; 1 "
                         "unless the record is oversampled)")
    an.add_argument("--quick", action="store_true",
                    help="smaller query sets, runs and spectra (a preview in seconds)")
    an.add_argument("--out", "-o", default="skdelay-out", metavar="DIR",
                    help="output directory (default skdelay-out)")

    de = sub.add_parser(
        "demo", parents=[common_out],
        help="the paper's analysis on the embedded laser-like data (delays 50, 150, 400)",
        description="Analyse the embedded CO2-laser-like data at the delays 50, 150 and 400 "
                    "and reproduce the paper's table and rescaled-spectrum collapse.",
    )
    de.add_argument("--out", "-o", default="demo-report", metavar="DIR",
                    help="output directory (default demo-report)")
    de.add_argument("--n-samples", type=_int_at_least(2000), default=None, metavar="N",
                    help="samples per data set (default 100000)")
    de.add_argument("--delays", type=_parse_delays, default=None, metavar="D",
                    help="laser data sets to analyse (default 50,150,400)")

    ga = sub.add_parser(
        "gap", parents=[common_out],
        help="diagnose the sim-to-real gap between a recording and a simulator",
        description="Find which effect (noise, quantization, drift, ...) explains the "
                    "difference between REAL and the simulator; write an HTML report.",
    )
    ga.add_argument("real", metavar="REAL", help="the recorded series (file)")
    ga.add_argument("--system", required=True, metavar="NAME",
                    help="simulator name (see `skdelay simulate --list`)")
    ga.add_argument("--param", action="append", default=[], metavar="K=V",
                    help="simulator parameter, repeatable (e.g. --param tau=30)")
    ga.add_argument("--column", "-c", default=None, help="column name or 0-based index")
    ga.add_argument("--dt", type=_positive_float, default=1.0,
                    help="sampling interval of REAL in the simulator's time unit (default 1)")
    ga.add_argument("--effects", default=None, metavar="E1,E2",
                    help="candidate effects, comma separated (default: all registered)")
    ga.add_argument("--out", "-o", default="gap-report", metavar="DIR",
                    help="output directory (default gap-report)")

    si = sub.add_parser(
        "simulate", help="simulate a delay system and write the observed series",
        description="Simulate a delay system (optionally with measurement noise and an ADC) "
                    "and write the series to a .npy or .csv/.txt file.",
    )
    si.add_argument("name", metavar="NAME", nargs="?", help="system name")
    si.add_argument("--list", action="store_true", help="list the systems and their parameters")
    si.add_argument("--n", type=_int_at_least(1), default=None, metavar="N",
                    help="number of samples")
    si.add_argument("--dt", type=_positive_float, default=1.0,
                    help="sampling interval (default 1)")
    si.add_argument("--param", action="append", default=[], metavar="K=V",
                    help="parameter, repeatable; K=a:b drifts linearly from a to b")
    si.add_argument("--noise", type=_nonneg_float, default=0.0, metavar="S",
                    help="measurement noise std relative to the signal std (default 0)")
    si.add_argument("--bits", type=_int_at_least(1), default=None, metavar="B",
                    help="quantise with a B-bit ADC over the signal range")
    si.add_argument("--dynamical-noise", type=_nonneg_float, default=0.0, metavar="S",
                    help="dynamical noise strength (default 0)")
    si.add_argument("--seed", type=_seed, default=0, help="random seed, 0..2**32-1 (default 0)")
    si.add_argument("-o", "--output", default=None, metavar="FILE",
                    help="output file (.npy, .csv or .txt)")
    si.add_argument("--force", action="store_true", help="overwrite FILE if it exists")
    return parser


def _version():
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("skdelay")
    except PackageNotFoundError:  # pragma: no cover - not installed
        return "unknown"


# ------------------------------------------------------------------------- commands
def _progress(args):
    start = time.perf_counter()

    def say(message):
        if not args.quiet:  # elapsed time: the stages' durations show in the log
            print(f"[skdelay {time.perf_counter() - start:6.1f} s] {message}", file=sys.stderr,
                  flush=True)

    return say


def _prepare_analyze(args):
    from . import _analysis
    from ._checks import resolve_sample_dt
    from ._io import check_output_directory, read_series

    check_output_directory(args.out, force=args.force)
    series = read_series(args.file, args.column)
    # a regular time index gives the step in seconds; an irregular one is an input error
    args.dt = resolve_sample_dt(series, args.dt)
    options = _analysis.check_options(
        series.to_numpy(), m=args.m, tau_min=args.tau_min, tau_max=args.tau_max,
        sample_dt=args.dt, n_queries=args.n_queries,
    )

    def run():
        say = _progress(args)
        start = time.perf_counter()
        result = _analysis.analyze_series(
            series.to_numpy(), **options, quick=args.quick, n_jobs=args.n_jobs,
            n_neighbors=args.neighbors, ridge=args.ridge, flow=args.flow,
            **({} if args.select_model is None else {"select_model": args.select_model}),
            step=args.step, time_unit=args.time_unit,
            random_state=args.seed,
            verbose=0 if args.quiet else 10, progress=say,
            name=f"{Path(args.file).name}" + (f" [{series.name}]" if args.column else ""),
        )
        say("writing results and report")
        result.save(args.out, force=args.force)
        print(result.summary())
        print(f"results in {args.out}/ (report.html) - {time.perf_counter() - start:.0f} s")

    return run


def _prepare_demo(args):
    from . import _demo
    from ._io import check_output_directory
    from .datasets import LASER_DELAYS

    check_output_directory(args.out, force=args.force)
    delays = args.delays or LASER_DELAYS
    unknown = [d for d in delays if d not in LASER_DELAYS]
    if unknown:
        raise UsageError(f"no embedded laser data for delay(s) {unknown}; choose from "
                         f"{', '.join(map(str, LASER_DELAYS))}")
    need = 20 * (max(delays) + 20)
    if args.n_samples is not None and args.n_samples < need:
        raise UsageError(f"--n-samples {args.n_samples} is too short for the delay "
                         f"{max(delays)}; use at least {need}")

    def run():
        say = _progress(args)
        start = time.perf_counter()
        demo = _demo.run_demo(
            delays=delays, n_samples=args.n_samples, n_jobs=args.n_jobs,
            random_state=args.seed, verbose=0 if args.quiet else 10, progress=say,
        )
        say("writing results and report")
        demo.save(args.out, force=args.force)
        print(demo.summary())
        print(f"results in {args.out}/ (report.html) - {time.perf_counter() - start:.0f} s")

    return run


def _system(name, params):
    from .systems import get_system

    overrides = {k: v for k, v in params.items() if isinstance(v, tuple)}
    fixed = {k: v for k, v in params.items() if not isinstance(v, tuple)}
    try:
        system = get_system(name, **fixed)
        for end in (0, 1):  # both ends of a drift must be valid parameter sets
            if overrides:
                get_system(name, **fixed, **{k: v[end] for k, v in overrides.items()})
    except (KeyError, TypeError, ValueError) as exc:
        raise UsageError(_one_line(exc)) from exc
    return system, overrides


def _prepare_gap(args):
    from ._io import check_output_directory, read_series

    check_output_directory(args.out, force=args.force)
    system, drift = _system(args.system, parse_params(args.param))
    if drift:
        raise UsageError("gap compares against a fixed simulator; give --param K=V without a "
                         "start:end drift")
    real = read_series(args.real, args.column, min_length=2)
    try:  # the simulator must be able to produce a series like REAL (delay resolution, ...)
        system.check_simulation(real.size, sample_dt=args.dt)
    except (TypeError, ValueError) as exc:
        raise UsageError(_one_line(exc)) from exc
    effects = None
    if args.effects:
        from .gap import EFFECTS

        effects = [e.strip() for e in args.effects.split(",") if e.strip()]
        unknown = [e for e in effects if e not in EFFECTS]
        if unknown:
            raise UsageError(f"unknown effect(s) {', '.join(unknown)}; choose from "
                             f"{', '.join(sorted(EFFECTS))}")

    def run():
        from ._io import atomic_directory, write_json
        from .gap import diagnose_gap

        say = _progress(args)
        say(f"diagnosing the gap between {args.real} and {system!r}")
        try:
            # a tqdm bar with ETA over the candidate fits (joblib's own lines would break it)
            report = diagnose_gap(real.to_numpy(), system, sample_dt=args.dt, effects=effects,
                                  random_state=args.seed, n_jobs=args.n_jobs,
                                  progress=not args.quiet)
        except (ValueError, TypeError) as exc:  # documented: input problems
            raise UsageError(_one_line(exc)) from exc
        summary = report.summary()
        with atomic_directory(args.out, force=args.force) as tmp:
            report.to_html(tmp / "report.html")
            report.effects.to_csv(tmp / "effects.csv", index=False)
            report.where.to_csv(tmp / "where.csv", index=False)
            (tmp / "summary.txt").write_text(summary + "\n", encoding="utf-8")
            write_json(tmp / "results.json", {
                "real": str(args.real), "system": system.name, "params": system.params,
                "sample_dt": args.dt, "best_effect": report.best_effect,
            }, reasons={"best_effect": (
                "; ".join(["no candidate effect explains the gap", *report.reasons])
                if report.significance["significant"] else
                "real and simulated data are indistinguishable within the sim-vs-sim spread")})
        print(summary)
        print(f"report in {args.out}/report.html")

    return run


def _list_systems():
    from .systems import SYSTEMS

    lines = []
    for name, cls in SYSTEMS.items():
        defaults = cls().params
        lines.append(f"{name}: " + ", ".join(f"{k}={v:g}" for k, v in defaults.items()))
    return "\n".join(lines)


def _prepare_simulate(args):
    from ._atomic import check_writable, clean_stale_temporaries

    if args.list:
        return lambda: print(_list_systems())
    if args.name is None:
        raise UsageError("simulate needs a system NAME (see `skdelay simulate --list`)")
    if args.n is None:
        raise UsageError("simulate needs --n N, the number of samples")
    if args.output is None:
        raise UsageError("simulate needs -o FILE (.npy, .csv or .txt)")
    out = Path(args.output)
    if out.suffix.lower() not in {".npy", ".csv", ".txt", ".dat"}:
        raise UsageError(f"-o {out}: name the output *.npy, *.csv or *.txt")
    if out.is_dir():
        raise UsageError(f"{out} is a directory; give a file name")
    if out.exists() and not args.force:
        raise UsageError(f"{out} exists; choose another -o FILE or pass --force to overwrite it")
    if args.bits is not None and args.bits > 32:
        raise UsageError(f"--bits {args.bits} is more than a real ADC has; use 8..24")
    system, drift = _system(args.name, parse_params(args.param))
    if args.n > 50_000_000:
        raise UsageError(f"--n {args.n} is too many samples for one file; use at most 5e7")
    try:
        # every check simulate() makes (delay resolution, drift ends, ...) before any work
        system.check_simulation(args.n, sample_dt=args.dt,
                                dynamical_noise=args.dynamical_noise, **drift)
        check_writable(out, what="-o")
    except (TypeError, ValueError) as exc:
        raise UsageError(_one_line(exc)) from exc
    clean_stale_temporaries(out.absolute().parent)  # leftovers of killed runs

    def run():
        from ._io import write_series
        from .systems import DivergenceError, measure

        try:
            x = system.simulate(args.n, sample_dt=args.dt, random_state=args.seed,
                                dynamical_noise=args.dynamical_noise, **drift)
        except DivergenceError as exc:  # the parameters given are the thing to change
            raise UsageError(_one_line(exc)) from exc
        if args.noise > 0 or args.bits is not None:
            x = measure(x, noise=args.noise, bits=args.bits, normalise=False,
                        random_state=(args.seed + 1) % (_MAX_SEED + 1))
        comment = (f"skdelay simulate {system!r} n={args.n} sample_dt={args.dt} "
                   f"noise={args.noise} bits={args.bits} seed={args.seed}")
        write_series(out, x, name=system.name, comment=comment)
        print(f"wrote {args.n} samples of {system.name} to {out}", file=sys.stderr)

    return run


_COMMANDS = {
    "analyze": _prepare_analyze,
    "demo": _prepare_demo,
    "gap": _prepare_gap,
    "simulate": _prepare_simulate,
}


def main(argv=None):
    """Entry point of the ``skdelay`` console script; returns the exit status.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        0 on success, 2 for bad usage or input, 1 when the computation failed.

    Examples
    --------
    >>> from skdelay.cli import main
    >>> main(["simulate", "--list"]) == 0  # doctest: +ELLIPSIS
    mackey_glass: ...
    True
    """
    parser = build_parser()
    prog = "skdelay"
    try:
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help(sys.stderr)
            return EXIT_USAGE
        prog = f"skdelay {args.command}"
        run = _COMMANDS[args.command](args)
    except SystemExit as exc:  # --help / --version
        return int(exc.code or 0)
    except (UsageError, ValueError, TypeError, KeyError, OSError) as exc:
        print(f"{prog}: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_USAGE
    try:
        with _sigterm_unwinds():
            run()
    except KeyboardInterrupt:
        remove_own_temporaries()
        print(f"{prog}: interrupted; nothing was written", file=sys.stderr)
        return EXIT_INTERRUPTED
    except _Terminated:
        remove_own_temporaries()  # one created just before the signal may not be unwound
        print(f"{prog}: terminated; nothing was written", file=sys.stderr)
        return EXIT_TERMINATED
    except UsageError as exc:
        print(f"{prog}: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_USAGE
    except Exception as exc:  # noqa: BLE001 - the CLI reports every failure in one line
        print(f"{prog}: failed: {type(exc).__name__}: {_one_line(exc)}", file=sys.stderr)
        return EXIT_FAILURE
    return EXIT_OK


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
