"""Package layout: the core library ``gmwm`` never imports the paper studies (``gmwm_studies``),
importing it pulls in none of the pipeline's dependencies, its light modules stay light, and no
study code (a public name only the studies or the workflow use) sits in the core."""

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
    modules = sorted(_module_name(f, CORE.parent) for f in CORE.rglob("*.py")
                     if f.stem != "__main__")
    assert {"gmwm.bootstrap", "gmwm.cli", "gmwm.readers.tables"} <= set(modules)
    code = "import importlib\n" + "".join(f"importlib.import_module({m!r})\n" for m in modules)
    loaded = _loaded_after(code)
    assert "numpy" in loaded  # the probe does see what the modules load
    assert sorted(set(loaded) & set(NOT_WITH_CORE)) == []


# -- light modules: readers, atomic writers and the result codec load no numerics beyond NumPy ----
def test_readers_and_writers_have_a_low_floor():
    loaded = _loaded_after("import gmwm.readers, gmwm.atomic, gmwm.codec")
    assert "numpy" in loaded
    assert sorted(set(loaded) & {"scipy", "numba", "matplotlib", "pandas", "h5py"}) == []


def test_readers_import_no_result_class():
    """gmwm.readers.tables imports only NumPy and gmwm.errors when loaded (pandas/h5py on first
    use); inside functions it imports the WV container read_wv_table returns and the time-base
    checks of time columns (gmwm.readers.timebase, itself NumPy-only)."""
    path = CORE / "readers" / "tables.py"
    tree = ast.parse(path.read_text(encoding="utf-8"))
    top = set()
    for node in tree.body:
        if isinstance(node, ast.Import):
            top.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            top.add(node.module or "")
    assert {m for m in top if m.startswith("gmwm")} == {"gmwm.errors"}
    assert {m for m in _imported_modules(path) if m.startswith("gmwm")} == {
        "gmwm.errors", "gmwm.wv", "gmwm.readers.timebase"}


def test_svo_modules_load_numba_only_on_first_use():
    assert "numba" not in _loaded_after("import gmwm.virtual, gmwm.wccv")


# -- study code stays out of the core ---------------------------------------------------------------
# Public names of the core that only gmwm_studies / workflow scripts use are study code, unless
# they are library API: exported in gmwm.__all__, or listed here with the reason.
_CONVERSION = "generic datasheet <-> per-sample unit conversion (docs/API.md, gmwm.units)"
LIBRARY_API = {
    "gmwm.atomic.write_json_atomic": "atomic output, as every writer of gmwm.atomic",
    "gmwm.codec.read_result": "lossless result files (docs/API.md)",
    "gmwm.codec.write_result": "lossless result files (docs/API.md)",
    "gmwm.bootstrap.parametric_bootstrap": "the library's bootstrap (docs/API.md)",
    "gmwm.wv.wvar_many": "the WV of many signals at once (docs/API.md)",
    "gmwm.fused.simulate_wv": "the WV of a simulated signal without the signal (Monte Carlo)",
    "gmwm.fused.simulate_signal": "the signal gmwm.fused.simulate_wv draws (its tests, studies)",
    **{f"gmwm.units.{n}": _CONVERSION for n in (
        "deg_per_hour_to_rad_per_second", "dr_coefficient_from_omega", "dr_from_per_hour2",
        "micro_g_to_si", "qn_coefficient_from_q2", "rw_coefficient_from_gamma2",
        "rw_from_per_hour_sqrt_hour", "wn_density_from_sigma2", "wn_from_arw_per_sqrt_hour")},
}
# study code still in the core, in files this check's author could not move; each entry must still
# be an offender (so the list only shrinks)
KNOWN_STUDY_CODE = {
    "gmwm.bootstrap.coverage": "coverage of replicate intervals, used by gmwm_studies.uncertainty",
}
REPO = CORE.parent.parent


def _module_name(path: Path, src: Path) -> str:
    parts = list(path.relative_to(src).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _from_module(path: Path, src: Path, node: ast.ImportFrom) -> str:
    """Absolute module of ``from ... import`` (relative imports resolved against ``path``)."""
    if not node.level:
        return node.module or ""
    package = _module_name(path, src).split(".")
    if path.name != "__init__.py":
        package = package[:-1]
    package = package[:len(package) - node.level + 1]
    return ".".join(package + ([node.module] if node.module else []))


def _defined(tree: ast.Module) -> set[str]:
    """Public names a module defines at top level (functions, classes, assigned names)."""
    names = set()
    for node in tree.body:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            names.add(node.name)
        elif isinstance(node, ast.Assign | ast.AnnAssign):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names.update(t.id for t in targets if isinstance(t, ast.Name))
    return {n for n in names if not n.startswith("_")}


class _Scan:
    """Who uses which public name of the core package ``pkg`` (sources under ``src``)."""

    def __init__(self, src: Path, pkg: str) -> None:
        self.src, self.pkg = src, pkg
        self.files = {_module_name(f, src): f for f in sorted((src / pkg).rglob("*.py"))}
        self.trees = {m: ast.parse(f.read_text(encoding="utf-8")) for m, f in self.files.items()}
        # module-level ``from X import n`` of a core module: its name n stands for X.n
        self.alias = {}
        for m, tree in self.trees.items():
            for node in tree.body:
                if isinstance(node, ast.ImportFrom):
                    x = _from_module(self.files[m], src, node)
                    for a in node.names:
                        if f"{x}.{a.name}" not in self.files:
                            self.alias[(m, a.asname or a.name)] = (x, a.name)

    def origin(self, module: str, name: str) -> tuple[str, str]:
        seen = set()
        while (module, name) in self.alias and (module, name) not in seen:
            seen.add((module, name))
            module, name = self.alias[(module, name)]
        return module, name

    def used_by(self, path: Path, tree: ast.Module, own: str | None) -> set[tuple[str, str]]:
        """(module, name) pairs of the core that ``tree`` uses: names it imports from a core module
        (in a core module's top level only if it also uses them: re-exports do not count), attribute
        accesses on an imported core module, and, in core module ``own``, its own names."""
        modules: dict[str, str] = {}
        names: dict[str, tuple[str, str]] = {}
        top = {a.asname or a.name for n in tree.body if isinstance(n, ast.ImportFrom)
               for a in n.names}
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                for a in node.names:
                    if a.name.split(".")[0] == self.pkg:
                        modules[a.asname or self.pkg] = a.name if a.asname else self.pkg
            elif isinstance(node, ast.ImportFrom):
                x = _from_module(path, self.src, node)
                if x.split(".")[0] != self.pkg:
                    continue
                for a in node.names:
                    full = f"{x}.{a.name}"
                    if full in self.files:
                        modules[a.asname or a.name] = full
                    else:
                        names[a.asname or a.name] = (x, a.name)
            elif (isinstance(node, ast.Assign) and isinstance(node.value, ast.Call)
                  and getattr(node.value.func, "attr", getattr(node.value.func, "id", ""))
                  == "import_module" and node.value.args
                  and isinstance(node.value.args[0], ast.Constant)):
                modules.update((t.id, str(node.value.args[0].value)) for t in node.targets
                               if isinstance(t, ast.Name))
        loads = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)
                 and isinstance(n.ctx, ast.Load)}
        out = {ref for local, ref in names.items()
               if own is None or local not in top or local in loads}
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute):
                chain, v = [], node
                while isinstance(v, ast.Attribute):
                    chain.append(v.attr)
                    v = v.value
                if isinstance(v, ast.Name) and v.id in modules:
                    module, rest = modules[v.id], chain[::-1]
                    while rest and f"{module}.{rest[0]}" in self.files:
                        module, rest = f"{module}.{rest[0]}", rest[1:]
                    if rest:
                        out.add((module, rest[0]))
        if own is not None:
            out.update((own, n) for n in loads)
        return {self.origin(*u) for u in out}

    def study_only(self, consumers: list[Path], api: set[tuple[str, str]]) -> dict[str, list[str]]:
        """``module.name`` -> consumer files, for public core names that only ``consumers`` use."""
        core_use = set().union(*(self.used_by(self.files[m], t, m) for m, t in self.trees.items()))
        users: dict[tuple[str, str], set[str]] = {}
        for f in consumers:
            for u in self.used_by(f, ast.parse(f.read_text(encoding="utf-8")), None):
                users.setdefault(u, set()).add(f.name)
        api = {self.origin(*a) for a in api}
        return {f"{m}.{n}": sorted(users[(m, n)]) for m, tree in self.trees.items()
                for n in sorted(_defined(tree))
                if (m, n) in users and (m, n) not in core_use and (m, n) not in api}


def _public_api() -> set[tuple[str, str]]:
    """(module, name) of every name in gmwm.__all__ (the package exports them lazily)."""
    exports = {}
    for node in ast.parse((CORE / "__init__.py").read_text(encoding="utf-8")).body:
        if isinstance(node, ast.Assign) and getattr(node.targets[0], "id", "") == "_EXPORTS":
            exports = ast.literal_eval(node.value)
    assert set(gmwm.__all__) <= set(exports)
    return {(f"gmwm.{exports[n]}", n) for n in gmwm.__all__}


def test_no_study_code_in_the_core():
    consumers = sorted((REPO / "src" / STUDIES).rglob("*.py")) + sorted(
        (REPO / "workflow").rglob("*.py"))
    assert len(consumers) > 30
    found = _Scan(REPO / "src", "gmwm").study_only(consumers, _public_api())
    stale = sorted(set(KNOWN_STUDY_CODE) - set(found))
    assert not stale, f"no longer study code in the core, drop from KNOWN_STUDY_CODE: {stale}"
    bad = {k: v for k, v in found.items() if k not in LIBRARY_API and k not in KNOWN_STUDY_CODE}
    assert not bad, "\n".join(
        f"{name} is defined in the core but used only by {', '.join(users)}: move it to "
        f"{STUDIES}, or, if it is library API, export it in gmwm.__all__ (or list it in "
        "LIBRARY_API with the reason)" for name, users in bad.items())


def test_the_study_code_check_sees_a_study_only_name(tmp_path):
    """A miniature tree: the core defines f (used only by a study), g (used by the core's CLI
    through a re-export) and h (exported); only f is reported."""
    core = tmp_path / "src" / "core"
    (core / "sub").mkdir(parents=True)
    (core / "__init__.py").write_text("")
    (core / "sub" / "__init__.py").write_text("from core.sub.impl import f, g\n")
    (core / "sub" / "impl.py").write_text("def f():\n    pass\n\n\ndef g():\n    pass\n\n\n"
                                          "def h():\n    pass\n\n\n_x = 1\n")
    (core / "cli.py").write_text("def main():\n    from core.sub import g\n    return g()\n")
    study = tmp_path / "study.py"
    study.write_text("import core.sub.impl as m\nfrom core.sub import f\n\nf(); m.g(); m.h()\n")
    found = _Scan(tmp_path / "src", "core").study_only([study], {("core.sub.impl", "h")})
    assert found == {"core.sub.impl.f": ["study.py"]}
