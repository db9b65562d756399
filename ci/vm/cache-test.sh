#!/usr/bin/env bash
# Checks the VM's cache rules without a VM, a network or apt: the functions of fetch.sh and
# initramfs.sh run against a made-up cache in a temporary folder (the host's own bash, ip and
# libraries; /bin/true standing in for each can-utils program), with the archive builder and
# the package fetcher stubbed to record their calls.
#
# 1. The base initramfs is reused while nothing that goes in changes, and rebuilt when the
#    can-utils program list (in fetch.sh, outside the files the key hashes) changes.
# 2. A module added to modules.txt after the kernel cache was filled makes prepare_kernel
#    unpack the kernel package again (saying why) instead of using the stale cache, and
#    building the initramfs against such a cache fails with the script's own message naming
#    the module, not a bare `cp` error.
#
# Usage: ci/vm/cache-test.sh   (exit 0: every check passed; prints each check)
set -euo pipefail

VM_DIR=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd -P)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

failures=0
check() {
    local what=$1
    shift
    if "$@"; then
        printf 'cache-test: ok: %s\n' "$what"
    else
        printf 'cache-test: FAILED: %s\n' "$what" >&2
        failures=$((failures + 1))
    fi
}

# A made-up cache: userland with busybox and the can-utils programs, a kernel with every
# module of modules.txt.
make_cache() {
    local cache=$1
    mkdir -p "$cache/userland/usr/bin" "$cache/kernel/modules"
    : >"$cache/userland/.complete"
    printf '6.1.0-test\n' >"$cache/kernel/version"
    : >"$cache/kernel/.complete"
    local program
    for program in busybox candump cansend canplayer cangen canbusload cangw cansequence extra; do
        cp /bin/true "$cache/userland/usr/bin/$program"
    done
    local module
    while read -r module; do
        mkdir -p "$cache/kernel/modules/${module%/*}"
        : >"$cache/kernel/modules/$module"
    done < <(sed -e 's/#.*//' -e 's/[[:space:]]*$//' -e '/^$/d' "$VM_DIR/modules.txt")
}

# Runs "$@" in a subshell with the VM scripts sourced against cache $1 and script folder $2
# (fetch.sh from $2, so a test can change its program list), the builder and fetcher
# stubbed: each call is appended to $1/calls.
with_scripts() {
    local cache=$1 scripts=$2
    shift 2
    (
        VM_CACHE=$cache VM_DIR=$scripts VM_REFRESH=0 VM_FETCH_TIMEOUT_S=1
        say() {
            printf 'say: %s\n' "$*" >>"$VM_CACHE/calls"
            # The unpacking itself is not under test: stop where it would start.
            [[ $* != "unpacking kernel and modules from"* ]] || exit 0
        }
        die() {
            printf 'die: %s\n' "$*" >>"$VM_CACHE/calls"
            exit 125
        }
        # shellcheck source=fetch.sh
        source "$scripts/fetch.sh"
        # shellcheck source=initramfs.sh
        source "$scripts/initramfs.sh"
        build_initramfs() {
            printf 'build: %s\n' "${1##*/}" >>"$VM_CACHE/calls"
            : >"$1"
        }
        kernel_package_name() {
            printf 'kernel package asked\n' >>"$VM_CACHE/calls"
            printf 'linux-image-test\n'
        }
        fetch_debs() {
            printf 'fetch: %s\n' "$*" >>"$VM_CACHE/calls"
            printf '%s/debs/%s.deb\n' "$VM_CACHE" "$1"
        }
        "$@"
    )
}

# 1. The key follows the can-utils program list.
cache=$work/cache-1
make_cache "$cache"
scripts=$work/scripts
cp -r "$VM_DIR" "$scripts"
first=$(with_scripts "$cache" "$scripts" base_initramfs)
again=$(with_scripts "$cache" "$scripts" base_initramfs)
builds() { grep -c '^build:' "$cache/calls" || true; }
check "an unchanged input reuses the archive ($first)" \
    test "$first" = "$again" -a "$(builds)" = 1
sed -i 's/^readonly CAN_UTILS_PROGRAMS=(\(.*\))$/readonly CAN_UTILS_PROGRAMS=(\1 extra)/' "$scripts/fetch.sh"
grep -q 'cansequence extra)' "$scripts/fetch.sh" || {
    echo "cache-test: cannot edit the program list in fetch.sh (its form changed?)" >&2
    exit 1
}
changed=$(with_scripts "$cache" "$scripts" base_initramfs)
check "a program added to CAN_UTILS_PROGRAMS gives a new archive ($changed)" \
    test "$changed" != "$first" -a "$(builds)" = 2

# 2. A module added to modules.txt since the kernel cache was filled.
cache=$work/cache-2
make_cache "$cache"
scripts=$work/scripts-2
cp -r "$VM_DIR" "$scripts"
printf 'drivers/net/can/added-since.ko\n' >>"$scripts/modules.txt"
with_scripts "$cache" "$scripts" prepare_kernel
check "prepare_kernel says the module is missing and unpacks the kernel again" \
    grep -q 'say: the kernel cache has no drivers/net/can/added-since.ko .*unpacking the kernel package again' "$cache/calls"
check "... by fetching the kernel package (from the cache when it is there)" \
    grep -q '^fetch: linux-image-test$' "$cache/calls"
: >"$cache/calls"
status=0
(
    VM_CACHE=$cache VM_DIR=$scripts VM_REFRESH=0
    say() { :; }
    die() {
        printf 'die: %s\n' "$*" >>"$VM_CACHE/calls"
        exit 125
    }
    # shellcheck source=fetch.sh
    source "$scripts/fetch.sh"
    # shellcheck source=initramfs.sh
    source "$scripts/initramfs.sh"
    build_initramfs "$work/archive.cpio" "$(host_program bash)" "$(host_program ip)" -- 2>"$work/stderr"
) || status=$?
check "building against the stale cache fails (exit 125, got $status)" test "$status" = 125
check "... with the script's message naming the module" \
    grep -q 'die: the kernel cache .* has no module drivers/net/can/added-since.ko (listed in ci/vm/modules.txt)' "$cache/calls"
check "... and no bare cp error" bash -c "! grep -q '^cp:' '$work/stderr'"

if ((failures > 0)); then
    echo "cache-test: $failures check(s) failed" >&2
    exit 1
fi
echo "cache-test: all checks passed"
