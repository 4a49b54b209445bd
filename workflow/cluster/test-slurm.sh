#!/usr/bin/env bash
# Run the smoke workflow through the Snakemake SLURM executor on a real, throw-away, single-node
# Slurm cluster on this machine, and check it against a local run of the same workflow.
#
#   sudo workflow/cluster/test-slurm.sh            # from the repository root, venv active
#
# What it does (exit 0 only if every step holds):
#   1. installs what is missing: Debian's slurm-wlm and munge (apt-get, needs root) and the
#      `slurm` extra of pyproject.toml (snakemake-executor-plugin-slurm) into the active Python;
#   2. starts munged, slurmctld and slurmd directly (no systemd, no slurmdbd), bound to
#      127.0.0.1, with a slurm.conf generated from this machine's hostname, cores and memory and
#      every state, spool, log and socket path under a scratch directory;
#   3. runs `snakemake TARGETS --configfile tests/smoke_config.yaml` (TARGETS: see
#      CRGPR_SLURM_TARGETS below) locally (profiles/default) and through Slurm (profiles/slurm,
#      plus the flags this accounting-free cluster needs and a 1 s status polling start), each
#      into its own directory under the scratch directory, each under `timeout`;
#   4. workflow/cluster/check_slurm_run.py checks that every job went through sbatch (a Slurm
#      job id, a per-job Slurm log, state COMPLETED in slurmctld's job-completion log, and the
#      CPUs, memory and time limit Slurm granted equal to the rule's threads, mem_mb, runtime),
#      and that the two runs' outputs are equal (see that script for the exact definition);
#   5. on exit, also on failure or Ctrl-C: cancels leftover jobs, stops slurmd, slurmctld and
#      munged by their PIDs, checks that none is left, removes the scratch directory.
#
# Exit codes: 0 all checks hold, 77 skipped (not root; slurm-wlm/munge missing and no apt-get
# or not installable; the slurm extra not installable; /etc/slurm/slurm.conf taken), anything
# else a failure.
# Environment: CRGPR_SLURM_TARGETS: the Snakemake targets of both runs, separated by blanks, or
# @FILE for the targets listed in FILE (one a line, `#` comments; relative to the repository
# root); default `all` (the whole smoke workflow, 78 jobs). CI uses
# @workflow/cluster/ci_targets.txt (a 16-job sub-DAG through every stage kind).
# CRGPR_SLURM_TIMEOUT (seconds for each of the two runs, default 1200),
# CRGPR_SLURM_KEEP=1 keeps the scratch directory, CRGPR_SLURM_SCRATCH sets its parent (/tmp),
# CRGPR_SLURM_LOCAL_RUN=DIR puts the local run in DIR instead (kept; Snakemake only runs what is
# missing there, so a finished local run is reused; one made at another commit fails the
# code_version comparison).
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
TIMEOUT=${CRGPR_SLURM_TIMEOUT:-1200}
TARGETS_SPEC=${CRGPR_SLURM_TARGETS:-all}
T_START=$(date +%s)
declare -A TIMINGS=()
TIMING_ORDER=()
PIDS=()            # daemons we started, stopped in reverse order
SCRATCH=""
SLURM_UP=0
DEFAULT_CONF=/etc/slurm/slurm.conf
CONF_LINK=""       # the symlink we made at DEFAULT_CONF, removed on exit

log() { echo "test-slurm: $*"; }
die() { echo "test-slurm: FAIL: $*" >&2; exit 1; }
skip() { echo "test-slurm: SKIPPED: $*"; exit 77; }
step_start() { STEP_NAME=$1; STEP_T0=$(date +%s); log "== $1"; }
step_end() { TIMINGS[$STEP_NAME]=$(( $(date +%s) - STEP_T0 )); TIMING_ORDER+=("$STEP_NAME"); }

alive() { kill -0 "$1" 2>/dev/null; }

stop_pid() {  # stop_pid PID NAME: SIGTERM, wait up to 15 s, then SIGKILL
    local pid=$1 name=$2 i
    alive "$pid" || return 0
    kill -TERM "$pid" 2>/dev/null || true
    for i in $(seq 1 30); do alive "$pid" || { wait "$pid" 2>/dev/null || true; return 0; }; sleep 0.5; done
    log "$name ($pid) ignored SIGTERM; sending SIGKILL"
    kill -KILL "$pid" 2>/dev/null || true
    wait "$pid" 2>/dev/null || true
}

cleanup() {
    local rc=$? i pid left=()
    trap - EXIT INT TERM
    set +e
    if [[ $SLURM_UP == 1 ]]; then
        # Jobs first (a killed slurmd leaves its job steps running), then the daemons.
        local jobs
        jobs=$(squeue -h -o %A 2>/dev/null)
        [[ -n $jobs ]] && scancel --quiet $jobs
        for i in $(seq 1 30); do
            [[ -z $(squeue -h -o %A 2>/dev/null) ]] && break; sleep 1
        done
        for pid in $(scontrol listpids 2>/dev/null | awk 'NR>1 {print $1}'); do
            [[ $pid =~ ^[0-9]+$ ]] && kill -KILL "$pid" 2>/dev/null
        done
    fi
    for (( i=${#PIDS[@]}-1; i>=0; i-- )); do
        stop_pid "${PIDS[$i]%%:*}" "${PIDS[$i]#*:}"
    done
    for i in "${PIDS[@]}"; do alive "${i%%:*}" && left+=("$i"); done
    if [[ -n $CONF_LINK && -L $CONF_LINK && $(readlink "$CONF_LINK") == "$SLURM_CONF" ]]; then
        rm -f "$CONF_LINK"
    fi
    # Any process still naming the scratch directory (a job's script) is ours and must not stay.
    if [[ -n $SCRATCH ]]; then
        for pid in $(pgrep -f -- "$SCRATCH/" 2>/dev/null); do
            [[ $pid == "$$" ]] && continue
            left+=("$pid:$(tr '\0' ' ' < "/proc/$pid/cmdline" 2>/dev/null | cut -c1-80)")
            kill -KILL "$pid" 2>/dev/null
        done
    fi
    if (( ${#left[@]} )); then
        echo "test-slurm: FAIL: still running: ${left[*]}" >&2; rc=1
    fi
    if [[ -n $SCRATCH && -d $SCRATCH ]]; then
        if [[ ${CRGPR_SLURM_KEEP:-0} == 1 || $rc != 0 ]]; then
            log "scratch directory kept: $SCRATCH"
        else
            rm -rf "$SCRATCH"
        fi
    fi
    log "timings [s]:"
    for i in "${TIMING_ORDER[@]}"; do printf 'test-slurm:   %-34s %5d\n' "$i" "${TIMINGS[$i]}"; done
    printf 'test-slurm:   %-34s %5d\n' "total" "$(( $(date +%s) - T_START ))"
    if [[ $rc == 0 ]]; then log "PASS"; elif [[ $rc != 77 ]]; then echo "test-slurm: FAIL (exit $rc)" >&2; fi
    exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

cluster_name() { echo crgprtest; }

# The body is one function, so that bash has read all of it before it runs (editing the file
# while it runs cannot change what runs).
main() {

# ---------------------------------------------------------------------------------------------
step_start "install (apt-get, pip)"
# Exit 77 (skipped) where this machine cannot host the test cluster at all.
[[ $(id -u) == 0 ]] || skip "needs root (apt-get, munged, slurmd)"
command -v python >/dev/null || die "no python on PATH: activate the project's venv first"
if ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null || ! command -v munged >/dev/null; then
    command -v apt-get >/dev/null || skip "slurm-wlm/munge missing and no apt-get"
    { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq slurm-wlm munge; } \
        > "/tmp/test-slurm-apt.$$.log" 2>&1 \
        || { tail -5 "/tmp/test-slurm-apt.$$.log"; skip "apt-get could not install slurm-wlm munge"; }
    rm -f "/tmp/test-slurm-apt.$$.log"
fi
# The plugin pin lives in one place: the `slurm` extra of pyproject.toml.
mapfile -t SLURM_EXTRA < <(python - "$ROOT/pyproject.toml" <<'EOF'
import sys, tomllib
with open(sys.argv[1], "rb") as f:
    print("\n".join(tomllib.load(f)["project"]["optional-dependencies"]["slurm"]))
EOF
)
if ! python -c 'import snakemake_executor_plugin_slurm' 2>/dev/null; then
    python -m pip install -q "${SLURM_EXTRA[@]}" > "/tmp/test-slurm-pip.$$.log" 2>&1 \
        || { tail -5 "/tmp/test-slurm-pip.$$.log"; rm -f "/tmp/test-slurm-pip.$$.log"
             skip "pip could not install the slurm extra (${SLURM_EXTRA[*]})"; }
    rm -f "/tmp/test-slurm-pip.$$.log"
fi
PLUGIN_VERSION=$(python -c 'from importlib.metadata import version; print(version("snakemake-executor-plugin-slurm"))')
log "slurm $(slurmctld -V | awk '{print $2}'), $(munged -V | awk '{print $1}'), snakemake $(snakemake --version), plugin $PLUGIN_VERSION"
step_end

# ---------------------------------------------------------------------------------------------
step_start "start munged, slurmctld, slurmd"
SCRATCH=$(mktemp -d "${CRGPR_SLURM_SCRATCH:-/tmp}/crgpr-slurm.XXXXXX")
chmod 755 "$SCRATCH"   # munged runs as the munge user and must reach its own directory
mkdir -p "$SCRATCH"/{etc,munge,munge-key,state,spool,log}
# munged (as the munge user) wants its own key directory (0700) and a socket directory that
# every client can traverse (0755)
chown munge:munge "$SCRATCH/munge" "$SCRATCH/munge-key"
chmod 755 "$SCRATCH/munge"
chmod 700 "$SCRATCH/munge-key"
MUNGE_KEY=$SCRATCH/munge-key/munge.key
mungekey --create --keyfile="$MUNGE_KEY" 2>/dev/null \
    || dd if=/dev/urandom of="$MUNGE_KEY" bs=1 count=1024 status=none
chown munge:munge "$MUNGE_KEY"
chmod 400 "$MUNGE_KEY"
MUNGE_SOCKET=$SCRATCH/munge/munge.socket
setpriv --reuid=munge --regid=munge --init-groups munged --foreground \
    --key-file="$MUNGE_KEY" --socket="$MUNGE_SOCKET" \
    --pid-file="$SCRATCH/munge/munged.pid" --log-file="$SCRATCH/munge/munged.log" \
    --seed-file="$SCRATCH/munge/munged.seed" > "$SCRATCH/log/munged.out" 2>&1 &
PIDS+=("$!:munged")
for _ in $(seq 1 50); do [[ -S $MUNGE_SOCKET ]] && break; sleep 0.2; done
[[ -S $MUNGE_SOCKET ]] || { cat "$SCRATCH/log/munged.out" >&2 || true; die "munged did not start"; }

# Free TCP ports on loopback for slurmctld and slurmd (another Slurm may use 6817/6818).
read -r CTLD_PORT SLURMD_PORT < <(python - <<'EOF'
import socket
socks = [socket.socket() for _ in range(2)]
for s in socks:
    s.bind(("127.0.0.1", 0))
print(*(s.getsockname()[1] for s in socks))
EOF
)
HOST=$(hostname -s)
CPUS=$(nproc)
MEM_MB=$(( $(awk '/MemTotal/ {print int($2 / 1024)}' /proc/meminfo) - 1024 ))
export SLURM_CONF=$SCRATCH/etc/slurm.conf
cat > "$SLURM_CONF" <<EOF
# generated by workflow/cluster/test-slurm.sh for a throw-away single-node test cluster
ClusterName=$(cluster_name)
SlurmctldHost=$HOST(127.0.0.1)
SlurmctldPort=$CTLD_PORT
SlurmdPort=$SLURMD_PORT
CommunicationParameters=NoInAddrAny,NoCtldInAddrAny
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$MUNGE_SOCKET
StateSaveLocation=$SCRATCH/state
SlurmdSpoolDir=$SCRATCH/spool
SlurmctldPidFile=$SCRATCH/state/slurmctld.pid
SlurmdPidFile=$SCRATCH/spool/slurmd.pid
SlurmctldLogFile=$SCRATCH/log/slurmctld.log
SlurmdLogFile=$SCRATCH/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/affinity
SwitchType=switch/none
MpiDefault=none
ReturnToService=2
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
DefMemPerCPU=1000
# squeue must still see a finished job when the plugin polls (>= 3 x the first-poll delay)
MinJobAge=300
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/filetxt
JobCompLoc=$SCRATCH/log/jobcomp.txt
NodeName=$HOST NodeAddr=127.0.0.1 CPUs=$CPUS RealMemory=$MEM_MB State=UNKNOWN
PartitionName=test Nodes=$HOST Default=YES MaxTime=INFINITE State=UP
EOF
# The job-step side of the plugin (snakemake-executor-plugin-slurm-jobstep) drops SLURM_CONF
# from the environment of the `srun` it runs inside each job, so srun must find the config at
# the default path: a symlink there, made only if there is none, removed on exit.
[[ -e $DEFAULT_CONF || -L $DEFAULT_CONF ]] && skip "$DEFAULT_CONF exists: this machine has its own Slurm"
mkdir -p "$(dirname "$DEFAULT_CONF")"
ln -s "$SLURM_CONF" "$DEFAULT_CONF"
CONF_LINK=$DEFAULT_CONF
slurmctld -D -c -f "$SLURM_CONF" > "$SCRATCH/log/slurmctld.out" 2>&1 &
PIDS+=("$!:slurmctld")
SLURM_UP=1
slurmd -D -f "$SLURM_CONF" -N "$HOST" > "$SCRATCH/log/slurmd.out" 2>&1 &
PIDS+=("$!:slurmd")
for _ in $(seq 1 60); do
    state=$(sinfo -h -N -o %T 2>/dev/null || true)
    [[ $state == idle ]] && break
    sleep 1
done
[[ ${state:-} == idle ]] || { tail -20 "$SCRATCH/log/slurmctld.log" "$SCRATCH/log/slurmd.log" >&2; die "node not idle (state: ${state:-none})"; }
log "node $HOST up: $CPUS CPUs, RealMemory=$MEM_MB MB, ports $CTLD_PORT/$SLURMD_PORT"
step_end

# ---------------------------------------------------------------------------------------------
if [[ $TARGETS_SPEC == @* ]]; then
    TARGETS_FILE=${TARGETS_SPEC#@}
    [[ $TARGETS_FILE == /* ]] || TARGETS_FILE=$ROOT/$TARGETS_FILE
    [[ -f $TARGETS_FILE ]] || die "CRGPR_SLURM_TARGETS: no file $TARGETS_FILE"
    mapfile -t TARGETS < <(sed -e 's/#.*//' -e 's/^[[:space:]]*//' -e 's/[[:space:]]*$//' "$TARGETS_FILE" | grep -v '^$')
else
    read -r -a TARGETS <<< "$TARGETS_SPEC"
fi
(( ${#TARGETS[@]} )) || die "CRGPR_SLURM_TARGETS names no target"
log "targets: ${TARGETS[*]}"
SMOKE=("${TARGETS[@]}" --snakefile "$ROOT/Snakefile" --configfile "$ROOT/tests/smoke_config.yaml")

run_timed() {  # run_timed NAME LOG CMD...: CMD under timeout, its output in LOG; die on failure
    local name=$1 out=$2 rc=0
    shift 2
    timeout --kill-after=30 "$TIMEOUT" "$@" > "$out" 2>&1 || rc=$?
    if [[ $rc != 0 ]]; then
        tail -40 "$out" >&2
        [[ $rc == 124 || $rc == 137 ]] && die "$name timed out (${TIMEOUT} s) or was stopped (exit $rc)"
        die "$name failed (exit $rc)"
    fi
}

LOCAL=${CRGPR_SLURM_LOCAL_RUN:-$SCRATCH/local}
step_start "local smoke run (-j$CPUS)"
run_timed "local smoke run" "$SCRATCH/local.log" \
    snakemake "${SMOKE[@]}" -d "$LOCAL" --workflow-profile "$ROOT/profiles/default" -j "$CPUS"
step_end

step_start "smoke run through the SLURM executor"
# For this cluster without accounting (no sacct): poll with squeue (the plugin accepts squeue
# only if MinJobAge >= 3 x the first-poll delay). First poll 1 s after a submission or after a
# poll that saw a job finish; the plugin adds 10 s to the delay after each poll that saw none
# finish (fixed in plugin 2.8, up to 180 s), so a job's end is noticed within its last delay.
run_timed "Slurm run" "$SCRATCH/slurm.log" \
    snakemake "${SMOKE[@]}" -d "$SCRATCH/slurm" \
    --workflow-profile "$ROOT/profiles/slurm" \
    --slurm-status-command squeue --slurm-init-seconds-before-status-checks 1 \
    --seconds-between-status-checks 1 --slurm-keep-successful-logs
step_end

# ---------------------------------------------------------------------------------------------
step_start "checks"
python "$ROOT/workflow/cluster/check_slurm_run.py" \
    --snakemake-log "$SCRATCH/slurm.log" --jobcomp "$SCRATCH/log/jobcomp.txt" \
    --slurm-logs "$SCRATCH/slurm/.snakemake/slurm_logs" \
    --local "$LOCAL" --cluster "$SCRATCH/slurm" --host "$HOST"
step_end
}

main "$@"
