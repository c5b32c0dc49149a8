"""Package layout: the core library ``gmwm`` never imports the paper studies (``gmwm_studies``),
importing it pulls in none of the pipeline's dependencies, its light modules stay light, and no
study code (a public name only the studies or the workflow use) sits in the core."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

import gmwm
from conftest import source_nodes

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


@pytest.mark.slow
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


@pytest.mark.slow
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


@pytest.mark.slow
def test_svo_modules_load_numba_only_on_first_use():
    assert "numba" not in _loaded_after("import gmwm.virtual, gmwm.wccv")


@pytest.mark.slow
def test_svo_job_modules_load_no_scipy_stats():
    """The SVO pipeline jobs' modules take the normal quantile from scipy.special: importing
    scipy.stats would add ~0.5 s to every job's start-up."""
    probe = ("import sys, gmwm.virtual, gmwm.wccv, gmwm_studies.svo_study\n"
             "print('scipy.stats' in sys.modules)")
    proc = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.split() == ["False"]


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


@pytest.mark.slow
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


# -- the import graph: no cycles, no private names across modules, the compile list ---------------
# Every ``import`` counts, at module level and inside functions (an import inside a function still
# ties the two modules together; it only defers the cost). A module whose own NAME starts with an
# underscore (``_wvkernels``, ``_haar``, ``_precompile``, ...) is private to the package, as in
# scikit-learn: other gmwm modules may import its public names, code outside gmwm may not.
# A leading-underscore NAME is private to the module that defines it, everywhere.
def _gmwm_modules(src: Path, pkg: str = "gmwm") -> dict[str, Path]:
    """Module name -> source file, for every Python module of ``pkg`` under ``src``."""
    return {_module_name(f, src): f for f in sorted((src / pkg).rglob("*.py"))}


def _all_modules(src: Path, pkg: str = "gmwm") -> set[str]:
    """Every module of ``pkg``: its Python modules and its compiled extensions (``_haar``)."""
    ext = {_module_name(f.with_name(f.name.split(".")[0] + ".py"), src)
           for f in (src / pkg).rglob("*") if f.suffix in (".so", ".pyd")}
    return set(_gmwm_modules(src, pkg)) | ext


def _import_targets(path: Path, src: Path, modules: dict[str, Path] | set[str]
                    ) -> list[tuple[str, list[str], int, bool]]:
    """``(module, names, line, in_function)`` for every import in ``path``: ``module`` is the
    imported module (``from gmwm import wv`` imports module ``gmwm.wv``, with no names;
    ``from gmwm.wv import _x`` imports ``gmwm.wv`` with names ``['_x']``)."""
    out = []
    for child, in_function in source_nodes(path):
        if isinstance(child, ast.Import):
            out.extend((a.name, [], child.lineno, in_function) for a in child.names)
        elif isinstance(child, ast.ImportFrom):
            x = _from_module(path, src, child)
            names = []
            for a in child.names:
                if f"{x}.{a.name}" in modules:
                    out.append((f"{x}.{a.name}", [], child.lineno, in_function))
                else:
                    names.append(a.name)
            if names:
                out.append((x, names, child.lineno, in_function))
        elif (isinstance(child, ast.Call)
              and getattr(child.func, "attr", getattr(child.func, "id", ""))
              in ("import_module", "__import__") and child.args
              and isinstance(child.args[0], ast.Constant)):
            out.append((str(child.args[0].value), [], child.lineno, in_function))
    return out


def import_graph(src: Path = REPO / "src", pkg: str = "gmwm"
                 ) -> tuple[dict[str, set[str]], list[tuple[str, str, int]]]:
    """The package's import arrows (module -> modules of the package it imports) and every import
    inside a function as ``(module, imported module, line)``."""
    files, modules = _gmwm_modules(src, pkg), _all_modules(src, pkg)
    arrows: dict[str, set[str]] = {m: set() for m in files}
    deferred = []
    for m, f in files.items():
        for target, _names, line, in_function in _import_targets(f, src, modules):
            if target.split(".")[0] != pkg:
                continue
            # ``import gmwm.readers.tables`` names a module; ``import gmwm.x.y`` of a non-module
            # attribute does not happen in the package
            while target not in modules and "." in target:
                target = target.rsplit(".", 1)[0]
            if target != m and target in files:
                arrows[m].add(target)
            if in_function:
                deferred.append((m, target, line))
    return arrows, deferred


def import_cycles(arrows: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan), each as one cycle
    through the component, so a failure names the imports to break."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    comps: list[list[str]] = []
    counter = [0]

    def strong(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(arrows.get(v, ())):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                comps.append(sorted(comp))

    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10_000))
    for v in sorted(arrows):
        if v not in index:
            strong(v)
    cycles = []
    for comp in comps:
        # shortest path back to the start (breadth first inside the component)
        start, members = comp[0], set(comp)
        prev: dict[str, str] = {}
        frontier, found = [start], None
        while frontier and found is None:
            nxt = []
            for v in frontier:
                for w in sorted(arrows[v] & members):
                    if w == start:
                        found = v
                        break
                    if w not in prev:
                        prev[w] = v
                        nxt.append(w)
                if found is not None:
                    break
            frontier = nxt
        path = [found]
        while path[-1] != start:
            path.append(prev[path[-1]])
        cycles.append([*path[::-1], start] + ([f"(component: {', '.join(comp)})"]
                                              if len(comp) > len(path) else []))
    return cycles


def private_imports(files: dict[str, Path], src: Path, pkg: str = "gmwm",
                    outside: bool = False) -> list[str]:
    """``file:line imports module._name`` for every import, from ``files``, of a leading-underscore
    name of another module of ``pkg``, or attribute access ``alias._name`` on an imported module
    of ``pkg``; with ``outside`` (code outside ``pkg``) also of any private module of ``pkg``."""
    modules = _all_modules(src, pkg)
    found = []
    for m, path in files.items():
        f = path
        where = str(path.relative_to(src)) if path.is_relative_to(src) else path.name
        aliases: dict[str, str] = {}
        for target, names, line, _ in _import_targets(f, src, modules):
            if target.split(".")[0] != pkg:
                continue
            private_module = any(p.startswith("_") and not p.startswith("__")
                                 for p in target.split("."))
            if outside and private_module:
                found.append(f"{where}:{line} imports private module {target}")
            for n in names:
                if n.startswith("_") and not n.startswith("__") and target != m:
                    found.append(f"{where}:{line} imports {target}.{n}")
        nodes = [node for node, _ in source_nodes(f)]
        for node in nodes:
            if isinstance(node, ast.Import):
                for a in node.names:
                    if a.name.split(".")[0] == pkg:
                        aliases[a.asname or a.name.split(".")[0]] = a.asname and a.name or pkg
            elif isinstance(node, ast.ImportFrom):
                x = _from_module(f, src, node)
                for a in node.names:
                    if f"{x}.{a.name}" in modules:
                        aliases[a.asname or a.name] = f"{x}.{a.name}"
        for node in nodes:
            if isinstance(node, ast.Attribute) and node.attr.startswith("_") \
                    and not node.attr.startswith("__"):
                chain, v = [node.attr], node.value
                while isinstance(v, ast.Attribute):
                    chain.append(v.attr)
                    v = v.value
                if not (isinstance(v, ast.Name) and v.id in aliases):
                    continue
                module, rest = aliases[v.id], chain[::-1]
                while len(rest) > 1 and f"{module}.{rest[0]}" in modules:
                    module, rest = f"{module}.{rest[0]}", rest[1:]
                if len(rest) == 1 and module != m and f"{module}.{rest[0]}" not in modules:
                    found.append(f"{where}:{node.lineno} uses {module}.{rest[0]}")
    return sorted(set(found))


def test_no_import_cycles():
    arrows, _ = import_graph()
    assert len(arrows) > 40
    cycles = import_cycles(arrows)
    assert not cycles, "import cycles (imports inside functions count):\n" + "\n".join(
        " -> ".join(c) for c in cycles)


def test_the_cycle_check_sees_a_cycle_through_a_function_import(tmp_path):
    pkg = tmp_path / "gmwm"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from gmwm.b import f\n")
    (pkg / "b.py").write_text("def f():\n    from gmwm import c\n    return c\n")
    (pkg / "c.py").write_text("def g():\n    from . import a\n    return a\n")
    (pkg / "d.py").write_text("import gmwm.a\n")
    arrows, deferred = import_graph(tmp_path)
    assert arrows["gmwm.d"] == {"gmwm.a"} and ("gmwm.b", "gmwm.c", 2) in deferred
    assert import_cycles(arrows) == [["gmwm.a", "gmwm.b", "gmwm.c", "gmwm.a"]]


def test_no_module_imports_another_modules_private_names():
    src = REPO / "src"
    found = private_imports(_gmwm_modules(src), src)
    assert not found, ("private names used across modules (make the name public, or move it "
                       "into a private _module):\n" + "\n".join(found))


def test_the_studies_use_no_private_name_of_the_library():
    src = REPO / "src"
    found = private_imports(_gmwm_modules(src, STUDIES), src, outside=True)
    assert not found, "gmwm_studies uses private parts of gmwm:\n" + "\n".join(found)


def test_the_private_name_check_sees_one(tmp_path):
    pkg = tmp_path / "gmwm"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "_kern.py").write_text("def k():\n    pass\n\n\ndef _k():\n    pass\n")
    (pkg / "a.py").write_text("_x = 1\n\n\ndef _own():\n    return _x\n")
    (pkg / "b.py").write_text("from gmwm._kern import k\nfrom gmwm import a\n\n\n"
                              "def f():\n    from gmwm._kern import _k\n    return a._x, k, _k\n")
    found = private_imports(_gmwm_modules(tmp_path), tmp_path)
    assert found == ["gmwm/b.py:6 imports gmwm._kern._k", "gmwm/b.py:7 uses gmwm.a._x"]
    study = tmp_path / "study.py"
    study.write_text("from gmwm._kern import k\n")
    assert private_imports({"study": study}, tmp_path, outside=True) == [
        "study.py:1 imports private module gmwm._kern"]


def test_the_install_time_compile_names_only_modules_that_exist():
    """Every gmwm module ``_precompile`` imports exists and imports, and every command its warm-up
    runs is a command of the CLI (an install swallows a failure of the compile step: a stale name
    would go unnoticed)."""
    src = REPO / "src"
    modules = _all_modules(src)
    named = {t for t, _, _, _ in _import_targets(CORE / "_precompile.py", src, modules)
             if t.split(".")[0] in ("gmwm", STUDIES)}
    assert "gmwm.wv" in named
    from gmwm import _precompile

    commands = {cmd[0] for cmd in _precompile._COMMANDS} | {"simulate"}
    named |= {f"gmwm.cli.commands.{c.replace('-', '_')}" for c in commands}
    missing = sorted(t for t in named if t not in modules)
    assert not missing, f"_precompile names modules that do not exist: {missing}"
    loaded = _loaded_after("import importlib\n" + "".join(
        f"importlib.import_module({t!r})\n" for t in sorted(named)))
    assert "numpy" in loaded
