#!/usr/bin/env bash
# ci/vm/measure.sh [WARM_RUNS]: measures ci/vcan-vm.sh and prints JSON (the figures in
# docs/ci-vm.md).
#
# cold_s: a first run into an empty cache (fetching and unpacking QEMU, kernel, busybox,
#         can-utils; building the initramfs) up to the command's end; needs the network.
# warm_s: a run with everything cached (median of WARM_RUNS, default 5): prepare, boot, run
#         `true`, power off.
# ready_s / guest_uptime_s: medians of the host's time from starting QEMU until the guest
#         reports it is set up (vcan0 up, 9p mounted), and the guest's own uptime at that point.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
warm_runs=${1:-5}

cold_cache=$(mktemp -d "${TMPDIR:-/tmp}/scanhil-vm-cold.XXXXXX")
trap 'rm -rf "$cold_cache"' EXIT

# Seconds (three decimals) that "$@" takes.
timed() {
    local start=$EPOCHREALTIME
    "$@" >/dev/null
    local now=$EPOCHREALTIME
    local us=$((${now/./} - ${start/./}))
    printf '%d.%03d' $((us / 1000000)) $((us % 1000000 / 1000))
}

# The median of the numbers on stdin.
median() {
    sort -n | awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'
}

cold=$(SCANHIL_VM_CACHE=$cold_cache timed ci/vcan-vm.sh true 2>/dev/null)
warm=() ready=() uptime=()
for _ in $(seq "$warm_runs"); do
    warm+=("$(timed ci/vcan-vm.sh true)")
    log=$(SCANHIL_VM_VERBOSE=1 ci/vcan-vm.sh true 2>&1)
    ready+=("$(sed -n 's/.*guest ready after \([0-9.]*\) s.*/\1/p' <<<"$log")")
    uptime+=("$(sed -n 's/^vcan-vm: guest: ready \([0-9.]*\)$/\1/p' <<<"$log")")
done
cat <<EOF
{
  "cold_s": $cold,
  "warm_s": $(printf '%s\n' "${warm[@]}" | median),
  "ready_s": $(printf '%s\n' "${ready[@]}" | median),
  "guest_uptime_s": $(printf '%s\n' "${uptime[@]}" | median),
  "warm_runs": $warm_runs,
  "host_cpus": $(nproc),
  "vm_cpus": ${SCANHIL_VM_CPUS:-1},
  "host_load_1min": $(cut -d' ' -f1 /proc/loadavg),
  "accelerator": "$(sed -n 's/.*VM ran [0-9.]* s, \([a-z]*\)).*/\1/p' <<<"$log")"
}
EOF
