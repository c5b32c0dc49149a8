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
status=0
mkdir -p results/quick
python -m snakemake --profile profiles/slurm --configfile config/quick.yaml "$@" 2>&1 \
    | tee results/quick/slurm_run.log || status=$?
t1=$(date +%s)
echo "run_quick.sh: snakemake exited with status ${status} after $((t1 - t0)) s"

# every job the run submitted (one SLURM job per Snakemake job; localrules ran on this host)
sacct -X -S "$start" -n -P -o JobID,JobName,Partition,Account,AllocCPUS,State,ExitCode,Elapsed \
    > results/quick/sacct.txt
echo "run_quick.sh: $(wc -l < results/quick/sacct.txt) SLURM jobs," \
     "$(grep -c '|COMPLETED|' results/quick/sacct.txt || true) COMPLETED," \
     "$(grep -c '^localrule ' results/quick/slurm_run.log || true) local jobs; SLURM jobs per rule:"
grep -o 'submitted with SLURM jobid [0-9]* (log: [^)]*/rule_[A-Za-z0-9_]*' results/quick/slurm_run.log \
    | sed 's|.*/rule_||' | sort | uniq -c || true
sacct -X -S "$start" -o JobID,JobName%36,Partition,AllocCPUS,State,ExitCode,Elapsed | head -n 14
exit "${status}"
