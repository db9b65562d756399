#!/usr/bin/env bash
# ci/vcan-vm.sh COMMAND [ARG...]: run COMMAND in a throwaway QEMU VM whose kernel has CAN.
#
# The VM boots Debian's own kernel (fetched with apt-get download, never installed) from a small
# initramfs, loads the CAN modules, creates and brings up vcan0, mounts this repository over 9p
# at the same absolute path as on the host, and runs COMMAND in the directory this script was
# called from. The script exits with COMMAND's exit status. The command's stdout and stderr
# arrive on this script's stdout and stderr; kernel messages and this script's own lines go to
# stderr prefixed with "vcan-vm:".
#
# Exit status: COMMAND's own (0-255); 124 when the hard time limit killed the VM; 125 when the
# VM itself failed (could not be prepared, did not boot, crashed, lost the command's status).
# Those two cases always come with a "vcan-vm: VM FAILED:" line on stderr.
#
# Environment (all optional):
#   SCANHIL_VM_TIMEOUT=60       hard limit in seconds for the VM run (boot + command)
#   SCANHIL_VM_BOOT_TIMEOUT=30  limit in seconds until the guest is set up and the command starts
#   SCANHIL_VM_FETCH_TIMEOUT=300  limit in seconds for each apt-get update / download, and for
#                               waiting on another run that holds the cache's lock
#   SCANHIL_VM_CACHE=DIR        cache of packages and images (${XDG_CACHE_HOME:-~/.cache}/scanhil-vm)
#   SCANHIL_VM_REFRESH=1        re-resolve and re-fetch packages even when cached
#   SCANHIL_VM_ACCEL=auto       tcg, kvm, or auto (kvm where the CPU has vmx/svm, /dev/kvm is
#                               usable and a KVM boot works; otherwise tcg)
#   SCANHIL_VM_CPUS=1           virtual CPUs (one boots fastest under TCG on a busy host)
#   SCANHIL_VM_MEMORY_MB=512    guest memory
#   SCANHIL_VM_VCAN="vcan0"     vcan interfaces to create (space-separated)
#   SCANHIL_VM_SHARE="DIR ..."  more host folders to mount at their paths (the repository always is)
#   SCANHIL_VM_ENV="NAME ..."   more host variables to pass to COMMAND
#   SCANHIL_VM_QEMU=PATH        the qemu-system-x86_64 to use (default: the host's, else Debian's)
#   SCANHIL_VM_VERBOSE=1        also show the QEMU command line, the guest's markers and timings
# COMMAND sees PATH, HOME=/root, USER=root, SHELL=/bin/bash, TERM (dumb unless stdout is a
# terminal), SCANHIL_IN_VM=1, the host's RUST_BACKTRACE, RUST_LOG, RUST_TEST_THREADS and other
# RUST_* test settings, NO_COLOR, TZ, LANG, LC_ALL and SCANHIL_* (not SCANHIL_VM_*) when set.
# Its stdin is /dev/null; its stdout/stderr are terminals only where the host's are.
# Also: ci/vcan-vm.sh --prepare (fetch and build only), ci/vcan-vm.sh --help.
set -euo pipefail
# (Under pipefail, no pipeline here may stop reading early (head, grep -q, awk's exit): the
# writer's SIGPIPE would fail it now and then.)
shopt -s inherit_errexit

VM_DIR=$(cd "$(dirname "${BASH_SOURCE[0]}")/vm" && pwd -P)
REPO_ROOT=$(cd "$VM_DIR/../.." && pwd -P)
readonly VM_DIR REPO_ROOT
readonly VM_CACHE=${SCANHIL_VM_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/scanhil-vm}
readonly VM_REFRESH=${SCANHIL_VM_REFRESH:-0}
readonly VM_TIMEOUT_S=${SCANHIL_VM_TIMEOUT:-60}
readonly VM_BOOT_TIMEOUT_S=${SCANHIL_VM_BOOT_TIMEOUT:-30}
readonly VM_FETCH_TIMEOUT_S=${SCANHIL_VM_FETCH_TIMEOUT:-300}
readonly VM_ACCEL=${SCANHIL_VM_ACCEL:-auto}
readonly VM_CPUS=${SCANHIL_VM_CPUS:-1}
readonly VM_MEMORY_MB=${SCANHIL_VM_MEMORY_MB:-512}
readonly VM_VCAN=${SCANHIL_VM_VCAN:-vcan0}
readonly VM_VERBOSE=${SCANHIL_VM_VERBOSE:-0}

# Exit statuses of the script itself (beside the command's own).
readonly EXIT_TIMEOUT=124
readonly EXIT_VM_FAILED=125

say() { printf 'vcan-vm: %s\n' "$*" >&2; }
verbose() { [[ $VM_VERBOSE == 1 ]] && say "$@"; return 0; }
die() {
    printf 'vcan-vm: VM FAILED: %s\n' "$*" >&2
    exit "$EXIT_VM_FAILED"
}

# shellcheck source=vm/fetch.sh
source "$VM_DIR/fetch.sh"
# shellcheck source=vm/initramfs.sh
source "$VM_DIR/initramfs.sh"

usage() {
    sed -n '2,/^set -euo/{/^set -euo/d;s/^# \{0,1\}//;p}' "${BASH_SOURCE[0]}"
}

# Checks the numeric settings, so that a typo fails here and not as a confusing QEMU error.
check_settings() {
    local setting value
    for setting in SCANHIL_VM_TIMEOUT:$VM_TIMEOUT_S SCANHIL_VM_BOOT_TIMEOUT:$VM_BOOT_TIMEOUT_S \
        SCANHIL_VM_FETCH_TIMEOUT:$VM_FETCH_TIMEOUT_S \
        SCANHIL_VM_CPUS:$VM_CPUS SCANHIL_VM_MEMORY_MB:$VM_MEMORY_MB; do
        value=${setting#*:}
        [[ $value =~ ^[1-9][0-9]*$ ]] || die "${setting%%:*} must be a positive whole number, not '$value'"
    done
    command -v timeout >/dev/null 2>&1 || die "the host has no timeout (coreutils)"
    case $VM_ACCEL in auto | tcg | kvm) ;; *) die "SCANHIL_VM_ACCEL must be auto, tcg or kvm, not '$VM_ACCEL'" ;; esac
    local interface
    for interface in $VM_VCAN; do
        [[ $interface =~ ^[A-Za-z0-9_.-]{1,15}$ ]] || die "SCANHIL_VM_VCAN: '$interface' is not an interface name"
    done
}

# Fetches and builds everything (under a lock: several runs may share the cache); sets
# KERNEL_IMAGE, BASE_INITRAMFS, BUSYBOX and QEMU_CMD.
prepare() {
    mkdir -p "$VM_CACHE" || die "cannot create the cache folder $VM_CACHE"
    command -v flock >/dev/null 2>&1 || die "the host has no flock (util-linux)"
    exec {lock_fd}>"$VM_CACHE/.lock"
    flock -w "$VM_FETCH_TIMEOUT_S" "$lock_fd" ||
        die "another run held the cache lock $VM_CACHE/.lock for over ${VM_FETCH_TIMEOUT_S} s (SCANHIL_VM_FETCH_TIMEOUT)"
    # Scratch folders of an interrupted or failed earlier run (none is in use: we hold the lock).
    rm -rf "$VM_CACHE"/.kernel.* "$VM_CACHE"/.userland.* "$VM_CACHE"/.qemu.* "$VM_CACHE"/.initramfs.* \
        "$VM_CACHE"/debs/.download.*
    prepare_qemu
    prepare_kernel
    prepare_userland
    BASE_INITRAMFS=$(base_initramfs)
    exec {lock_fd}>&-
    KERNEL_IMAGE=$VM_CACHE/kernel/vmlinux
    BUSYBOX=$(userland_busybox)
    verbose "QEMU: ${QEMU_CMD[*]} ($QEMU_ORIGIN)"
    verbose "kernel $(<"$VM_CACHE/kernel/version"), initramfs $BASE_INITRAMFS"
}

# Host variables the command sees besides PATH, HOME, USER, SHELL and TERM: what steers Rust
# programs and tests, the project's own settings, and the names in SCANHIL_VM_ENV.
forwarded_environment() {
    local name
    for name in RUST_BACKTRACE RUST_LIB_BACKTRACE RUST_LOG RUST_TEST_THREADS RUST_TEST_NOCAPTURE \
        RUST_MIN_STACK NO_COLOR CLICOLOR CLICOLOR_FORCE TZ LANG LC_ALL ${SCANHIL_VM_ENV:-} \
        $(compgen -e SCANHIL_ | grep -v '^SCANHIL_VM_' || true); do
        [[ -v $name ]] && printf '%s=%s\0' "$name" "${!name}"
    done
    return 0
}

# The shared folders: the repository and SCANHIL_VM_SHARE, physical paths, parents first,
# folders inside another shared folder dropped (they are visible already).
shared_folders() {
    local folder physical folders=()
    for folder in "$REPO_ROOT" ${SCANHIL_VM_SHARE:-}; do
        physical=$(cd "$folder" 2>/dev/null && pwd -P) || die "SCANHIL_VM_SHARE: no folder $folder"
        folders+=("$physical")
    done
    local sorted=() kept=() candidate parent inside
    mapfile -t sorted < <(printf '%s\n' "${folders[@]}" | awk '{ print length($0) "\t" $0 }' | sort -n | cut -f2- | uniq)
    for candidate in "${sorted[@]}"; do
        inside=0
        for parent in "${kept[@]}"; do
            [[ $candidate == "$parent" || $candidate == "$parent"/* ]] && inside=1
        done
        [[ $candidate == / ]] && die "SCANHIL_VM_SHARE: sharing / is not supported"
        ((inside)) || kept+=("$candidate")
    done
    printf '%s\n' "${kept[@]}"
}

# Writes the job archive for command "${@:2}" to $1 (see ci/vm/init for the files).
write_job() {
    local archive=$1
    shift
    local job=$RUN_DIR/job/etc/scanhil-vm
    mkdir -p "$job"
    printf '%s\0' "$@" >"$job/argv"
    local cwd
    cwd=$(pwd -P)
    local folders=() folder inside=0 listed
    listed=$(shared_folders)
    mapfile -t folders <<<"$listed"
    for folder in "${folders[@]}"; do
        [[ $cwd == "$folder" || $cwd == "$folder"/* ]] && inside=1
    done
    ((inside)) || die "the current folder $cwd is not visible in the VM: run from inside $REPO_ROOT or add it to SCANHIL_VM_SHARE"
    printf '%s\0' "$cwd" >"$job/cwd"
    printf '%s\0' "${folders[@]}" >"$job/shares"
    SHARED_FOLDERS=("${folders[@]}")
    local interface
    : >"$job/vcan"
    for interface in $VM_VCAN; do printf '%s\0' "$interface" >>"$job/vcan"; done
    local stdout_kind=pipe stderr_kind=pipe term=dumb
    [[ -t 1 ]] && stdout_kind='tty' && term=${TERM:-dumb}
    [[ -t 2 ]] && stderr_kind='tty'
    printf '%s %s\n' "$stdout_kind" "$stderr_kind" >"$job/stdio"
    {
        printf '%s\0' PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin \
            HOME=/root USER=root LOGNAME=root SHELL=/bin/bash "TERM=$term" SCANHIL_IN_VM=1
        forwarded_environment
    } >"$job/env"
    (cd "$RUN_DIR/job" && find . -mindepth 1 | LC_ALL=C sort | "$BUSYBOX" cpio -o -H newc 2>/dev/null) >"$archive" ||
        die "writing the job archive failed"
}

# Chooses the accelerator: sets ACCEL_ARGS and ACCEL_NAME for attempt $1 (1 or 2).
choose_accel() {
    local attempt=$1
    local kvm_possible=0
    if grep -q -w -E 'vmx|svm' /proc/cpuinfo 2>/dev/null && [[ -r /dev/kvm && -w /dev/kvm ]]; then
        kvm_possible=1
    fi
    case $VM_ACCEL in
        kvm)
            [[ -e /dev/kvm ]] || die "SCANHIL_VM_ACCEL=kvm but there is no /dev/kvm"
            ACCEL_NAME=kvm ;;
        tcg) ACCEL_NAME=tcg ;;
        auto) if ((kvm_possible && attempt == 1)) && [[ ! -f $VM_CACHE/kvm-broken ]]; then
                  ACCEL_NAME=kvm
              else
                  ACCEL_NAME=tcg
              fi ;;
    esac
    if [[ $ACCEL_NAME == kvm ]]; then
        ACCEL_ARGS=(-accel kvm -cpu host)
    else
        # -cpu max gives RDRAND, so the guest's getrandom() does not wait at boot.
        ACCEL_ARGS=(-accel tcg -cpu max)
    fi
}

# Boots the VM once for the job in $RUN_DIR; sets VM_OUTCOME (ready/no-ready), QEMU_STATUS,
# BOOT_TIMED_OUT, READY_AFTER_S.
boot_vm() {
    local initrd=$RUN_DIR/initrd.cpio
    cat "$BASE_INITRAMFS" "$RUN_DIR/job.cpio" >"$initrd"
    local fifo
    for fifo in console stdout stderr; do
        rm -f "$RUN_DIR/$fifo"
        mkfifo "$RUN_DIR/$fifo"
    done
    : >"$RUN_DIR/console.log"
    rm -f "$RUN_DIR/ready"

    local share_args=() index
    for index in "${!SHARED_FOLDERS[@]}"; do
        share_args+=(-virtfs "local,path=${SHARED_FOLDERS[index]},mount_tag=share$index,security_model=none,id=share$index")
    done
    local qemu=(
        "${QEMU_CMD[@]}" -nodefaults -no-user-config -display none -no-reboot
        -machine pc "${ACCEL_ARGS[@]}" -smp "$VM_CPUS" -m "$VM_MEMORY_MB"
        -kernel "$KERNEL_IMAGE" -initrd "$initrd"
        -append "console=ttyS0 quiet loglevel=4 panic=-1 8250.nr_uarts=4 mitigations=off"
        -chardev "file,id=console,path=$RUN_DIR/console" -serial chardev:console
        -chardev "file,id=stdout,path=$RUN_DIR/stdout" -serial chardev:stdout
        -chardev "file,id=stderr,path=$RUN_DIR/stderr" -serial chardev:stderr
        -device isa-debug-exit,iobase=0xf4,iosize=0x04
        "${share_args[@]}"
    )
    verbose "running: ${qemu[*]}"

    # Readers first: QEMU opens each FIFO for writing and waits for its reader.
    cat "$RUN_DIR/stdout" &
    local stdout_reader=$!
    cat "$RUN_DIR/stderr" >&2 &
    local stderr_reader=$!
    read_console <"$RUN_DIR/console" &
    local console_reader=$!

    local start=$EPOCHREALTIME
    timeout --kill-after=5 "$VM_TIMEOUT_S" "${qemu[@]}" </dev/null >"$RUN_DIR/qemu.log" 2>&1 &
    QEMU_PID=$!

    # Boot watchdog: a guest that is not set up in time is stopped (and told apart from a
    # command that runs long).
    BOOT_TIMED_OUT=0
    local boot_limit=$VM_BOOT_TIMEOUT_S
    [[ $ACCEL_NAME == kvm && $VM_ACCEL == auto ]] && boot_limit=10
    while kill -0 "$QEMU_PID" 2>/dev/null && [[ ! -f $RUN_DIR/ready ]]; do
        if (($(elapsed_ms "$start") > boot_limit * 1000)); then
            BOOT_TIMED_OUT=1
            kill "$QEMU_PID" 2>/dev/null || true
            break
        fi
        sleep 0.05
    done
    QEMU_STATUS=0
    wait "$QEMU_PID" || QEMU_STATUS=$?
    QEMU_PID=
    # A QEMU that failed before opening its FIFOs leaves the readers waiting in open(): a
    # momentary writer lets them see the end.
    local release
    for fifo in console stdout stderr; do
        exec {release}<>"$RUN_DIR/$fifo"
        exec {release}>&-
    done
    wait "$console_reader" "$stdout_reader" "$stderr_reader" || true
    TOTAL_S=$(seconds "$(elapsed_ms "$start")")
    if [[ -f $RUN_DIR/ready ]]; then
        VM_OUTCOME=ready
        READY_AFTER_S=$(seconds "$(($(<"$RUN_DIR/ready") - ${start/./} / 1000))")
    else
        VM_OUTCOME=no-ready
    fi
}

# Milliseconds since $EPOCHREALTIME value $1.
elapsed_ms() {
    local now=$EPOCHREALTIME
    echo $(((${now/./} - ${1/./}) / 1000))
}

# Milliseconds $1 as seconds with one decimal.
seconds() {
    printf '%d.%d' $(($1 / 1000)) $(($1 % 1000 / 100))
}

# Reads the guest console: keeps it in console.log, notes when the guest is ready, and shows
# the kernel's lines on stderr (all lines when verbose).
read_console() {
    local line now
    while IFS= read -r line || [[ -n $line ]]; do
        line=${line%$'\r'}
        printf '%s\n' "$line" >>"$RUN_DIR/console.log"
        case $line in
            "scanhil-vm: ready "*)
                now=$EPOCHREALTIME
                echo $((${now/./} / 1000)) >"$RUN_DIR/ready"
                verbose "guest: ${line#scanhil-vm: }" ;;
            "scanhil-vm: exit-status "*) verbose "guest: ${line#scanhil-vm: }" ;;
            "scanhil-vm: setup failed: "*) ;;
            "") ;;
            *) printf 'vcan-vm: console: %s\n' "$line" >&2 ;;
        esac
    done
}

# Keeps the logs of a failed run where the user can read them, and shows QEMU's own messages
# (the console's lines were shown as they came).
keep_console_log() {
    cp "$RUN_DIR/console.log" "$VM_CACHE/last-console.log" 2>/dev/null || true
    cp "$RUN_DIR/qemu.log" "$VM_CACHE/last-qemu.log" 2>/dev/null || true
    if [[ -s $RUN_DIR/qemu.log ]]; then
        say "QEMU said:"
        sed 's/^/vcan-vm:   /' "$RUN_DIR/qemu.log" | tail -n 20 >&2
    fi
    say "logs kept: guest console $VM_CACHE/last-console.log, QEMU $VM_CACHE/last-qemu.log"
}

# Turns the finished boot into this script's exit status (printed), explaining failures.
judge_run() {
    local marker setup_failure
    marker=$(sed -n 's/^scanhil-vm: exit-status \([0-9]*\)$/\1/p' "$RUN_DIR/console.log" | tail -n 1)
    setup_failure=$(sed -n 's/^scanhil-vm: setup failed: //p' "$RUN_DIR/console.log" | tail -n 1)
    local status=$EXIT_VM_FAILED failure=
    if ((BOOT_TIMED_OUT)); then
        failure="the VM did not boot: the guest was not set up within ${VM_BOOT_TIMEOUT_S} s (SCANHIL_VM_BOOT_TIMEOUT, accelerator $ACCEL_NAME)"
    elif [[ $QEMU_STATUS == 124 || $QEMU_STATUS == 137 ]]; then
        status=$EXIT_TIMEOUT
        failure="timed out: the VM was killed after ${VM_TIMEOUT_S} s (SCANHIL_VM_TIMEOUT) while running: $COMMAND_TEXT"
    elif [[ -n $setup_failure ]]; then
        failure="the guest could not be set up: $setup_failure"
    elif [[ -z $marker && $VM_OUTCOME == ready ]]; then
        failure="the VM stopped (QEMU exit status $QEMU_STATUS) without reporting the command's exit status: guest crash or kernel panic"
    elif [[ -z $marker ]]; then
        failure="the VM did not boot (QEMU exit status $QEMU_STATUS)"
    elif ((QEMU_STATUS != (((marker << 1) | 1) & 255))); then
        failure="the guest reported exit status $marker but QEMU exited $QEMU_STATUS, not $((((marker << 1) | 1) & 255)) (isa-debug-exit): the status is not trustworthy"
    fi
    if [[ -n $failure ]]; then
        keep_console_log
        printf 'vcan-vm: VM FAILED: %s\n' "$failure" >&2
        echo "$status"
    else
        verbose "'$COMMAND_TEXT' exited $marker (guest ready after $READY_AFTER_S s, VM ran $TOTAL_S s, $ACCEL_NAME)"
        echo "$marker"
    fi
}

cleanup() {
    [[ -n ${QEMU_PID:-} ]] && kill "$QEMU_PID" 2>/dev/null
    [[ -n ${RUN_DIR:-} ]] && rm -rf "$RUN_DIR"
    return 0
}

main() {
    case ${1:-} in
        "" | -h | --help)
            usage
            [[ -n ${1:-} ]] && exit 0
            exit 2 ;;
        --prepare)
            check_settings
            prepare
            say "ready: QEMU ($QEMU_ORIGIN), kernel $(<"$VM_CACHE/kernel/version"), cache $VM_CACHE"
            exit 0 ;;
    esac
    check_settings
    COMMAND_TEXT=$*
    prepare
    RUN_DIR=$(mktemp -d "${TMPDIR:-/tmp}/scanhil-vm.XXXXXX")
    trap cleanup EXIT
    trap 'exit 130' INT
    trap 'exit 143' TERM
    write_job "$RUN_DIR/job.cpio" "$@"

    local status
    choose_accel 1
    boot_vm
    if [[ $VM_OUTCOME != ready && $ACCEL_NAME == kvm && $VM_ACCEL == auto ]]; then
        say "KVM did not boot the guest here (nested virtualisation?); using TCG from now on (remembered in $VM_CACHE/kvm-broken; delete it to try KVM again)"
        : >"$VM_CACHE/kvm-broken"
        choose_accel 2
        boot_vm
    fi
    status=$(judge_run)
    exit "$status"
}

main "$@"
