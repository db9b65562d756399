#!/usr/bin/env bash
# ci/vm/selftest.sh: checks that ci/vcan-vm.sh keeps its promises, with three VM boots.
#
# 1. One boot runs the guest half of this script (--in-vm), which shows vcan0, records a
#    candump/cansend round trip into out/vm-selftest/candump.log in the shared repository,
#    writes a line to stdout and one to stderr, and exits 7. The host then checks: exit status
#    7 came through; stdout and stderr arrived separately; the recording is readable here and
#    holds exactly the frames sent, in candump -L format.
# 2. A kernel panic inside the VM is reported as a VM failure (125), never as success.
# 3. A command that outlives SCANHIL_VM_TIMEOUT is killed and reported (124).
# Prints what it checks; exits non-zero with the reason on the first broken promise.
set -euo pipefail

repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd -P)
vm=$repo/ci/vcan-vm.sh
out_dir=$repo/out/vm-selftest

# The frames the guest sends, in cansend syntax; candump -L writes them back the same way
# (upper-case hex), which the host compares line by line.
readonly FRAMES=(123#DEADBEEF 12345678#0102030405060708 7FF#R 000# 1ABCDEF0#R)
readonly EXPECTED_STATUS=7
# Frames the guest sends around them to know candump is recording (dropped by the host).
readonly PROBE=7FE#00 SENTINEL=7FD#FF

# The guest half: runs inside the VM, in the repository.
in_vm() {
    local dir=$1
    ip -details link show vcan0
    candump -L vcan0 >"$dir/candump.log" &
    local recorder=$!
    # candump needs a moment to open and bind its socket: poll with probe frames until one is
    # recorded (no fixed sleep), then send the frames, then a sentinel, and poll until the
    # sentinel is recorded (candump flushes each line). The host drops probes and sentinel.
    local tries=0
    until grep -q " vcan0 $PROBE\$" "$dir/candump.log" 2>/dev/null; do
        ((tries++ < 500)) || { echo "selftest: candump never recorded a probe" >&2; exit 1; }
        cansend vcan0 "$PROBE"
        sleep 0.01
    done
    local frame
    for frame in "${FRAMES[@]}"; do
        cansend vcan0 "$frame"
    done
    cansend vcan0 "$SENTINEL"
    tries=0
    until grep -q " vcan0 $SENTINEL\$" "$dir/candump.log"; do
        ((tries++ < 500)) || { echo "selftest: candump never recorded the sentinel" >&2; exit 1; }
        sleep 0.01
    done
    kill -INT "$recorder"
    wait "$recorder" || true
    echo "selftest: to stdout"
    echo "selftest: to stderr" >&2
    exit "$EXPECTED_STATUS"
}

fail() {
    echo "selftest: FAILED: $*" >&2
    exit 1
}

# Runs the VM with "$@" as the command, leaving its status in $status, stdout in
# $out_dir/stdout, stderr in $out_dir/stderr.
run_vm() {
    echo "selftest: running ci/vcan-vm.sh $*" >&2
    status=0
    "$vm" "$@" >"$out_dir/stdout" 2>"$out_dir/stderr" || status=$?
}

host() {
    rm -rf "$out_dir"
    mkdir -p "$out_dir"

    run_vm ci/vm/selftest.sh --in-vm "$out_dir"
    cat "$out_dir/stdout"
    [[ $status == "$EXPECTED_STATUS" ]] ||
        fail "the guest command exited $EXPECTED_STATUS but ci/vcan-vm.sh exited $status; its stderr: $(cat "$out_dir/stderr")"
    grep -q 'vcan0: <NOARP,UP,LOWER_UP>' "$out_dir/stdout" || fail "vcan0 is not up in the VM"
    grep -q '^ *vcan ' "$out_dir/stdout" || fail "ip -details does not show vcan0 as a vcan link"
    grep -qx 'selftest: to stdout' "$out_dir/stdout" || fail "the guest's stdout line did not reach stdout"
    grep -q 'selftest: to stderr' "$out_dir/stdout" && fail "the guest's stderr line arrived on stdout"
    grep -qx 'selftest: to stderr' "$out_dir/stderr" || fail "the guest's stderr line did not reach stderr"
    [[ -r $out_dir/candump.log ]] || fail "no candump log $out_dir/candump.log on the host"
    local line index=0 sentinel=0
    while IFS= read -r line; do
        [[ $line =~ ^\([0-9]+\.[0-9]{6}\)\ vcan0\ (.*)$ ]] ||
            fail "candump.log line $((index + 1)) is not candump -L format: $line"
        [[ ${BASH_REMATCH[1]} == "$PROBE" && $index == 0 ]] && continue
        [[ ${BASH_REMATCH[1]} == "$SENTINEL" && $index == "${#FRAMES[@]}" ]] && { sentinel=1; continue; }
        [[ ${BASH_REMATCH[1]} == "${FRAMES[index]:-<none>}" ]] ||
            fail "candump.log line $((index + 1)) is ${BASH_REMATCH[1]}, expected ${FRAMES[index]:-no more lines}"
        index=$((index + 1))
    done <"$out_dir/candump.log"
    ((sentinel == 1)) || fail "candump.log does not end with the sentinel $SENTINEL"
    ((index == ${#FRAMES[@]})) || fail "candump.log holds $index frames, expected ${#FRAMES[@]}"
    echo "selftest: ok: exit status $status came through, stdout/stderr apart, $index frames recorded over vcan0"

    run_vm sh -c 'echo c >/proc/sysrq-trigger'
    [[ $status == 125 ]] || fail "a kernel panic in the VM gave exit status $status, expected 125"
    grep -q 'VM FAILED: .*crash or kernel panic' "$out_dir/stderr" || fail "the panic was not reported as such"
    echo "selftest: ok: a kernel panic is reported as a VM failure (125)"

    SCANHIL_VM_TIMEOUT=6 run_vm sleep 60
    [[ $status == 124 ]] || fail "a command outliving SCANHIL_VM_TIMEOUT=6 gave exit status $status, expected 124"
    grep -q 'VM FAILED: timed out' "$out_dir/stderr" || fail "the timeout was not reported as such"
    echo "selftest: ok: a hung command is killed at SCANHIL_VM_TIMEOUT (124)"
}

if [[ ${1:-} == --in-vm ]]; then
    in_vm "$2"
else
    host
fi
