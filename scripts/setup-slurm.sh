#!/usr/bin/env bash
# Installs Debian's Slurm (slurmctld, slurmd, the client commands) and MUNGE, which the Slurm
# executor's test needs to start its own single-node cluster (idempotent; needs root or sudo;
# scripts/setup.sh calls it).
# Nothing is started or configured here: the test writes its own slurm.conf and munge key in a
# temporary directory and stops every daemon it started.
set -euo pipefail
need=()
for cmd in slurmctld slurmd sbatch squeue scancel munged; do
  command -v "$cmd" >/dev/null 2>&1 || [ -x "/usr/sbin/$cmd" ] || need+=("$cmd")
done
if [ ${#need[@]} -eq 0 ]; then
  exit 0
fi
echo "setup-slurm: installing slurmctld slurmd slurm-client munge (missing: ${need[*]})" >&2
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  SUDO="sudo"
fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends slurmctld slurmd slurm-client munge >/dev/null
