#!/usr/bin/env bash
# ci/vm/socketcan-tests.sh [--direct] [TEST-FILTER...]: the tests that need a real vcan0: the
# SocketCAN link's (scanhil-protocol) and `scanhil-emulator serve` as a process on the bus.
#
# Builds the test binaries of each package in SUITES on the host with the cargo features in
# SCANHIL_VCAN_FEATURES (default "vcan": the tests that need a live vcan0; each package has the
# feature) and its cargo target selection (scanhil-protocol: "--test link_socketcan_vcan";
# scanhil-emulator: "--test serve_vcan"; SCANHIL_VCAN_CARGO_TARGETS, e.g. "--tests" for every
# test target, replaces both), finds them through cargo's --message-format=json, and runs them:
#   - by default inside the throwaway VM of ci/vcan-vm.sh (vcan0 is created there);
#   - with --direct right here, on a host whose kernel has CAN and whose vcan0 is up
#     (sudo modprobe vcan; sudo ip link add dev vcan0 type vcan; sudo ip link set up vcan0).
# TEST-FILTER arguments (default: SCANHIL_VCAN_TEST_FILTER, else "vcan") go to each test binary
# as libtest filters (substrings of the test path): by default only the tests with "vcan" in
# their path run, e.g. `link::socketcan::vcan::frames_round_trip` in a `mod vcan` behind
# `#[cfg(feature = "vcan")]`; the rest of the crate's tests run on the host anyway.
# Fails when a test fails, when no test ran at all, or when the VM fails.
set -euo pipefail

repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd -P)
readonly FEATURES=${SCANHIL_VCAN_FEATURES:-vcan}
# Each package with its vcan test targets: "PACKAGE CARGO-TARGET-ARGS...".
readonly SUITES=(
    "scanhil-protocol ${SCANHIL_VCAN_CARGO_TARGETS:---test link_socketcan_vcan}"
    "scanhil-emulator ${SCANHIL_VCAN_CARGO_TARGETS:---test serve_vcan}"
)

# Guest half: runs each binary (up to --) with the filters after it; exits 1 if any failed.
in_vm() {
    local binaries=()
    while [[ $1 != -- ]]; do binaries+=("$1"); shift; done
    shift
    local binary status=0
    for binary in "${binaries[@]}"; do
        echo "socketcan-tests: running ${binary#"$repo"/} $*"
        "$binary" "$@" || status=1
    done
    exit "$status"
}

fail() {
    echo "socketcan-tests: FAILED: $*" >&2
    exit 1
}

# The test executables cargo builds for each of SUITES with $FEATURES, one a line.
build_test_binaries() {
    command -v python3 >/dev/null 2>&1 || fail "python3 is needed to read cargo's JSON messages"
    local suite package targets
    for suite in "${SUITES[@]}"; do
        read -r package targets <<<"$suite"
        read -r -a targets <<<"$targets"
        echo "socketcan-tests: cargo test -p $package --features $FEATURES ${targets[*]} --no-run" >&2
        cargo test -p "$package" --features "$FEATURES" "${targets[@]}" --no-run --message-format=json
    done |
        python3 -c '
import json, sys
for line in sys.stdin:
    try:
        message = json.loads(line)
    except ValueError:
        continue
    if message.get("reason") == "compiler-artifact" and message.get("executable") \
            and message["profile"]["test"]:
        print(message["executable"])
'
}

# The cargo target folder, shared into the VM when it lies outside the repository.
target_directory() {
    cargo metadata --no-deps --format-version 1 |
        python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])'
}

host() {
    local direct=0
    if [[ ${1:-} == --direct ]]; then
        direct=1
        shift
    fi
    local filters=("$@")
    if ((${#filters[@]} == 0)); then
        read -r -a filters <<<"${SCANHIL_VCAN_TEST_FILTER:-vcan}"
    fi
    cd "$repo"
    local binaries=()
    mapfile -t binaries < <(build_test_binaries)
    # (The process substitution hides cargo's status: an empty list is the sign of a failed build.)
    ((${#binaries[@]} == ${#SUITES[@]})) || [[ -n ${SCANHIL_VCAN_CARGO_TARGETS:-} ]] ||
        fail "cargo built ${#binaries[@]} test binaries for ${#SUITES[@]} suites (--features $FEATURES): a build failed"
    ((${#binaries[@]} > 0)) || fail "cargo built no test binary (--features $FEATURES)"

    log=$(mktemp)
    trap 'rm -f "$log"' EXIT
    local status=0
    if ((direct)); then
        ip link show vcan0 >/dev/null 2>&1 ||
            fail "--direct needs a vcan0 on this host: sudo modprobe vcan && sudo ip link add dev vcan0 type vcan && sudo ip link set up vcan0"
        (in_vm "${binaries[@]}" -- "${filters[@]}") | tee "$log" || status=$?
    else
        local share=${SCANHIL_VM_SHARE:-} target
        target=$(target_directory)
        [[ $target == "$repo" || $target == "$repo"/* ]] || share="$share $target"
        echo "socketcan-tests: ci/vcan-vm.sh ci/vm/socketcan-tests.sh --in-vm ${#binaries[@]} binaries -- ${filters[*]}" >&2
        SCANHIL_VM_SHARE=$share "$repo/ci/vcan-vm.sh" ci/vm/socketcan-tests.sh --in-vm \
            "${binaries[@]}" -- "${filters[@]}" | tee "$log" || status=$?
    fi
    ((status == 0)) || fail "exit status $status (see the output above)"
    # libtest prints one "test result: ok. N passed; ..." line per binary.
    local passed
    passed=$(sed -n 's/^test result: ok\. \([0-9]*\) passed.*/\1/p' "$log" | awk '{ sum += $1 } END { print sum + 0 }')
    ((passed > 0)) || fail "no test ran (features '$FEATURES', filters '${filters[*]}'): nothing was checked"
    echo "socketcan-tests: ok: $passed tests (filters '${filters[*]}') passed on a real vcan0 ($( ((direct)) && echo "this host" || echo "in the VM"))"
}

if [[ ${1:-} == --in-vm ]]; then
    shift
    in_vm "$@"
else
    host "$@"
fi
