"""``skdelay analyze`` end to end on 10^6 points: wall time per stage and the longest silence.

Run (prints every command, the load average and the table)::

    python benchmarks/analyze_scale.py [--n 1000000] [--n-jobs J] [--baseline REV]
                                       [--tau-max T] [--data-dir DIR]

The data are made by the CLI itself: noisy 12-bit Mackey-Glass with delay 100
(``skdelay simulate mackey_glass --n N --param tau=100 --noise 0.01 --bits 12
--seed 0``), cached in ``--data-dir``.  Then ``skdelay analyze FILE --out DIR
--force`` runs in a subprocess; its stderr (the progress lines and tqdm bars)
is passed through and time-stamped, so the table also gives the longest gap
between two progress outputs ("silence").  The stage times come from
``results.json`` (``timings_s``): correlations, delay scan, and the model
stage split into free runs, Lyapunov spectra and the rest (model fits, noise
level, histogram / spectrum / cross-prediction distances); "write" is the
CLI's wall time minus the analysis (reading, results and report).

The model stage does not grow with the record: it works on the last
``N_VALIDATION = 2e5`` samples and takes spectra along ``1e5`` steps, so
``--n 200000 --tau-max 120`` (a short scan) times it in a few minutes.
``--baseline REV`` runs the same command with the package as of git revision
``REV`` (``git archive`` into a temporary directory, run from there) right
after the current one; its model stage is only timed as a whole.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _revision import export_package

ROOT = Path(__file__).resolve().parents[1]
SIMULATE = ["mackey_glass", "--param", "tau=100", "--noise", "0.01", "--bits", "12",
            "--seed", "0"]


def _skdelay(*args):
    return [sys.executable, "-m", "skdelay", *map(str, args)]


def _data(n, data_dir):
    path = Path(data_dir) / f"mackey_glass_tau100_n{n}.npy"
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        cmd = _skdelay("simulate", *SIMULATE, "--n", n, "-o", path)
        print("data:    " + shlex.join(cmd[2:]), flush=True)
        subprocess.run(cmd, check=True, cwd=ROOT)
    return path


def run_analyze(path, out, extra, src=None, echo=True):
    """Run the CLI; return (wall seconds, results dict, longest silence, text before it).

    ``src``: a directory holding another ``skdelay`` package to run instead (it is
    the working directory, so ``python -m skdelay`` imports that one).
    """
    cmd = _skdelay("analyze", Path(path).resolve(), "--out", Path(out).resolve(), "--force",
                   *extra)
    print(f"command (in {src or ROOT}): " + shlex.join(cmd[2:]), flush=True)
    t0 = last = time.perf_counter()
    gap, gap_after, tail = 0.0, "", b""
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, stdout=subprocess.PIPE,
                            cwd=src or ROOT)
    fd = proc.stderr.fileno()
    while True:
        chunk = os.read(fd, 65536)
        now = time.perf_counter()
        if not chunk:
            break
        if now - last > gap:
            gap, gap_after = now - last, tail.decode(errors="replace").strip()[-100:]
        last, tail = now, (tail + chunk)[-300:]
        if echo:
            sys.stderr.write(chunk.decode(errors="replace"))
            sys.stderr.flush()
    stdout = proc.stdout.read().decode()
    if proc.wait() != 0:
        raise RuntimeError(f"skdelay analyze failed:\n{stdout}")
    wall = time.perf_counter() - t0
    results = json.loads((Path(out) / "results.json").read_text())
    return wall, results, gap, gap_after.replace("\r", " | ")


def _table(wall, results):
    t = results["timings_s"]
    rows = [("correlations", t.get("correlations")), ("delay scan", t.get("delay_scan")),
            ("free runs", t.get("free_runs")), ("Lyapunov spectra", t.get("spectra")),
            ("fits + validation", t.get("fits_and_validation")),
            ("(model stage total)", t.get("models")),
            ("write (read, json, report)", wall - t["total"]),
            ("analyze end to end", wall)]
    return rows


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1_000_000)
    parser.add_argument("--n-jobs", type=int, default=None)
    parser.add_argument("--tau-max", type=int, default=None)
    parser.add_argument("--baseline", default=None, metavar="REV")
    parser.add_argument("--data-dir", default=os.path.join(tempfile.gettempdir(),
                                                           "skdelay-bench"))
    parser.add_argument("--no-echo", action="store_true", help="do not pass stderr through")
    args = parser.parse_args(argv)
    print("command: python benchmarks/analyze_scale.py " + " ".join(sys.argv[1:] if argv is None
                                                                     else argv))
    print(f"{os.cpu_count()} cores; load average at start {os.getloadavg()[0]:.2f}", flush=True)
    path = _data(args.n, args.data_dir)
    extra = [] if args.n_jobs is None else ["--n-jobs", args.n_jobs]
    if args.tau_max is not None:
        extra += ["--tau-max", args.tau_max]
    runs = {}
    with tempfile.TemporaryDirectory() as tmp:
        runs["current"] = run_analyze(path, Path(tmp) / "current", extra,
                                      echo=not args.no_echo)
        print(f"load average after the current run {os.getloadavg()[0]:.2f}", flush=True)
        if args.baseline:
            src = Path(tmp) / "baseline_src"
            src.mkdir()
            export_package(args.baseline, str(src))
            runs["baseline"] = run_analyze(path, Path(tmp) / "baseline", extra, src=src,
                                           echo=not args.no_echo)
            print(f"load average after the baseline run {os.getloadavg()[0]:.2f}")
    print(f"load average at end {os.getloadavg()[0]:.2f}")
    wall, results, gap, after = runs["current"]
    summary = results["summary"]
    print(f"\n{args.n} samples (Mackey-Glass tau = 100, noise 1 %, 12 bit): delay "
          f"{summary['delay']} +- {summary['delay_error']}, D_KY {summary['D_KY']:.2f}, "
          f"minimal m {summary['minimal_m']}")
    head = f"{'stage':<28} {'wall [s]':>9} {'share':>6}"
    if "baseline" in runs:
        head += f" {'baseline [s]':>13} {'ratio':>6}"
    print(head)
    base_rows = dict(_table(*runs["baseline"][:2])) if "baseline" in runs else {}
    for name, sec in _table(wall, results):
        if sec is None:
            continue
        line = f"{name:<28} {sec:9.1f} {sec / wall:6.1%}"
        b = base_rows.get(name)
        if "baseline" in runs:
            line += (f" {b:13.1f} {b / sec:6.2f}" if b is not None and sec > 0
                     else f" {'-':>13} {'-':>6}")
        print(line)
    print(f"longest silence on stderr: {gap:.1f} s, after: {after[-60:]!r}")
    if "baseline" in runs:
        print(f"baseline: git revision {args.baseline}; longest silence "
              f"{runs['baseline'][2]:.1f} s")


if __name__ == "__main__":
    main()
