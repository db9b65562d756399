# shellcheck shell=bash
# Fetching what the throwaway VM needs, without installing anything system-wide.
#
# Sourced by ci/vcan-vm.sh. Debian packages are fetched with `apt-get download` into
# "$VM_CACHE/debs" and unpacked with dpkg-deb into folders of the cache; each unpacked folder
# gets a `.complete` stamp naming the packages in it, written last, so an interrupted run is
# redone instead of used half-done. Once a folder is complete it is used as is (no apt call,
# works offline); delete the cache folder (or set SCANHIL_VM_REFRESH=1) to pick up newer
# packages.
#
# Network steps (apt-get update, apt-get download) are each limited to VM_FETCH_TIMEOUT_S.
#
# Needs from the caller: VM_CACHE, VM_REFRESH, VM_FETCH_TIMEOUT_S, and the functions say and die.

# The package whose dependency names the current kernel image package.
readonly KERNEL_METAPACKAGE=linux-image-amd64

# Guest userland from Debian (the host's own bash and ip are added by initramfs.sh).
readonly USERLAND_PACKAGES=(busybox-static can-utils)

# can-utils programs the guest carries.
readonly CAN_UTILS_PROGRAMS=(candump cansend canplayer cangen canbusload cangw cansequence)

# True when folder $1 was completely unpacked by an earlier run (and no refresh is asked).
unpacked_complete() {
    [[ $VM_REFRESH != 1 && -f $1/.complete ]]
}

# Makes sure apt knows package $1, running `apt-get update` once when it does not.
ensure_apt_knows() {
    local package=$1
    if apt-cache show --no-all-versions "$package" >/dev/null 2>&1; then
        return 0
    fi
    refresh_apt_lists "apt does not know package $package"
    apt-cache show --no-all-versions "$package" >/dev/null 2>&1 ||
        die "apt has no package $package even after apt-get update (is a Debian bookworm source configured in /etc/apt/sources.list*?)"
}

# Runs `apt-get update` (once per run); reason $1 says why.
refresh_apt_lists() {
    [[ ${APT_LISTS_REFRESHED:-0} == 1 ]] && return 0
    say "$1: running apt-get update"
    local runner=()
    if [[ $(id -u) != 0 ]]; then
        command -v sudo >/dev/null 2>&1 ||
            die "$1, and apt-get update needs root: run 'sudo apt-get update' once"
        runner=(sudo -n)
    fi
    timeout "$VM_FETCH_TIMEOUT_S" "${runner[@]}" apt-get -q update >"$VM_CACHE/apt-update.log" 2>&1 ||
        die "apt-get update failed (log: $VM_CACHE/apt-update.log): $(tail -n 3 "$VM_CACHE/apt-update.log")"
    APT_LISTS_REFRESHED=1
}

# Downloads the candidate .deb of each package named in "$@" into $VM_CACHE/debs (skipping
# those already there) and prints the .deb paths, one a line, in argument order.
fetch_debs() {
    command -v apt-get >/dev/null 2>&1 && command -v dpkg-deb >/dev/null 2>&1 ||
        die "fetching $* needs apt-get and dpkg-deb (a Debian host with bookworm sources), or a cache filled elsewhere (SCANHIL_VM_CACHE)"
    local debs_dir=$VM_CACHE/debs
    mkdir -p "$debs_dir"
    local uris
    uris=$(apt-get download --print-uris "$@" 2>&1) || {
        refresh_apt_lists "apt cannot name the files of $*"
        uris=$(apt-get download --print-uris "$@" 2>&1) ||
            die "apt-get download --print-uris $* failed: $uris"
    }
    local files=() missing=() file
    while read -r _url file _size _hash; do
        [[ -n $file ]] || continue
        files+=("$file")
        [[ -f $debs_dir/$file ]] || missing+=("${file%%_*}")
    done <<<"$uris"
    [[ ${#files[@]} == "$#" ]] ||
        die "apt-get download --print-uris $* named ${#files[@]} files for $# packages: $uris"
    if ((${#missing[@]} > 0)); then
        say "downloading ${missing[*]}"
        download_into "$debs_dir" "${missing[@]}" || {
            # Stale lists on a CI image give 404s: refresh once and try again.
            refresh_apt_lists "apt-get download ${missing[*]} failed"
            download_into "$debs_dir" "${missing[@]}" ||
                die "apt-get download ${missing[*]} failed (log: $debs_dir/download.log): $(tail -n 3 "$debs_dir/download.log")"
            # The refresh may have changed the candidate versions: name the files again.
            fetch_debs "$@"
            return 0
        }
    fi
    for file in "${files[@]}"; do
        [[ -f $debs_dir/$file ]] || die "apt-get download did not leave $debs_dir/$file"
        printf '%s\n' "$debs_dir/$file"
    done
}

# Downloads packages "${@:2}" into folder $1 through a scratch folder, so that no partial
# .deb is ever left under its final name.
download_into() {
    local target=$1
    shift
    local scratch
    scratch=$(mktemp -d "$target/.download.XXXXXX")
    # apt-get download as root warns that it runs unsandboxed; the scratch folder is ours.
    if (cd "$scratch" && timeout "$VM_FETCH_TIMEOUT_S" apt-get -q download "$@") >"$target/download.log" 2>&1; then
        mv "$scratch"/*.deb "$target"/
        rm -rf "$scratch"
    else
        rm -rf "$scratch"
        return 1
    fi
}

# The kernel image package the metapackage currently depends on, e.g. linux-image-6.1.0-48-amd64.
kernel_package_name() {
    ensure_apt_knows "$KERNEL_METAPACKAGE"
    local name
    name=$(apt-cache depends "$KERNEL_METAPACKAGE" 2>/dev/null |
        awk '$1 == "Depends:" && $2 ~ /^linux-image-[0-9]/ && !found { print $2; found = 1 }')
    [[ -n $name ]] || die "cannot resolve the kernel package: 'apt-cache depends $KERNEL_METAPACKAGE' names no linux-image-<version> package"
    printf '%s\n' "$name"
}

# The module paths of ci/vm/modules.txt (comments and blank lines dropped).
module_list() {
    sed -e 's/#.*//' -e 's/[[:space:]]*$//' -e '/^$/d' "$VM_DIR/modules.txt"
}

# Prepares $VM_CACHE/kernel: vmlinux (uncompressed when the payload could be extracted,
# else the compressed vmlinuz), `version`, and modules/<path> for every entry of modules.txt.
prepare_kernel() {
    local dir=$VM_CACHE/kernel
    if unpacked_complete "$dir"; then
        # A module added to modules.txt since the cache was filled: unpack again (from the
        # cached package, offline).
        local listed missing=()
        while read -r listed; do
            [[ -f $dir/modules/$listed ]] || missing+=("$listed")
        done < <(module_list)
        ((${#missing[@]} == 0)) && return 0
        say "the kernel cache has no ${missing[*]} (added to ci/vm/modules.txt since it was filled): unpacking the kernel package again"
    fi
    local package deb
    package=$(kernel_package_name)
    deb=$(fetch_debs "$package")
    say "unpacking kernel and modules from ${deb##*/}"
    local scratch
    scratch=$(mktemp -d "$VM_CACHE/.kernel.XXXXXX")
    local patterns=('./boot/vmlinuz-*') module
    while read -r module; do
        patterns+=("./lib/modules/*/kernel/$module" "./usr/lib/modules/*/kernel/$module")
    done < <(module_list)
    # Only the kernel and the listed modules are written; tar exits 2 for the patterns of the
    # two module roots (merged /usr or not) that match nothing, so success is checked below.
    dpkg-deb --fsys-tarfile "$deb" |
        tar -x -C "$scratch" --wildcards --no-wildcards-match-slash "${patterns[@]}" 2>/dev/null || true
    local vmlinuz
    vmlinuz=$(find "$scratch/boot" -name 'vmlinuz-*' -print -quit 2>/dev/null)
    [[ -n $vmlinuz ]] || die "no /boot/vmlinuz-* in $deb"
    local version=${vmlinuz##*/vmlinuz-}
    local modules_root
    modules_root=$(find "$scratch" -type d -path "*/modules/$version/kernel" -print -quit)
    [[ -n $modules_root ]] || die "no lib/modules/$version/kernel in $deb"
    mkdir -p "$scratch/out/modules"
    while read -r module; do
        [[ -f $modules_root/$module ]] ||
            die "kernel $version has no module $module (listed in ci/vm/modules.txt); is it built in or renamed?"
        mkdir -p "$scratch/out/modules/${module%/*}"
        mv "$modules_root/$module" "$scratch/out/modules/$module"
    done < <(module_list)
    extract_vmlinux "$vmlinuz" "$scratch/out/vmlinux" || {
        say "could not extract an uncompressed vmlinux from ${vmlinuz##*/}; booting the compressed image (slower)"
        cp "$vmlinuz" "$scratch/out/vmlinux"
    }
    printf '%s\n' "$version" >"$scratch/out/version"
    printf '%s\n' "${deb##*/}" >"$scratch/out/.complete"
    rm -rf "$dir"
    mv "$scratch/out" "$dir"
    rm -rf "$scratch"
}

# Writes the uncompressed ELF kernel inside bzImage $1 to $2 (returns 1 when none is found).
# Under TCG the guest then skips decompressing itself, which halves the boot time.
extract_vmlinux() {
    local image=$1 out=$2 magic_tool magic tool offset
    for magic_tool in '\xFD7zXZ\x00:xz' '\x28\xB5\x2F\xFD:zstd' '\x1F\x8B\x08\x00:gzip'; do
        magic=${magic_tool%%:*}
        tool=${magic_tool#*:}
        command -v "$tool" >/dev/null 2>&1 || continue
        while read -r offset; do
            # The decompressor stops with an error at the data after the payload: the ELF
            # header check below is what decides.
            tail -c +$((offset + 1)) "$image" | "$tool" -dc 2>/dev/null >"$out" || true
            if [[ $(head -c 4 "$out" | od -An -tx1 | tr -d ' \n') == 7f454c46 ]]; then
                return 0
            fi
        done < <(LC_ALL=C grep -obUaP "$magic" "$image" | cut -d: -f1 | head -n 8)
    done
    rm -f "$out"
    return 1
}

# Prepares $VM_CACHE/userland: the unpacked busybox-static and can-utils packages.
prepare_userland() {
    local dir=$VM_CACHE/userland
    unpacked_complete "$dir" && return 0
    local debs=() deb
    mapfile -t debs < <(fetch_debs "${USERLAND_PACKAGES[@]}")
    [[ ${#debs[@]} == "${#USERLAND_PACKAGES[@]}" ]] || die "fetching ${USERLAND_PACKAGES[*]} failed"
    local scratch
    scratch=$(mktemp -d "$VM_CACHE/.userland.XXXXXX")
    for deb in "${debs[@]}"; do
        dpkg-deb -x "$deb" "$scratch" || die "dpkg-deb -x $deb failed"
    done
    local busybox
    busybox=$(userland_busybox "$scratch")
    local cpio_help
    cpio_help=$("$busybox" cpio --help 2>&1 || true)
    [[ $cpio_help == *"-o"* ]] ||
        die "the busybox in ${debs[0]} cannot write cpio archives (no 'cpio -o')"
    printf '%s\n' "${debs[@]##*/}" >"$scratch/.complete"
    rm -rf "$dir"
    mv "$scratch" "$dir"
}

# The busybox binary inside unpacked userland folder $1 (default: the cache's).
userland_busybox() {
    local root=${1:-$VM_CACHE/userland} candidate
    for candidate in "$root/bin/busybox" "$root/usr/bin/busybox"; do
        [[ -x $candidate ]] && { printf '%s\n' "$candidate"; return 0; }
    done
    die "no busybox in $root"
}

# Sets QEMU_CMD (array) to a runnable qemu-system-x86_64: $SCANHIL_VM_QEMU when set, else the
# host's, else Debian's unpacked into $VM_CACHE/qemu and run with its own libraries and firmware.
prepare_qemu() {
    if [[ -n ${SCANHIL_VM_QEMU:-} ]]; then
        [[ -x $SCANHIL_VM_QEMU ]] || die "SCANHIL_VM_QEMU=$SCANHIL_VM_QEMU is not an executable file"
        QEMU_CMD=("$SCANHIL_VM_QEMU")
        QEMU_ORIGIN="SCANHIL_VM_QEMU"
        return 0
    fi
    local host_qemu
    if host_qemu=$(command -v qemu-system-x86_64 2>/dev/null); then
        QEMU_CMD=("$host_qemu")
        QEMU_ORIGIN="host"
        return 0
    fi
    local dir=$VM_CACHE/qemu
    if ! unpacked_complete "$dir"; then
        command -v apt-get >/dev/null 2>&1 ||
            die "no qemu-system-x86_64 on PATH and no apt-get to fetch Debian's: install QEMU or set SCANHIL_VM_QEMU"
        ensure_apt_knows qemu-system-x86
        # What a real install would add; the host already has the rest of QEMU's libraries.
        local plan packages=()
        plan=$(apt-get install -s --no-install-recommends qemu-system-x86 2>&1) ||
            die "cannot plan qemu-system-x86: $plan"
        mapfile -t packages < <(awk '$1 == "Inst" { print $2 }' <<<"$plan")
        ((${#packages[@]} > 0)) || die "apt-get install -s qemu-system-x86 lists nothing to install: $plan"
        local debs=() deb
        mapfile -t debs < <(fetch_debs "${packages[@]}")
        [[ ${#debs[@]} == "${#packages[@]}" ]] || die "fetching QEMU's packages failed"
        say "unpacking ${#debs[@]} packages of QEMU"
        local scratch
        scratch=$(mktemp -d "$VM_CACHE/.qemu.XXXXXX")
        for deb in "${debs[@]}"; do
            dpkg-deb -x "$deb" "$scratch" || die "dpkg-deb -x $deb failed"
        done
        printf '%s\n' "${debs[@]##*/}" >"$scratch/.complete"
        rm -rf "$dir"
        mv "$scratch" "$dir"
    fi
    local library_path=$dir/usr/lib/x86_64-linux-gnu:$dir/lib/x86_64-linux-gnu
    QEMU_CMD=(env "LD_LIBRARY_PATH=$library_path${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
        "$dir/usr/bin/qemu-system-x86_64"
        -L "$dir/usr/share/qemu" -L "$dir/usr/share/seabios" -L "$dir/usr/lib/ipxe/qemu")
    QEMU_ORIGIN="Debian package unpacked in $dir"
    local version
    version=$("${QEMU_CMD[@]}" --version 2>&1) || die "Debian's QEMU in $dir does not run: $version"
}
