"""Package layout: the core library ``gmwm`` never imports the paper studies (``gmwm_studies``),
and importing it pulls in none of the pipeline's dependencies."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import gmwm

CORE = Path(gmwm.__file__).parent
STUDIES = "gmwm_studies"
# pipeline-only packages (pyproject extra "pipeline") and emcee, which the core loads on first use
# (pyyaml is no core dependency either, but numba imports it whenever it is installed)
NOT_WITH_CORE = (STUDIES, "snakemake", "statsmodels", "netCDF4", "rdata", "emcee", "xarray")
# a bare ``import gmwm`` must stay cheap (``gmwm --help`` starts fast): no numerics at all
NOT_WITH_BARE_IMPORT = (*NOT_WITH_CORE, "numpy", "scipy", "numba", "pandas", "matplotlib", "h5py",
                        "yaml")


def _imported_modules(path: Path) -> set[str]:
    """Absolute names of every module that ``path`` imports, at any depth (relative ones resolved)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = "gmwm" if node.level else ""
            names.add(".".join(p for p in (base, node.module or "") if p))
        elif (isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(node.func, "id", ""))
              in ("import_module", "__import__") and node.args
              and isinstance(node.args[0], ast.Constant)):
            names.add(str(node.args[0].value))
    return names


def test_core_files_never_import_the_studies():
    files = sorted(CORE.rglob("*.py"))
    assert len(files) > 20
    offenders = {f.name: sorted(m for m in _imported_modules(f) if m.split(".")[0] == STUDIES)
                 for f in files}
    assert {k: v for k, v in offenders.items() if v} == {}


def test_the_scan_sees_an_import_of_the_studies(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("def f():\n    from gmwm_studies.seeds import stable_int\n    return stable_int\n")
    assert "gmwm_studies.seeds" in _imported_modules(bad)


def _loaded_after(code: str) -> list[str]:
    """Top-level packages of NOT_WITH_BARE_IMPORT in sys.modules after running ``code`` afresh."""
    probe = (f"{code}\nimport json, sys\n"
             f"print(json.dumps(sorted({{m.split('.')[0] for m in sys.modules}} & "
             f"set({list(NOT_WITH_BARE_IMPORT)!r}))))")
    proc = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_bare_import_is_cheap():
    assert _loaded_after("import gmwm") == []


def test_every_core_module_imports_without_the_pipeline():
    modules = sorted(f"gmwm.{f.stem}" for f in CORE.glob("*.py")
                     if f.stem not in ("__init__", "__main__"))
    assert "gmwm.bootstrap" in modules and "gmwm.cli" in modules
    code = "import importlib\n" + "".join(f"importlib.import_module({m!r})\n" for m in modules)
    loaded = _loaded_after(code)
    assert "numpy" in loaded  # the probe does see what the modules load
    assert sorted(set(loaded) & set(NOT_WITH_CORE)) == []
