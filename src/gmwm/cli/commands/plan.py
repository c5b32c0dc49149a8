"""``gmwm plan``: before recording, the predicted precision of every coefficient by recording
length (:func:`gmwm.plan.make_plan`), from a sensor datasheet or a model with values."""

from __future__ import annotations

import argparse
from typing import Any, TextIO

import numpy as np

from gmwm.cli.inputs import model_theta
from gmwm.cli.outputs import save_plot
from gmwm.cli.parser import EXIT_OK, UsageError
from gmwm.errors import InputError
from gmwm.formatting import json_text, table


def run(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from gmwm.plan import DEFAULT_DURATIONS, make_plan, parse_duration, parse_target

    items = _plan_inputs(args)
    durations = [parse_duration(d) for d in (args.duration or DEFAULT_DURATIONS)]
    targets = [parse_target(t) for t in args.target]
    plans = []
    for item in items:
        args.progress(f"planning {item['name'] or item['model'].spec}")
        plans.append(make_plan(item["model"], item["theta"], sorted(durations), unit=item["unit"],
                               targets=targets, bi=item["bi"], notes=item["notes"],
                               labels=_plan_labels(item["model"], item["unit"], item["bi"])))
    if args.plot:
        from gmwm.plan import curve
        from gmwm.plots import channel_grid, plot_plan

        fig, axes = channel_grid(len(plans), ncols=2, panel=(4.6, 3.2))
        for ax, item, plan in zip(axes, items, plans, strict=True):
            secs, rse = curve(plan)
            plot_plan(secs, rse, plan, ax=ax)
            if item["name"]:
                ax.set_title(item["name"])
        save_plot(fig, args.plot)
    if args.json:
        objs = []
        for item, plan in zip(items, plans, strict=True):
            sheet = item["sheet"]
            objs.append({"command": "plan", **({"datasheet": {
                "part": sheet.part, "source": sheet.source, "file": sheet.path,
                "sensor": item["name"]}} if sheet is not None else {}), **plan.to_dict()})
        out.write(json_text(objs[0] if len(objs) == 1 else
                            {"command": "plan", "plans": {i["name"]: o for i, o in
                                                          zip(items, objs, strict=True)}}))
    else:
        out.write("\n\n".join(_plan_text(i, p) for i, p in zip(items, plans, strict=True)) + "\n")
    return EXIT_OK


def _plan_inputs(args: argparse.Namespace) -> list[dict[str, Any]]:
    """What to plan: per sensor (or the one model) the model, values, unit and notes."""
    from gmwm.units import parse_unit

    if (args.datasheet is None) == (args.model is None):
        raise UsageError("give a datasheet (--datasheet FILE) or a MODEL with -p values, not both")
    if args.datasheet is None:
        if args.sensor:
            raise UsageError("--sensor applies to --datasheet")
        if args.freq is None:
            raise UsageError("give the sampling frequency with --freq")
        unit = args.units
        if unit:
            parse_unit(unit)
        model, theta = model_theta(args.model, args.param, args.freq)
        return [{"name": None, "model": model, "theta": theta, "unit": unit or None,
                 "notes": [], "bi": None, "sheet": None}]
    if args.param:
        raise UsageError("-p gives the values of a MODEL; a datasheet carries its own")
    from gmwm.sensor_datasheet import load_datasheet, to_model

    sheet = load_datasheet(args.datasheet)
    freq = args.freq if args.freq is not None else sheet.rate
    if freq is None:
        raise UsageError(f"give the sampling frequency with --freq (the datasheet {sheet.where} "
                         "has no 'rate')")
    sensors = [args.sensor] if args.sensor else list(sheet.sensors)
    items = []
    for sensor in sensors:
        spec = sheet.sensor(sensor)
        unit = args.units
        if unit is not None:
            parsed = parse_unit(unit)
            if parsed is None or parsed[2] != sensor:
                if len(sensors) > 1:
                    raise UsageError(f"--units {unit} is not a {sensor} unit; with a datasheet "
                                     "of several sensors choose one with --sensor")
                raise InputError(f"--units {unit} is not a {sensor} unit")
        unit = unit or ("deg/s" if sensor == "gyroscope" else "m/s^2")
        dm = to_model(spec, freq, unit)
        notes = list(dm.notes)
        if args.freq is None:
            notes.insert(0, f"sampling frequency {freq:g} Hz from the datasheet's 'rate'")
        items.append({"name": sensor, "model": dm.model, "theta": dm.theta, "unit": unit,
                      "notes": notes, "bi": dm.bi, "sheet": sheet})
    return items


def _plan_labels(model: Any, unit: str | None, bi: str | None) -> dict[str, str]:
    """Component -> the name a datasheet gives it (ARW, RRW, ..., BI)."""
    from gmwm.units import unit_system

    us = unit_system(unit)
    names = {"WN": us.white_name, "RW": us.rw_name, "QN": "QN", "DR": "RR"}
    out = {}
    for c in model.components:
        if c.name == bi:
            out[c.name] = f"BI ({c.name})"
        elif c.process.name in names:
            out[c.name] = names[c.process.name]
        else:
            out[c.name] = c.name
    return out


def _fmt_precision(e: dict[str, Any]) -> str:
    rse, ci = e.get("rse"), e.get("ci95")
    if rse is None or not np.isfinite(rse):
        return "-"
    pct = f"{100 * rse:.2g}%" if rse < 0.1 else f"{100 * rse:.0f}%"
    # enough digits that the two ends of a narrow interval differ
    digits = max(3, 2 + int(np.ceil(-np.log10(max(2 * 1.96 * rse, 1e-15)))))
    return pct if not ci else f"{pct} [{ci[0]:.{digits}g}, {ci[1]:.{digits}g}]"


def _plan_text(item: dict[str, Any], plan: Any) -> str:
    from gmwm.plan import IDENTIFIABLE_RSE, format_duration

    model = plan.model
    sheet = item["sheet"]
    what = (f"{item['name']} of the datasheet {sheet.part}" if sheet is not None
            else f"model {model.spec}")
    lines = [f"recording plan for the {what} at {model.freq:g} Hz"
             + (f", signal in {plan.unit}" if plan.unit else "")
             + f": model {model.spec}, default fit ({plan.method.upper()}, {plan.weights} weights)"]
    lines += [f"note: {n}" for n in plan.notes]
    first = plan.predictions[0] if plan.predictions else None
    coefs = [k for k in (first.coefficients if first else {})
             if not (plan.bi and k == f"{plan.bi}.sigma")]
    rows = []
    for c in model.components:
        v = plan.min_length[c.name]
        rows.append((plan.labels.get(c.name, c.name), "> 30 d" if v is None else format_duration(v)))
    lines.append(f"identifiable from (each parameter's 95% Wald interval excludes 0, i.e. relative "
                 f"SE <= {100 * IDENTIFIABLE_RSE:.0f}%):")
    lines.append(table(["term", "length"], rows))
    if first is not None:
        lines.append("predicted relative standard error [95% interval] of the fit's coefficients:")
        headers = ["length", "samples", "J"] + [
            f"{k} [{first.coefficients[k]['unit']}]" if first.coefficients[k]["unit"] else k
            for k in coefs]
        trows = [(format_duration(p.seconds), p.n_samples, p.levels,
                  *(_fmt_precision(p.coefficients.get(k, {})) for k in coefs))
                 for p in plan.predictions]
        lines.append(table(headers, trows))
        vals = ", ".join(f"{k} = {first.coefficients[k]['value']:.4g}"
                         f"{' ' + first.coefficients[k]['unit'] if first.coefficients[k]['unit'] else ''}"
                         for k in coefs if first.coefficients[k]["value"] is not None)
        lines.append(f"(at the values {vals})")
    for t in plan.targets.values():
        lines.append(f"target {t['name']} to {100 * t['relative_se']:g}% (relative SE): record "
                     + (f"at least {t['duration']}" if t["seconds"] is not None
                        else f"longer than {t['duration'][2:]} (not reached)"))
    return "\n".join(lines)
