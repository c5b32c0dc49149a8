"""Running a fleet: the settings, the one call that calibrates a recording, and the Snakemake
workflow (``gmwm/data/fleet.smk``) that calls it for every recording and then builds the table.

Layout of ``OUT``::

    OUT/units/<unit>/<recording>/   the recording's report, configuration files, report.json
                                    (the report's --json), status.json (the fleet job's verdict)
    OUT/fleet.{json,csv,md,html}, OUT/fleet_summary.csv   the fleet table (gmwm.fleet.output)
    OUT/.fleet/settings.json        the settings every job uses
    OUT/.fleet/config.json          the recordings (path, content hash, topic, datasheet, date)
                                    by key, and the settings' hash
    OUT/.fleet/snakemake.log        Snakemake's output, one part per run

Incremental: a job's params are its recording's content hash and the settings' hash, and
Snakemake reruns on params and inputs only (not time stamps): a new or changed recording reruns its
job and the table; a changed setting reruns everything; an unchanged run (or a touched file) does
nothing. Resumable: a killed run is rerun with the same command (stale Snakemake locks of a
dead run are removed under an OS lock, as workflow/rules/runlock.smk does for the pipeline).
"""

from __future__ import annotations

import datetime as _dt
import fcntl
import hashlib
import json
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from gmwm.atomic import write_json_atomic, write_text_atomic
from gmwm.errors import GMWMError, InputError
from gmwm.fleet.collect import Recording, content_hash

__all__ = ["MIN_STATIC_S", "FleetSettings", "calibrate_recording", "prepare", "run_workflow",
           "workflow_file"]

#: the shortest static stretch the fleet calibrates [s]: below it the recording is listed as
#: failed. 60 s holds ~2^12 samples at 100 Hz, enough for the white-noise densities' intervals
#: but not for random walks (the plan rule then says so term by term).
MIN_STATIC_S = 60.0
#: the line that starts each run's part of OUT/.fleet/snakemake.log
RUN_MARK = "#### gmwm fleet run"


@dataclass(frozen=True)
class FleetSettings:
    """What every recording is calibrated with (``gmwm report`` options) and how the table is
    built. Part of every job's inputs: changing any of them reruns the whole fleet."""

    model: str = "auto"
    columns: str | None = None
    units: tuple[str, ...] = ()
    freq: float | None = None
    topic: str | None = None
    datasheet: str | None = None
    export: str = "kalibr,json"
    min_static_s: float = MIN_STATIC_S
    method_re: str = "pm"
    report_args: tuple[str, ...] = ()

    def report_argv(self, path: str, outdir: str, topic: str | None = None,
                    datasheet: str | None = None) -> list[str]:
        """The ``gmwm report`` command line for one recording (the fleet's defaults: the longest
        static stretch, the json export for the table, --json for the verdicts)."""
        export = self.export if "json" in self.export.split(",") or self.export == "all" \
            else self.export + ",json"
        argv = ["report", path, self.model, "-o", outdir, "--json", "--quiet",
                "--segment", "longest-static", "--export", export]
        if self.columns:
            argv += ["--columns", self.columns]
        for u in self.units:
            argv += ["--units", u]
        if self.freq is not None:
            argv += ["--freq", repr(self.freq)]
        topic = topic or self.topic
        if topic:
            argv += ["--topic", topic]
        sheet = datasheet or self.datasheet
        if sheet:
            argv += ["--datasheet", sheet]
        return argv + list(self.report_args)

    def to_json(self) -> dict[str, Any]:
        d = asdict(self)
        d["units"], d["report_args"] = list(self.units), list(self.report_args)
        return d


# --------------------------------------------------------------------------------------------------
# one recording
# --------------------------------------------------------------------------------------------------


def _not_identifiable(fits: Mapping[str, Any], notes: list[str]) -> dict[str, dict[str, bool]]:
    """Per axis, per component (WN, RW, ...): True where the ``gmwm plan`` rule at the fitted
    values and the length used says the term is not identifiable. An axis the rule cannot be
    evaluated on gets a line in ``notes`` (its fit's own flags then stand alone)."""
    import numpy as np

    from gmwm.model import as_model
    from gmwm.plan import predict

    out: dict[str, dict[str, bool]] = {}
    for axis, f in fits.items():
        try:
            params = {k: float(v) for k, v in (f.get("params") or {}).items()}
            if any(v <= 0 for k, v in params.items() if not k.startswith(("AR1", "SIN", "GM"))):
                continue  # a term at 0: the fit's own flag says so
            pred = predict(as_model(f["model"], float(f["freq"])), params, int(f["n"]))
        except (GMWMError, ValueError, KeyError, TypeError, ArithmeticError,
                np.linalg.LinAlgError) as exc:
            notes.append(f"{axis}: identifiability at this length not checked ({exc})")
            continue
        out[axis] = {name.split("[")[0]: not ok for name, ok in pred.identifiable.items()}
    return out


def calibrate_recording(path: str | Path, outdir: str | Path, settings: FleetSettings, *,
                        report: Callable[[list[str]], tuple[int, dict[str, Any] | None, str]],
                        topic: str | None = None, datasheet: str | None = None,
                        content: str | None = None) -> dict[str, Any]:
    """Calibrate one recording into ``outdir`` exactly as ``gmwm report`` would (same defaults,
    same refusals; the longest static stretch), then judge what the fleet can use: ``ok``, the
    exit status, a one-line ``reason`` when not ok, the length used and, per axis, the terms the
    ``gmwm plan`` rule finds not identifiable at that length. ``report(argv)`` calibrates the
    recording with the arguments of the ``gmwm report`` command line ``argv`` and returns (exit
    status, the report's ``--json`` object or None, stderr's text)
    (:func:`gmwm.fleet.job.report`: :func:`gmwm.calibrate.calibrate` and
    :func:`gmwm.report.write_calibration` with the arguments ``gmwm report`` passes; the job
    layer parses the command line, this module sits below it). Writes ``report.json`` and,
    last (so a killed job leaves none), ``status.json``; returns the status."""
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    argv = settings.report_argv(str(path), str(outdir), topic, datasheet)
    code, obj, err = report(argv)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    errors = [ln.removeprefix("gmwm: error: ") for ln in lines if ln.startswith("gmwm: error:")]
    status: dict[str, Any] = {"ok": False, "exit_status": code, "reason": "",
                              "recording": str(path), "content_sha256": content,
                              "command": "gmwm " + " ".join(argv),
                              "warnings": [ln.removeprefix("gmwm: warning: ") for ln in lines
                                           if ln.startswith("gmwm: warning:")]}
    report: dict[str, Any] | None = None
    if code in (0, 3):  # 3: an optimizer did not report convergence; the report says so
        report = obj
        if report is None:
            status["reason"] = "the calibration gave no JSON result"
    else:
        status["reason"] = errors[-1] if errors else (lines[-1] if lines else
                                                      f"gmwm report exited with status {code}")
    if report is not None:
        write_json_atomic(outdir / "report.json", report)
        fits = report.get("fits") or {}
        st = report.get("stationarity") or {}
        used = st.get("used") or {}
        if used.get("end_s") is not None and used.get("start_s") is not None:
            used_s = float(used["end_s"]) - float(used["start_s"])
        else:
            f = next(iter(fits.values()), {})
            used_s = float(f.get("n", 0)) / float(f.get("freq", 1.0) or 1.0)
        status["used_s"] = used_s
        status["used"] = used.get("how") or "the whole recording"
        if used_s < settings.min_static_s:
            status["reason"] = (f"the longest static stretch lasts {used_s:.1f} s, shorter than "
                                f"the fleet's minimum of {settings.min_static_s:g} s")
        else:
            status["ok"] = True
            notes: list[str] = []
            status["not_identifiable"] = _not_identifiable(fits, notes)
            status["warnings"] += notes
    status["seconds"] = time.perf_counter() - t0
    write_json_atomic(outdir / "status.json", status)
    return status


# --------------------------------------------------------------------------------------------------
# the workflow
# --------------------------------------------------------------------------------------------------


def workflow_file() -> Path:
    """The fleet's Snakefile, shipped in the package."""
    return Path(str(resources.files("gmwm") / "data" / "fleet.smk"))


def _write_if_changed(path: Path, text: str) -> bool:
    if path.is_file() and path.read_text(encoding="utf-8") == text:
        return False
    write_text_atomic(path, text)
    return True


@dataclass
class Prepared:
    """What :func:`prepare` wrote: the config file and the recordings whose hash changed."""

    config: Path
    changed: list[str] = field(default_factory=list)
    recordings: list[Recording] = field(default_factory=list)


def prepare(recordings: Sequence[Recording], out: Path, settings: FleetSettings) -> Prepared:
    """Write ``OUT/.fleet``: the settings and the config the workflow reads (every recording's
    path and content hash, the settings' hash). The hashes are the jobs' params, which is what
    Snakemake compares (not time stamps): a dry run changes nothing a later run depends on.
    ``changed``: recordings new or changed since the last prepare. An unreadable recording is
    still listed (its job fails and says why)."""
    meta = out / ".fleet"
    text = json.dumps(settings.to_json(), indent=2, sort_keys=True) + "\n"
    _write_if_changed(meta / "settings.json", text)
    path = meta / "config.json"
    try:
        old = json.loads(path.read_text(encoding="utf-8")).get("recordings", {})
    except (OSError, ValueError):
        old = {}
    recs: dict[str, Any] = {}
    changed = []
    for r in recordings:
        try:
            digest = content_hash(r.path)
        except OSError as exc:
            digest = f"unreadable: {exc.strerror or exc}"
        if old.get(r.key, {}).get("sha256") != digest:
            changed.append(r.key)
        recs[r.key] = {"path": str(r.path.resolve()), "unit": r.unit, "name": r.name,
                       "date": r.date.isoformat() if r.date else None, "topic": r.topic,
                       "datasheet": r.datasheet, "temperature": r.temperature,
                       "sha256": digest}
    from gmwm import __version__

    # another gmwm version may calibrate differently: it counts as a changed setting
    key = f"{text}gmwm {__version__}\n"
    config = {"recordings": recs, "python": sys.executable, "out": str(out.resolve()),
              "gmwm_version": __version__,
              "settings_sha256": hashlib.sha256(key.encode()).hexdigest()}
    write_json_atomic(path, config)
    return Prepared(path, changed, list(recordings))


def _clear_stale_locks(out: Path) -> Any:
    """Hold an OS lock on ``OUT/.fleet/run.flock`` for this run; with it held exclusively no
    other fleet run is alive here, so Snakemake lock files are stale (a killed run) and are
    removed. Another live run on OUT is an InputError. Returns the open lock file."""
    (out / ".fleet").mkdir(parents=True, exist_ok=True)
    fh = open(out / ".fleet" / "run.flock", "a")  # noqa: SIM115 (held for the run's life)
    try:
        fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        fh.close()
        raise InputError(f"another 'gmwm fleet' run is writing {out}: wait for it or use "
                         "another -o") from None
    locks = out / ".snakemake" / "locks"
    if locks.is_dir() and any(locks.iterdir()):
        shutil.rmtree(locks)
    return fh


def snakemake_argv(out: Path, config: Path, *, cores: int | None = None,
                   profile: str | None = None, dry_run: bool = False,
                   extra: Sequence[str] = ()) -> list[str]:
    """The ``python -m snakemake`` command that runs the fleet in ``out``."""
    argv = [sys.executable, "-m", "snakemake", "--snakefile", str(workflow_file()),
            "--directory", str(out), "--config", f"fleet_config={config.resolve()}",
            "--rerun-triggers", "params", "input", "--keep-going",
            "--rerun-incomplete",
            # the default ILP scheduler costs Snakemake twice the CPU of the greedy one at ~1000
            # jobs, and all the fleet's jobs are alike, so an optimal schedule buys nothing
            "--scheduler", "greedy"]
    if profile:
        argv += ["--profile", profile]
    else:
        argv += ["--cores", str(cores or 1)]
    if dry_run:
        argv += ["-n"]
    return argv + list(extra)


def run_workflow(out: Path, config: Path, *, cores: int | None = None,
                 profile: str | None = None, dry_run: bool = False, extra: Sequence[str] = (),
                 log: Any = None) -> int:
    """Run the fleet's Snakemake workflow (a subprocess); its output goes to
    ``OUT/.fleet/snakemake.log`` (and ``log`` if given). Returns Snakemake's exit status."""
    lock = _clear_stale_locks(out)
    try:
        argv = snakemake_argv(out, config, cores=cores, profile=profile, dry_run=dry_run,
                              extra=extra)
        env = dict(os.environ)
        # the jobs import this very gmwm (a worktree or an editable install alike)
        src = str(Path(__file__).resolve().parents[2])
        env["PYTHONPATH"] = os.pathsep.join([src, *filter(None, [env.get("PYTHONPATH")])])
        env.setdefault("MPLBACKEND", "Agg")
        env["PYTHONUNBUFFERED"] = "1"  # Snakemake's lines reach the log as they happen
        logfile = out / ".fleet" / "snakemake.log"
        with open(logfile, "a", encoding="utf-8") as fh:
            fh.write(f"\n{RUN_MARK} {_dt.datetime.now().isoformat(timespec='seconds')}: "
                     + " ".join(argv) + "\n")
            fh.flush()
            # the child inherits the lock's descriptor: the flock lives as long as Snakemake
            with subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                  text=True, env=env, pass_fds=(lock.fileno(),)) as proc:
                assert proc.stdout is not None
                for line in proc.stdout:
                    fh.write(line)
                    fh.flush()
                    if log is not None:
                        log.write(line)
                return proc.wait()
    finally:
        lock.close()
