"""Numbers REPRODUCTION.md quotes from committed tables: the cell and untraced markers
(gmwm_studies.counts.check_quotes) and the committed page checked against reports/."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest

from gmwm.errors import InputError
from gmwm_studies.counts import (
    cell_value,
    check_quotes,
    find_quotes,
    format_like,
    main,
    plain_numbers,
    plan_refresh,
    refresh_quotes,
)

REPO = Path(__file__).resolve().parents[1]
REPORTS = REPO / "reports"

TABLE = """method,level,ratio_to_equal,share
rdvg,14,1.0797508,0.808
rdvg,15,0.9376293,0.25
svo_w2,15,0.9123718,-0.75
"""

PAGE = """# Quotes

| item | numbers |
|---|---|
| Fig 7 | RDVG [0.9376](t/wv.csv#method=rdvg&level=15&col=ratio_to_equal) at j = 15, \
range [0.912](t/wv.csv#level=15&col=ratio_to_equal&agg=min)-\
[0.938](t/wv.csv#level=15&col=ratio_to_equal&agg=max); lowest in [80.8](t/wv.csv#level=14&col=share&mul=100) %, |share| at least [25](t/wv.csv#col=share&agg=min&abs=1&mul=100) % |

JSON: [1.00004](s.json#fig41/N/mc_mean); a count [13](counts.md#sim2.gmwm.label_switched.SIN);
not in any file: [145](#untraced "no per-replicate K readings"), [2.8](#untraced).
An example in code, `[1](t/wv.csv#col=nope)`, is no marker; nor is a plain [link](t/wv.csv) or
a link to [the untraced list](#untraced).
"""


def write_page(root: Path, page: str = PAGE) -> Path:
    (root / "t").mkdir(exist_ok=True)
    (root / "t" / "wv.csv").write_text(TABLE, encoding="utf-8")
    (root / "s.json").write_text(json.dumps({"fig41": {"N": {"mc_mean": 1.000037518}},
                                             "outage": [160.0, 210.0]}), encoding="utf-8")
    (root / "counts.json").write_text(json.dumps(
        {"counts": {"sim2.gmwm.label_switched.SIN": {"value": 13, "definition": "d",
                                                     "source": "x"}}}), encoding="utf-8")
    md = root / "REPRODUCTION.md"
    md.write_text(page, encoding="utf-8")
    return md


def test_find_quotes_kinds_in_order(tmp_path):
    q = find_quotes(PAGE)
    assert [(x.kind, x.quote) for x in q] == [
        ("cell", "0.9376"), ("cell", "0.912"), ("cell", "0.938"), ("cell", "80.8"),
        ("cell", "25"), ("cell", "1.00004"), ("count", "13"), ("untraced", "145"),
        ("untraced", "2.8")]
    assert q[7].selector == "no per-replicate K readings" and q[8].selector == ""
    assert q[0].source == "t/wv.csv" and q[5].selector == "fig41/N/mc_mean"


def test_cell_value_selectors_and_errors(tmp_path):
    write_page(tmp_path)
    wv = tmp_path / "t" / "wv.csv"
    assert cell_value(wv, "method=rdvg&level=15&col=ratio_to_equal") == pytest.approx(0.9376293)
    assert cell_value(wv, "level=15.0&col=ratio_to_equal&agg=max") == pytest.approx(0.9376293)
    assert cell_value(wv, "col=share&agg=min&abs=1&mul=100") == pytest.approx(25.0)
    assert cell_value(wv, "level<15&col=ratio_to_equal") == pytest.approx(1.0797508)
    assert cell_value(wv, "col=share&agg=mean") == pytest.approx((0.808 + 0.25 - 0.75) / 3)
    assert cell_value(wv, "method=rdvg&col=level&agg=sum") == 29.0
    assert cell_value(wv, "method=rdvg&level=15&col=ratio_to_equal&over.level=14") == \
        pytest.approx(0.9376293 / 1.0797508)
    assert cell_value(wv, "method=svo_w2&level=15&col=share&over.method=rdvg&abs=1&mul=100") == \
        pytest.approx(300.0)
    assert cell_value(wv, "method=rdvg&level=15&col=share&less.method=svo_w2&abs=1") == \
        pytest.approx(1.0)
    assert cell_value(wv, "method=rdvg&level=14&col=ratio_to_equal&minus=share") == \
        pytest.approx(1.0797508 - 0.808)
    assert cell_value(wv, "col=level&plus=share&agg=sum") == pytest.approx(44 + 0.308)
    with pytest.raises(InputError, match="no column 'x'"):
        cell_value(wv, "method=rdvg&level=14&col=share&plus=x")
    for sel, msg in [("level=15&col=share&over.level=14", "2 rows"),
                     ("method=rdvg&level=15&col=share&over.gyro=1", "must replace a key"),
                     ("method=rdvg&level=15&col=share&over.level=14&less.level=14", "not both"),
                     ("method=rdvg&level=15&col=share&over.level=16", "no row")]:
        with pytest.raises(InputError, match=msg):
            cell_value(wv, sel)
    assert cell_value(wv, "level>=15&col=ratio_to_equal&agg=min") == pytest.approx(0.9123718)
    with pytest.raises(InputError, match="not a number"):
        cell_value(wv, "level<x&col=share")
    assert cell_value(tmp_path / "s.json", "fig41/N/mc_mean&mul=2") == pytest.approx(2.000075)
    for sel, msg in [("level=15&col=ratio_to_equal", "2 rows"), ("method=x&col=share", "no row"),
                     ("method=rdvg&level=15&col=nope", "no column"),
                     ("nokey=1&col=share", "no key column"),
                     ("col=share&agg=median", "min, max, mean or sum"), ("col", "not key=value")]:
        with pytest.raises(InputError, match=msg):
            cell_value(wv, sel)
    assert cell_value(tmp_path / "s.json", "outage/1") == 210.0
    with pytest.raises(InputError, match="no key '2'"):
        cell_value(tmp_path / "s.json", "outage/2")
    with pytest.raises(InputError, match="no key 'M'"):
        cell_value(tmp_path / "s.json", "fig41/M/mc_mean")
    with pytest.raises(InputError, match="table not found"):
        cell_value(tmp_path / "none.csv", "col=share")


def test_check_quotes_fails_on_a_changed_digit(tmp_path):
    md = write_page(tmp_path)
    quotes, bad = check_quotes(md)
    assert len(quotes) == 9 and bad == []
    for old, new in [("[0.9376]", "[0.9377]"), ("[80.8]", "[80.9]"), ("[1.00004]", "[1.00001]"),
                     ("[13]", "[15]"), ("level=15&col=ratio", "level=16&col=ratio")]:
        _, bad = check_quotes(write_page(tmp_path, PAGE.replace(old, new, 1)))
        assert len(bad) == 1, (old, bad)
    assert bad[0].value is None and "no row" in bad[0].counts_file


def committed_md() -> Path:
    md = REPORTS / "REPRODUCTION.md"
    if not md.is_file():
        pytest.skip("no reports/REPRODUCTION.md")
    return md


def test_committed_reproduction_quotes_match_their_tables():
    """Every count and table-cell marker of reports/REPRODUCTION.md equals its committed value at
    the quoted precision; every untraced marker is listed in the page's own section."""
    md = committed_md()
    quotes, bad = check_quotes(md)
    assert bad == [], "\n".join(f"line {b.line}: [{b.quote}] {b.name} = {b.value} ({b.counts_file})"
                                for b in bad)
    kinds = [q.kind for q in quotes]
    assert kinds.count("cell") > 0
    if "untraced" in kinds:  # the list they link to exists and states their number
        m = re.search(r'<a id="untraced"></a>(\d+) numbers on this page are marked not traceable',
                      md.read_text(encoding="utf-8"))
        assert m is not None, "no untraced section"
        assert int(m.group(1)) == kinds.count("untraced"), (
            f"the untraced section says {m.group(1)}, the page has {kinds.count('untraced')}")


def test_a_changed_digit_in_a_committed_quote_fails(tmp_path):
    """A copy of the committed page (beside copies of the tables it cites) with one digit of one
    plain-text quote changed fails the check: the quoted-number test catches a stale number
    (cell markers at the page's start, middle and end, a count marker, and a marker with each
    option that combines cells)."""
    md = committed_md()
    text = md.read_text(encoding="utf-8")
    quotes = find_quotes(text)
    cells = [q for q in quotes if q.kind == "cell"]
    if not cells:
        pytest.skip("no cell markers yet")
    picks = [cells[0], cells[len(cells) // 2], cells[-1]]
    picks += [next(q for q in quotes if q.kind == "count")]
    for option in ("over.", "less.", "plus=", "agg=sum"):  # a marker of each kind of option
        picks += [q for q in cells if option in q.selector][:1]
    for q in picks:
        marker = f"[{q.quote}]({q.source}#{q.selector})"
        assert marker in text
        last = re.search(r"\d(?=\D*$)", q.quote)
        assert last is not None
        i = last.start()
        changed = q.quote[:i] + str((int(q.quote[i]) + 1) % 10) + q.quote[i + 1:]
        copy = tmp_path / "reports" / "REPRODUCTION.md"
        copy.parent.mkdir(exist_ok=True)
        dst = copy.parent / q.source
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(md.parent / q.source, dst)
        if q.kind == "count":  # the values are in the counts.json beside the counts.md
            shutil.copy((md.parent / q.source).with_suffix(".json"), dst.with_suffix(".json"))
        lines = text.split("\n")  # on the quote's own line: the same marker may also be shown
        lines[q.line - 1] = lines[q.line - 1].replace(  # as an example in a code span above
            marker, f"[{changed}]({q.source}#{q.selector})", 1)
        copy.write_text("\n".join(lines), encoding="utf-8")
        _, bad = check_quotes(copy)
        assert any(b.quote == changed and b.value is not None for b in bad), (q, changed)


@pytest.mark.parametrize("quote, value, want", [
    ("0.9376", 0.93812, "0.9381"), ("37", 145, "145"), ("80.8", 79.96, "80.0"),
    ("0.99", 0.9996, "1.0"), ("0.0123", 0.009871, "0.00987"), ("1.12e-9", 1.2345e-9, "1.23e-9"),
    ("1.0E+03", 2345.0, "2.3E+03"), ("\u22120.5", -0.4444, "\u22120.4"), ("+3.1", 3.04, "+3.0"),
])
def test_format_like_keeps_precision_and_notation(quote, value, want):
    assert format_like(quote, value) == want


def test_refresh_check_fixes_and_keeps_precision(tmp_path, capsys):
    """A changed digit (a stale quote) fails --check without writing; refresh rewrites it, and
    the count link, at the quote's precision; the page then checks clean."""
    stale = (PAGE.replace("[0.9376]", "[0.9377]", 1).replace("[13]", "[15]", 1)
             .replace("[80.8]", "[79]", 1))
    md = write_page(tmp_path, stale)
    assert main(["refresh", str(md), "--check"]) == 1
    out = capsys.readouterr().out
    assert "[0.9377] -> [0.9376]" in out and "[15] -> [13]" in out and "3 stale" in out
    assert md.read_text(encoding="utf-8") == stale  # --check writes nothing
    assert main(["refresh", str(md)]) == 0
    text = md.read_text(encoding="utf-8")
    assert "[0.9376](t/wv.csv#method=rdvg" in text and "[13](counts.md#" in text
    assert "[81](t/wv.csv#level=14" in text  # 2 significant digits kept (79 -> 81, not 80.8)
    assert "[145](#untraced" in text  # untraced markers are not touched
    assert check_quotes(md)[1] == []
    assert main(["refresh", str(md), "--check"]) == 0
    changes, errors = refresh_quotes(md)
    assert changes == [] and errors == []


def test_refresh_follows_a_changed_table(tmp_path):
    md = write_page(tmp_path)
    wv = tmp_path / "t" / "wv.csv"
    wv.write_text(TABLE.replace("0.9376293", "0.9412001"), encoding="utf-8")
    new, changes, errors = plan_refresh(md.read_text(encoding="utf-8"), tmp_path)
    assert errors == []
    assert [(c.line, c.old, c.new) for c in changes] == [(5, "0.9376", "0.9412"),
                                                         (5, "0.938", "0.941")]
    assert "ratio_to_equal&agg=min)-[0.941](t/wv.csv" in new  # the range's end, same line
    assert new.count("\n") == PAGE.count("\n")


def test_refresh_names_the_line_and_link_of_a_vanished_cell(tmp_path, capsys):
    md = write_page(tmp_path, PAGE.replace("[0.9376]", "[0.9377]", 1))
    (tmp_path / "t" / "wv.csv").write_text(TABLE.replace("rdvg,15,", "rdvg,16,"),
                                           encoding="utf-8")
    before = md.read_text(encoding="utf-8")
    _, errors = refresh_quotes(md)
    assert md.read_text(encoding="utf-8") == before  # a broken link: nothing written
    assert errors and errors[0].startswith(
        "line 5: [0.9377](t/wv.csv#method=rdvg&level=15&col=ratio_to_equal): ")
    assert "no row" in errors[0]
    (tmp_path / "counts.json").write_text('{"counts": {}}', encoding="utf-8")
    assert main(["refresh", str(md)]) == 1
    err = capsys.readouterr().err
    assert "line 7: [13](counts.md#sim2.gmwm.label_switched.SIN): no count" in err
    assert "left unchanged" in err and "Traceback" not in err
    assert md.read_text(encoding="utf-8") == before
    assert main(["refresh", str(tmp_path / "none.md")]) == 1
    assert "page not found" in capsys.readouterr().err


def test_plain_numbers_leave_out_the_classes_that_stay_plain():
    text = """# Fig 7 of paper 004 (1.5 in a heading)

| item | paper's claim | reproduction |
|---|---|---|
| Fig 4 | peak 1.1789 at 209 s | peak [1.267](t/wv.csv#col=x) at 209.9 s, T = 1e4, AR1 and SIN[2] |

Run of 2026-11-26 05:26:46 at 46fd1ec, `code 3.5`, [link](a/b2.csv), ratio (= 1 - x) 0.42;
Simulation 2 quotes 0.8549-0.9922 and 37 of 500[^n2], 0 of 500 replicates at 1.6e5;
to 1.4e3; lower by (= 1 - ratio) 5.8 % and 7.6 %; 1.3-5.0 SDs (= (1/6 - mean) / SD) | 2.5
m = 4096 / 8192 / 16384, (phi, theta) = (0.9, -0.5), (0.99, 0); S(f) = (1 +- 0.5 cos(2 pi f)).
At the boundary 0 in [304](counts.md#x) of 500, nominal 95 % and a 95 % CI; 0 of 1000.
"""
    found = [(p.line, p.text) for p in plain_numbers(text)]
    assert found == [(5, "209.9"), (8, "0.8549"), (8, "0.9922"), (8, "37"), (8, "500"),
                     (8, "0"), (9, "1.4e3"), (9, "2.5"), (11, "0"), (11, "1000")]
    p = plain_numbers(text)[0]
    assert text.splitlines()[p.line - 1][p.start:].startswith("209.9 s")


def test_committed_reproduction_has_no_unlinked_number(capsys):
    """Every number of reports/REPRODUCTION.md is a checked link, an untraced marker or in a
    class that stays plain (the papers' own numbers, design values, computed clauses marked
    "(= ...)"): a number quoted as plain text fails here, so a changed digit in a quote cannot
    pass unchecked; unlinking a committed quote is caught the same way."""
    md = committed_md()
    text = md.read_text(encoding="utf-8")
    plain = plain_numbers(text)
    lines = text.splitlines()
    assert not plain, "plain-text numbers not linked to their source:\n" + "\n".join(
        f"  line {p.line}: {p.text!r} in ...{lines[p.line - 1][max(0, p.start - 50):p.start + 20]}"
        for p in plain)
    with capsys.disabled():
        print(f"\n{md.name}: {len(find_quotes(text))} linked numbers, none unlinked")
    raised = []
    for q in [q for q in find_quotes(text) if q.kind == "cell"][:10]:
        marker = f"[{q.quote}]({q.source}#{q.selector})"
        raised.append(len(plain_numbers(text.replace(marker, q.quote, 1))) - len(plain))
    assert set(raised) <= {0, 1} and 1 in raised, raised  # 0: the quote is in a plain class


def test_a_seven_digit_number_is_not_taken_for_a_commit():
    """Commits (7-40 hex digits with a letter) stay plain; an all-digit number of that length is a
    number (a count of 1107083 samples quoted without a link is caught)."""
    found = [p.text for p in plain_numbers("Run of 51db49f: 1107083 samples kept, 0.5 of them.\n")]
    assert found == ["1107083", "0.5"]
