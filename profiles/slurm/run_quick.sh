#!/usr/bin/env bash
# Run the quick profile through the SLURM executor (after setup_local_slurm.sh, or on a real
# cluster from the repository root), then print what SLURM ran:
#   bash profiles/slurm/run_quick.sh [extra snakemake args]
# Outputs go to results/quick/ (config/quick.yaml: outdir), like the local quick run; the
# executor's own logs to results/quick/.snakemake/slurm_logs/. Prints the number of SLURM jobs
# and an `sacct` excerpt of them.
set -euo pipefail
cd "$(dirname "$0")/../.."

start=$(date +%Y-%m-%dT%H:%M:%S)
t0=$(date +%s)
python -m snakemake --profile profiles/slurm --configfile config/quick.yaml "$@"
t1=$(date +%s)
echo "run_quick.sh: snakemake finished in $((t1 - t0)) s"

# every job the run submitted (one SLURM job per Snakemake job; localrules ran on this host)
sacct -X -S "$start" -n -P -o JobID,JobName,Partition,Account,AllocCPUS,State,ExitCode,Elapsed \
    > results/quick/sacct.txt
echo "run_quick.sh: $(wc -l < results/quick/sacct.txt) SLURM jobs," \
     "$(grep -c '|COMPLETED|' results/quick/sacct.txt || true) COMPLETED; per rule:"
python - <<'EOF'
import collections, json, re
from pathlib import Path
rules = collections.Counter()
for log in Path("results/quick/.snakemake/slurm_logs").glob("rule_*/**/*.log"):
    rules[log.parts[3].removeprefix("rule_")] += 1
print(json.dumps(dict(sorted(rules.items()))))
EOF
sacct -X -S "$start" -o JobID,JobName%36,Partition,AllocCPUS,State,ExitCode,Elapsed | head -n 14
