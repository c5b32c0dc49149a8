# The fleet workflow of `gmwm fleet` (gmwm.fleet.run): one `calibrate` job per recording, then
# the fleet table. Run in OUT (--directory OUT) with --config fleet_config=OUT/.fleet/config.json,
# which `gmwm fleet` writes (gmwm.fleet.run.prepare). Not meant to be run by hand, but
# `gmwm fleet ... --dry-run` shows what it would do.
#
# Incremental: run with --rerun-triggers params input; a calibrate job's params are its
# recording's content hash and the settings' hash (not time stamps: a touched file reruns nothing,
# a changed one its job). The table depends on every recording's status.json.
# Cluster: `group: "calibrate"` lets a profile bundle many recordings into one submission
# (e.g. --group-components calibrate=50 in the profile).

import json

CFG = json.load(open(config["fleet_config"]))
RECS = CFG["recordings"]
PY = CFG["python"]
CONFIG = config["fleet_config"]

wildcard_constraints:
    unit=r"[^/]+",
    rec=r"[^/]+",

localrules: all, fleet_table

rule all:
    input: "fleet.json"

rule calibrate:
    input:
        settings=".fleet/settings.json",
    output: "units/{unit}/{rec}/status.json"
    params:
        sha256=lambda w: RECS[f"{w.unit}/{w.rec}"]["sha256"],
        settings=CFG["settings_sha256"],
    group: "calibrate"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    shell:
        "{PY:q} -m gmwm.fleet.job calibrate --config {CONFIG:q} --key {wildcards.unit:q}/{wildcards.rec:q}"

rule fleet_table:
    input:
        status=[f"units/{k}/status.json" for k in RECS],
        settings=".fleet/settings.json",
    output: "fleet.json", "fleet.csv", "fleet_summary.csv", "fleet.md", "fleet.html"
    params:
        settings=CFG["settings_sha256"],
        recordings=sorted(RECS),
    shell:
        "{PY:q} -m gmwm.fleet.job table --config {CONFIG:q}"
