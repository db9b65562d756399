#!/usr/bin/env bash
# ci/vm/ci-step.sh: the VM step of .ci/run: everything that needs a real vcan0, in a throwaway
# QEMU VM (ci/vcan-vm.sh). Prints each command before it runs and how long it took; the first
# failure (a test, or the VM itself) fails the step. Nothing is skipped: a machine that cannot
# fetch QEMU or the kernel fails here with the reason.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."

step_start=$EPOCHREALTIME

# Runs "$@" as one step, framed by what ran and how long it took.
step() {
    echo "==> vm step: $*" >&2
    local start=$EPOCHREALTIME
    "$@"
    echo "<== vm step: $1 ok in $(elapsed_s "$start") s" >&2
}

# Seconds (one decimal) since $EPOCHREALTIME value $1.
elapsed_s() {
    local now=$EPOCHREALTIME
    local ms=$(((${now/./} - ${1/./}) / 1000))
    printf '%d.%d' $((ms / 1000)) $((ms % 1000 / 100))
}

# Fetch (cold: about 15 s) and build the VM's kernel, QEMU and initramfs.
step ci/vcan-vm.sh --prepare
# The harness itself: exit status, stdout/stderr, a candump/cansend round trip, panic, timeout.
step ci/vm/selftest.sh
# The SocketCAN link's own tests on vcan0.
step ci/vm/socketcan-tests.sh
# The loop over socketcan:vcan0 (emulator and controller as two processes, candump beside them),
# decoded with cantools on the host and compared bit for bit with the same scan over pty links.
step ci/vm/loop-vcan.sh

echo "<== vm step: all ok in $(elapsed_s "$step_start") s" >&2
