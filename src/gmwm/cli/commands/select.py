"""``gmwm select``: rank candidate models of every requested channel by a wavelet information
criterion (:func:`gmwm.select.rank_models`)."""

from __future__ import annotations

import argparse
import time
from typing import Any, TextIO

from gmwm.cli.inputs import check_levels, read_signals, stream_wvs
from gmwm.cli.parser import EXIT_OK
from gmwm.formatting import json_text, table


def run(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from gmwm.model import Model
    from gmwm.select import auto_candidates, rank_models

    if args.auto:
        models: list[str] = []
        for base in args.models:
            models += [m for m in auto_candidates(base) if m not in models]
    else:
        models = []
        for m in args.models:  # model errors before reading the file
            spec = Model(m).spec
            models += [] if spec in models else [spec]
    # ranking needs the WV only (the drift sign does not enter it): streamed when large
    got = stream_wvs(args, err)
    streamed = got is not None
    if got is None:
        got = read_signals(args, err)
    options = {} if args.n_starts is None else {"n_starts": args.n_starts}
    rankings: dict[str, tuple[Any, float]] = {}
    robust = {"robust": True, "eff": args.eff} if args.robust else {}
    for col, x in got.data.items():
        if not streamed:
            check_levels(x.size, args.levels)
        where = "" if args.columns is None else f" [{col}]"

        def progress(i: int, n: int, spec: str, where: str = where) -> None:
            args.progress(f"select{where}: fitting candidate {i}/{n}: {spec}")

        t0 = time.perf_counter()
        r = rank_models(x, models, criterion=args.criterion, levels=args.levels,
                        freq=got.freq, weights=args.weights, seed=args.seed,
                        progress=progress, **robust, **options)
        rankings[col] = (r, time.perf_counter() - t0)

    def skipped(r: Any) -> list[dict[str, Any]]:
        return [{"model": e.model, "error": e.error} for e in r.skipped]

    if args.json:
        obj: dict[str, Any] = {"command": "select", "input": args.input,
                               "criterion": args.criterion, "robust": bool(args.robust),
                               "candidates": models}
        if args.columns is None:
            r, sec = next(iter(rankings.values()))
            obj.update(ranking=[e.to_json_dict() for e in r.ranked], penalty_factor=r.factor,
                       simplified=[st.to_json_dict() for st in r.simplified],
                       skipped=skipped(r), seconds=sec)
        else:
            obj["rankings"] = {c: [e.to_json_dict() for e in r.ranked]
                               for c, (r, _) in rankings.items()}
            obj["simplified"] = {c: [st.to_json_dict() for st in r.simplified]
                                 for c, (r, _) in rankings.items()}
            obj["skipped"] = {c: skipped(r) for c, (r, _) in rankings.items()}
            obj["seconds"] = {c: sec for c, (_, sec) in rankings.items()}
        out.write(json_text(obj))
    else:
        for col, (r, sec) in rankings.items():
            what = args.input if args.columns is None else f"{args.input} column {col}"
            out.write(f"model ranking for {what}: T = {r.wv.n_samples}, J = {r.wv.n_levels}, "
                      f"{args.criterion.upper()} = objective + {r.factor:.3g} x penalty"
                      f"{', robust WV' if args.robust else ''}; {len(models)} candidates, "
                      f"{sec:.2f} s\n")
            rows = [(i, e.model, e.criterion, e.objective, e.penalty, e.n_params,
                     "yes" if e.converged else "NO", e.p_value,
                     "REJECTED" if e.rejected(r.gof_alpha) else "")
                    for i, e in enumerate(r.ranked, 1)]
            out.write(table(["rank", "model", "criterion", "objective", "penalty",
                             "n_params", "converged", "GOF p", "GOF"], rows) + "\n")
            if any(e.rejected(r.gof_alpha) for e in r.ranked):
                out.write(f"candidates the goodness-of-fit test rejects at {r.gof_alpha:g} are "
                          "ranked below every accepted one, whatever their criterion\n")
            out.writelines(f"parsimony: {st.describe()}\n" for st in r.simplified)
            out.writelines(f"skipped {e.model}: {e.error}\n" for e in r.skipped)
    for col, (r, _) in rankings.items():
        if not r.best.converged:
            where = "" if args.columns is None else f" (column {col})"
            err.write(f"gmwm: warning: the best model {r.best.model}{where} did not converge; "
                      "treat the ranking with care\n")
    return EXIT_OK
