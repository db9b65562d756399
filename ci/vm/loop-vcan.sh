#!/usr/bin/env bash
# ci/vm/loop-vcan.sh [--direct] [OUT_DIR]: the loop over a real CAN bus, checked against the pty link.
#
# 1. Builds `scanhil` and `scanhil-emulator` on the host (debug, like `cargo test`).
# 2. On vcan0 (by default inside the throwaway VM of ci/vcan-vm.sh; with --direct on this host's
#    own vcan0): starts `candump -L vcan0` and waits until it listens, runs
#    `scanhil scan fixtures/scenarios/vcan-small.json` (the controller starts
#    `scanhil-emulator serve --fsm socketcan:vcan0 --sensor fsm` as a separate process; both
#    talk only over vcan0), then stops candump and waits for it to exit (its log is complete).
#    Output: OUT_DIR/vcan/ (the scan's folder) and OUT_DIR/vcan/candump.log.
# 3. On the host: the same scenario over the emulated pty links, twice: the mirror on SLCAN with
#    the sensor's Distance frames on it (OUT_DIR/pty-can/: the same frames as on vcan0), and the
#    default links, SLCAN plus the sensor's own ILD stream (OUT_DIR/pty-ild/).
# 4. ci/interop/vcan_loop_check.py (the .venv of ci/interop/venv.sh: cantools): every frame of
#    the capture decodes with protocol/scanhil.dbc, the sequence counters are gapless, the bus
#    carried exactly the controller's recorded frames, the ILD stream carried the same sensor
#    samples as the Distance frames, and the results of the three runs are bit-identical (that
#    script's doc says which files and fields, and why).
#
# OUT_DIR defaults to out/vcan (gitignored); its vcan/, pty-can/ and pty-ild/ are removed first. Exit status 0 when every check
# passed; the script prints how long each part took.
set -euo pipefail

repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd -P)
readonly SCENARIO=fixtures/scenarios/vcan-small.json
readonly IFACE=vcan0
# How long candump may take to bind to the interface.
readonly CANDUMP_START_S=10
# candump's socket receive buffer (SO_RCVBUFFORCE as root; else capped at net.core.rmem_max, and
# candump says so on stderr).
readonly CANDUMP_BUFFER_BYTES=16777216
# The VM's hard limit unless SCANHIL_VM_TIMEOUT says otherwise: the run takes about 17 s on a
# quiet host, the CPU-bound scan being some 70 times slower under TCG than on the host.
readonly VM_TIMEOUT_S=100

fail() {
    echo "loop-vcan: FAILED: $*" >&2
    exit 1
}

# Seconds (one decimal) since $EPOCHREALTIME value $1.
elapsed_s() {
    local now=$EPOCHREALTIME
    local ms=$(((${now/./} - ${1/./}) / 1000))
    printf '%d.%d' $((ms / 1000)) $((ms % 1000 / 100))
}

# Raw CAN receivers bound to $IFACE (rows of /proc/net/can/rcvlist_all).
receivers() {
    awk -v iface="$IFACE" '$1 == iface && $2 ~ /^[0-9A-Fa-f]+$/' /proc/net/can/rcvlist_all | wc -l
}

# The bus half, on a host or guest with $IFACE up: OUT SCANHIL EMULATOR.
on_bus() {
    local out=$1 scanhil=$2 emulator=$3
    ip link show "$IFACE" >/dev/null 2>&1 || fail "no $IFACE here"
    mkdir -p "$out/vcan"
    local before
    before=$(receivers)
    # A receive buffer for the whole run: candump must not drop a frame while the two programs
    # keep the (virtual) CPU busy (seen with 2 vCPUs and the default buffer: 3747 of 4005 frames).
    candump -L -r "$CANDUMP_BUFFER_BYTES" "$IFACE" >"$out/vcan/candump.log" &
    local candump=$!
    local waited=0
    while (($(receivers) <= before)); do
        kill -0 "$candump" 2>/dev/null || fail "candump -L $IFACE exited before it listened"
        ((waited++ < CANDUMP_START_S * 20)) || fail "candump did not bind to $IFACE within $CANDUMP_START_S s"
        sleep 0.05
    done
    local start=$EPOCHREALTIME status=0
    "$scanhil" scan "$SCENARIO" --out "$out/vcan" --emulator "$emulator" || status=$?
    echo "loop-vcan: scan over socketcan:$IFACE exited $status in $(elapsed_s "$start") s"
    # The last frame (the node's Status(ready)) reached the controller before the scan imaged
    # its result; candump, stopped by SIGINT, flushes its log and exits 0.
    kill -INT "$candump"
    local candump_status=0
    wait "$candump" || candump_status=$?
    ((candump_status == 0)) || fail "candump exited $candump_status"
    echo "loop-vcan: candump recorded $(wc -l <"$out/vcan/candump.log") frames on $IFACE"
    exit "$status"
}

host() {
    local direct=0
    if [[ ${1:-} == --direct ]]; then
        direct=1
        shift
    fi
    local out=${1:-out/vcan}
    cd "$repo"
    mkdir -p "$out"
    out=$(cd "$out" && pwd -P)
    [[ $out == "$repo"/* ]] || ((direct)) || fail "OUT_DIR $out must lie inside $repo (the VM sees only the repository)"
    if ((direct)); then
        ip link show "$IFACE" >/dev/null 2>&1 ||
            fail "--direct needs a $IFACE on this host: sudo modprobe vcan && sudo ip link add dev $IFACE type vcan && sudo ip link set up $IFACE"
        command -v candump >/dev/null || fail "--direct needs candump on this host (Debian/Ubuntu: sudo apt-get install can-utils)"
    fi
    rm -rf "$out/vcan" "$out/pty-can" "$out/pty-ild"

    local start=$EPOCHREALTIME
    cargo build --quiet -p scanhil-controller -p scanhil-emulator --bins
    local target
    target=$(cargo metadata --no-deps --format-version 1 |
        python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
    local scanhil=$target/debug/scanhil emulator=$target/debug/scanhil-emulator
    echo "loop-vcan: built in $(elapsed_s "$start") s"

    start=$EPOCHREALTIME
    if ((direct)); then
        (on_bus "$out" "$scanhil" "$emulator") || fail "the run on this host's $IFACE failed (exit status $?)"
    else
        local share=${SCANHIL_VM_SHARE:-}
        [[ $target == "$repo" || $target == "$repo"/* ]] || share="$share $target"
        SCANHIL_VM_SHARE=$share SCANHIL_VM_TIMEOUT=${SCANHIL_VM_TIMEOUT:-$VM_TIMEOUT_S} "$repo/ci/vcan-vm.sh" ci/vm/loop-vcan.sh --on-bus "$out" "$scanhil" "$emulator" ||
            fail "the run in the VM failed (exit status $?)"
    fi
    echo "loop-vcan: bus run ($( ((direct)) && echo "this host" || echo "VM")) took $(elapsed_s "$start") s"

    start=$EPOCHREALTIME
    "$scanhil" scan "$SCENARIO" --fsm pty --sensor fsm --out "$out/pty-can" --emulator "$emulator" >/dev/null ||
        fail "the scan over the pty link (sensor on the mirror link) failed"
    "$scanhil" scan "$SCENARIO" --fsm pty --sensor pty --out "$out/pty-ild" --emulator "$emulator" >/dev/null ||
        fail "the scan over the pty links (sensor on its ILD stream) failed"
    echo "loop-vcan: two pty runs took $(elapsed_s "$start") s"

    start=$EPOCHREALTIME
    ci/interop/venv.sh
    .venv/bin/python ci/interop/vcan_loop_check.py "$out" protocol/scanhil.dbc "$scanhil" ||
        fail "the checks of $out failed (see above)"
    echo "loop-vcan: checks took $(elapsed_s "$start") s (venv included)"
    echo "loop-vcan: ok: the loop over $IFACE ($( ((direct)) && echo "this host" || echo "in the VM")) decodes, is gapless and matches the pty link bit for bit"
}

if [[ ${1:-} == --on-bus ]]; then
    shift
    on_bus "$@"
else
    host "$@"
fi
