"""Library errors name parameters; the command line says them with its flags (gmwm.cli.errors)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import gmwm
from conftest import source_nodes
from gmwm.cli.errors import PARAMETER_FLAGS, as_flags

CORE = Path(gmwm.__file__).parent
_FLAG = re.compile(r"(?<![\w-])--[a-z][a-z-]+")
# library messages that still name a flag, per file (owned elsewhere when this check was written):
# the counts may only go down; new messages name the parameter in backquotes (`freq`)
# calibrate.py is at 0; the readers' counts rose with the DataFlash, phone and rate messages
# merged beside this check (recording.py 15 -> 22, timebase.py 4 -> 5, dataflash.py and phone.py
# new): the readers are the next to convert
KNOWN_FLAG_MESSAGES = {  # string pieces (an f-string's constant parts count one each)
    "report.py": 1, "stationarity.py": 2, "stream.py": 8,
    "readers/recording.py": 22, "readers/rosbag.py": 2, "readers/tables.py": 10,
    "readers/text.py": 1, "readers/timebase.py": 5, "readers/ulog.py": 2,
    "readers/dataflash.py": 2, "readers/phone.py": 2,
    # the fleet: run.py builds Snakemake's own command line and job.py is a job's command line
    # (their flags are other programs' options, not messages; job.py parses a `gmwm report`
    # command line and answers in its terms); collect.py's one is a table note
    "fleet/run.py": 18, "fleet/job.py": 4, "fleet/collect.py": 1,
}


def test_as_flags_maps_parameters_to_flags():
    assert as_flags("`start_s`/`end_s` select 0 samples; give `freq` (Hz)") == (
        "--start/--end select 0 samples; give --freq (Hz)")
    assert as_flags("column `gyro_x` is not numeric; choose with `columns`") == (
        "column `gyro_x` is not numeric; choose with --columns")
    assert as_flags("try the identifiability check (`gmwm.identify.check`)") == (
        "try the identifiability check (--check)")
    assert all(f.startswith("--") for f in PARAMETER_FLAGS.values())


def _messages(path: Path) -> list[tuple[int, str]]:
    """String constants of ``path`` outside docstrings, with their lines."""
    nodes = [node for node, _ in source_nodes(path)]  # ast.walk order, parsed once a session
    docs = set()
    for node in nodes:
        body = getattr(node, "body", None)
        if isinstance(body, list) and body and isinstance(body[0], ast.Expr) \
                and isinstance(body[0].value, ast.Constant):
            docs.add(id(body[0].value))
    return [(n.lineno, n.value) for n in nodes
            if isinstance(n, ast.Constant) and isinstance(n.value, str) and id(n) not in docs]


def test_library_messages_name_parameters_not_flags():
    found: dict[str, list[str]] = {}
    for f in sorted(CORE.rglob("*.py")):
        rel = f.relative_to(CORE).as_posix()
        if rel.startswith("cli/") or rel == "_precompile.py":  # the CLI, and the CLI's warm-up
            continue
        hits = [f"{rel}:{line}: {text.strip()[:70]}" for line, text in _messages(f)
                if _FLAG.search(text)]
        if hits:
            found[rel] = hits
    grown = {k: v for k, v in found.items() if len(v) > KNOWN_FLAG_MESSAGES.get(k, 0)}
    assert not grown, ("library messages naming command-line flags (name the parameter in "
                       "backquotes; gmwm.cli.errors maps it to the flag):\n"
                       + "\n".join(h for v in grown.values() for h in v))


def test_the_flag_scan_sees_a_message(tmp_path):
    f = tmp_path / "m.py"
    f.write_text('"""Docs may say --freq."""\n\n\ndef g(x):\n    raise ValueError(f"give --freq {x}")\n')
    assert [t for _, t in _messages(f) if _FLAG.search(t)] == ["give --freq "]


def test_select_criterion_default_is_the_librarys():
    # one place for the default criterion: the CLI offers the library's criteria and default
    from gmwm.cli.parser import build_parser
    from gmwm.criteria import CRITERIA, DEFAULT

    p = build_parser()
    assert p.parse_args(["select", "x.csv", "WN"]).criterion == DEFAULT
    for crit in CRITERIA:
        assert p.parse_args(["select", "x.csv", "WN", "--criterion", crit]).criterion == crit
