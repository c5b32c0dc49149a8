"""Shared fixtures: ONE quick-profile Snakemake run per test session, in a git copy of the workflow.

The run uses the README's command verbatim (`snakemake -j2 --configfile config/quick.yaml`) in a
temporary git repository holding the workflow files, so tests can also check that a quick run
leaves `git status` clean. Tests that need the pipeline's outputs take the `quick_run` fixture;
pytest builds it once, on first use.
"""

from __future__ import annotations

import ast
import functools
import importlib.util
import os
import shutil
import subprocess
import sys
from collections import deque
from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[1]
WORKFLOW_FILES = ("Snakefile", ".gitignore", "workflow", "config", "profiles")
QUICK_ARGS = ("-j2", "--configfile", "config/quick.yaml")  # README / docs/pipeline.md
QUICK_OUT = Path("results/quick")  # config/quick.yaml: outdir


def c_toolchain() -> bool:
    """True if this interpreter can build the C kernel gmwm._haar (a C compiler and Python.h):
    then `pip install` must have built it, and tests that need it fail rather than skip."""
    import sysconfig

    cc = (sysconfig.get_config_var("CC") or "cc").split()[0]
    header = Path(sysconfig.get_paths()["include"]) / "Python.h"
    return shutil.which(cc) is not None and header.exists()


#: for tests of the C kernel: skipped only where it cannot have been built
needs_c_kernel = pytest.mark.skipif(not c_toolchain(),
                                    reason="no C compiler or Python.h: gmwm._haar is not built "
                                           "and gmwm.wv uses the Numba kernel")


def load_benchmark(name: str):
    """The module ``benchmarks/<name>.py``, loaded from its path (the tests of a benchmark's logic
    use it; ``sys.path`` is left alone)."""
    path = REPO / "benchmarks" / f"{name}.py"
    mod_name = f"gmwm_benchmarks_{name}"
    if mod_name in sys.modules:
        return sys.modules[mod_name]
    spec = importlib.util.spec_from_file_location(mod_name, path)
    assert spec is not None and spec.loader is not None, path
    module = importlib.util.module_from_spec(spec)
    sys.modules[mod_name] = module  # dataclasses and pickling look the module up by name
    spec.loader.exec_module(module)
    return module


def source_nodes(path: Path) -> tuple[tuple[ast.AST, bool], ...]:
    """Every node of the syntax tree of the Python file ``path`` in ``ast.walk`` order, each with
    whether it lies inside a function or lambda. Parsed and walked once per file content and
    session: the source checks (test_layout, test_cli_errors) read the same files, and parsing and
    walking are most of their time. The trees are shared: do not modify them."""
    return _source_nodes(str(path), path.read_text(encoding="utf-8"))


@functools.cache
def _source_nodes(filename: str, text: str) -> tuple[tuple[ast.AST, bool], ...]:
    out = []
    todo = deque([(ast.parse(text, filename=filename), False)])
    while todo:
        node, in_function = todo.popleft()
        out.append((node, in_function))
        inner = in_function or isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda)
        todo.extend((child, inner) for child in ast.iter_child_nodes(node))
    return tuple(out)


def pytest_sessionfinish(session, exitstatus):
    """Free the cached syntax trees while the interpreter is whole: left to its shutdown, their
    ~300,000 nodes delay the exit by ~1.5 s."""
    _source_nodes.cache_clear()


@pytest.fixture
def one_process(monkeypatch: pytest.MonkeyPatch) -> None:
    """Reports draw their figures and commands choose models in this process (as on one core:
    ``gmwm.calibrate.available_cores`` -> 1), for tests of what a page, a file or the output says,
    where worker processes are not what is tested: starting them costs a small report more than
    the work itself. That workers give the same page: test_report_workers; that parallel fits
    equal serial ones: test_multi_imu; other report tests still run with the workers."""
    import gmwm.calibrate

    monkeypatch.setattr(gmwm.calibrate, "available_cores", lambda: 1)


#: set by .ci/run: CI has every optional package and ../shared, so a skipped test there is a
#: test that did not run for a reason CI should not have; it fails instead of passing silently
NO_SKIPS = os.environ.get("GMWM_TEST_NO_SKIPS") == "1"


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if NO_SKIPS and report.skipped and not hasattr(report, "wasxfail"):
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        report.outcome = "failed"
        report.longrepr = f"skipped in CI (GMWM_TEST_NO_SKIPS=1), which must run it: {reason}"


@pytest.hookimpl(tryfirst=True)  # before `-m` deselects
def pytest_collection_modifyitems(items):
    """A pipeline test is a slow test too: `-m "not slow"` leaves out every Snakemake run."""
    for item in items:
        if item.get_closest_marker("pipeline") and not item.get_closest_marker("slow"):
            item.add_marker(pytest.mark.slow)


def snakemake_cmd(*args: str) -> list[str]:
    """The `snakemake` command of this interpreter's environment with ``args``."""
    return [sys.executable, "-m", "snakemake", *args]


def run_snakemake(work: Path, *args: str) -> str:
    """Run snakemake in ``work`` (no time limit); return stdout + stderr; fail the test on error."""
    proc = subprocess.run(snakemake_cmd(*args), cwd=work, capture_output=True, text=True,
                          check=False)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, f"snakemake {' '.join(args)} failed:\n{out[-4000:]}"
    return out


def git_status(work: Path) -> str:
    """`git status --porcelain` of ``work``, including untracked files."""
    return subprocess.run(["git", "status", "--porcelain", "--untracked-files=all"], cwd=work,
                          capture_output=True, text=True, check=True).stdout


def workflow_copy(dest: Path) -> Path:
    """Copy the workflow files of the working tree to ``dest`` and commit them to a new git repo."""
    for name in WORKFLOW_FILES:
        src = REPO / name
        if src.is_dir():
            shutil.copytree(src, dest / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy(src, dest / name)
    env = {**os.environ, "GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t",
           "GIT_COMMITTER_NAME": "t", "GIT_COMMITTER_EMAIL": "t@t"}
    for cmd in (["git", "init", "-q"], ["git", "add", "-A"], ["git", "commit", "-q", "-m", "copy"]):
        subprocess.run(cmd, cwd=dest, check=True, env=env, capture_output=True)
    return dest


@dataclass(frozen=True)
class QuickRun:
    """A finished quick run: the git copy it ran in, Snakemake's exit status and output, and
    `git status --porcelain` before and after."""

    work: Path
    returncode: int
    output: str
    git_before: str
    git_after: str

    @property
    def out(self) -> Path:
        """Its output directory (results/, reports/, logs/ below it)."""
        return self.work / QUICK_OUT


def navchip_data_missing() -> str | None:
    """Why the quick run cannot run offline, or None: its navchip rules copy the Navchip WV file
    from the dataset registry's local directory (config/datasets.yaml `local_dir`, ../shared/data
    next to the repository) and would otherwise download it. The same lookup as
    workflow/rules/navchip.smk (config `navchip.dataset`, `navchip.data_dir` null)."""
    from gmwm_studies.data import load_registry, local_copy

    cfg = {}
    for name in ("config.yaml", "quick.yaml"):
        cfg.update(yaml.safe_load((REPO / "config" / name).read_text()).get("navchip") or {})
    if not cfg.get("enabled", True):
        return None
    if cfg.get("data_dir") is not None:
        data_dir = REPO / cfg["data_dir"]
    else:
        data_dir = load_registry().get("local_dir_resolved")
    if local_copy(cfg["dataset"], data_dir) is not None:
        return None
    return (f"the quick run needs the Navchip data on disk ({cfg['dataset']} in {data_dir}, "
            "config/datasets.yaml); without it its navchip rules would download it")


@pytest.fixture(scope="session")
def quick_run(tmp_path_factory) -> QuickRun:
    """One uninterrupted quick run per session. It is not asserted here: with keep-going a
    failing rule leaves the other outputs, so test_quick_run_completes reports the
    failure and the tests of the other outputs still run. Skipped (with every test using it)
    when the Navchip data is not on disk: a fresh clone without ../shared, offline."""
    missing = navchip_data_missing()
    if missing:
        pytest.skip(missing)
    work = workflow_copy(tmp_path_factory.mktemp("quick"))
    before = git_status(work)
    proc = subprocess.run(snakemake_cmd(*QUICK_ARGS), cwd=work, capture_output=True, text=True,
                          check=False)
    return QuickRun(work, proc.returncode, proc.stdout + proc.stderr, before, git_status(work))
