# shellcheck shell=bash
# Building the throwaway VM's base initramfs (an uncompressed newc cpio archive).
#
# Sourced by ci/vcan-vm.sh. Contents, in a merged-/usr layout (/bin, /sbin, /lib, /lib64 are
# links into /usr):
# - /init: ci/vm/init, the guest's PID 1;
# - busybox (static) and links for its applets, except where a real program is carried;
# - the host's bash (also as /bin/sh: busybox sh would prefer its own applets, e.g. its `ip`,
#   over PATH) and the host's iproute2 `ip` (busybox ip cannot create vcan/vxcan links);
# - can-utils programs (ci/vm/fetch.sh CAN_UTILS_PROGRAMS);
# - every shared library these need, plus glibc, libm, libgcc_s and the dynamic loader, so that
#   Rust binaries built on this host run in the guest;
# - the kernel modules of ci/vm/modules.txt under /lib/modules/<version>/, and their load order
#   in /etc/scanhil-vm/modules.
# The archive is cached under a key made of everything that goes in; the per-run job archive
# (command, environment, shares) is appended to a copy by ci/vcan-vm.sh.
#
# Needs from the caller: VM_CACHE, VM_DIR, and the functions say, die, module_list,
# userland_busybox (ci/vm/fetch.sh).

# Host libraries every host-built binary may need beyond what ldd shows for bash and ip.
readonly GLIBC_LIBRARIES=(libc.so.6 libm.so.6 libgcc_s.so.1 libpthread.so.0 libdl.so.2
    librt.so.1 libutil.so.1 libresolv.so.2)

# Prints the path of the cached base initramfs, building it first when needed.
base_initramfs() {
    local bash_path ip_path
    bash_path=$(host_program bash)
    ip_path=$(host_program ip)
    local can_programs=() program
    for program in "${CAN_UTILS_PROGRAMS[@]}"; do
        [[ -x $VM_CACHE/userland/usr/bin/$program ]] ||
            die "can-utils in $VM_CACHE/userland has no $program"
        can_programs+=("$VM_CACHE/userland/usr/bin/$program")
    done
    local needed library
    needed=$(shared_libraries "$bash_path" "$ip_path" "${can_programs[@]}")
    for library in "${GLIBC_LIBRARIES[@]}"; do
        needed+=$'\n'$(host_library "$library")
    done
    local libraries=()
    mapfile -t libraries < <(sort -u <<<"$needed")
    local key
    key=$(
        {
            cat "$VM_DIR/init" "$VM_DIR/modules.txt" "$VM_DIR/initramfs.sh" "$VM_CACHE/kernel/version" \
                "$VM_CACHE/userland/.complete"
            # The programs it carries (listed in fetch.sh, which is not in the key).
            printf 'can-utils: %s\n' "${CAN_UTILS_PROGRAMS[*]}"
            stat -L -c '%n %s %Y' "$bash_path" "$ip_path" "${libraries[@]}"
        } | sha256sum | cut -c1-16
    )
    local archive=$VM_CACHE/initramfs-$key.cpio
    if [[ ! -f $archive ]]; then
        build_initramfs "$archive" "$bash_path" "$ip_path" "${can_programs[@]}" -- "${libraries[@]}"
        # Keep the three newest: a concurrent run from another checkout may still use its own.
        find "$VM_CACHE" -maxdepth 1 -name 'initramfs-*.cpio' -printf '%T@ %p\n' | sort -rn |
            tail -n +4 | cut -d' ' -f2- | xargs -r rm -f
    fi
    printf '%s\n' "$archive"
}

# The host's program $1, or a loud error.
host_program() {
    local path
    path=$(PATH=/usr/sbin:/usr/bin:/sbin:/bin:$PATH command -v "$1" 2>/dev/null) ||
        die "the host has no '$1' to carry into the VM (install $( [[ $1 == ip ]] && echo iproute2 || echo "$1"))"
    readlink -f "$path"
}

# The host path of shared library $1 (x86-64), or a loud error.
host_library() {
    local path
    path=$(/sbin/ldconfig -p 2>/dev/null | awk -v name="$1" '$1 == name && /x86-64/ && !found { print $NF; found = 1 }')
    [[ -n $path ]] || die "the host has no $1 (x86-64) for the VM's glibc-linked programs"
    printf '%s\n' "$path"
}

# Every shared library (and the dynamic loader) the dynamic executables in "$@" load.
shared_libraries() {
    local binary output
    for binary in "$@"; do
        output=$(ldd "$binary" 2>&1) || {
            # A static executable (busybox) needs nothing.
            grep -q 'not a dynamic executable' <<<"$output" && continue
            die "ldd $binary failed: $output"
        }
        grep -q 'not found' <<<"$output" && die "$binary needs libraries the host lacks: $output"
        awk '$2 == "=>" && $3 ~ /^\// { print $3 } $1 ~ /^\// { print $1 }' <<<"$output"
    done
}

# Where host file $1 goes in the merged-/usr guest: /lib/x -> usr/lib/x, /usr/lib/x -> usr/lib/x.
guest_path() {
    local path=$1
    path=${path#/usr/}
    printf 'usr/%s\n' "${path#/}"
}

# Builds archive $1 from bash $2, ip $3, can-utils programs up to `--`, and libraries after it.
build_initramfs() {
    local archive=$1 bash_path=$2 ip_path=$3
    shift 3
    local programs=()
    while [[ $1 != -- ]]; do programs+=("$1"); shift; done
    shift
    local libraries=("$@")
    say "building the initramfs"
    local root
    root=$(mktemp -d "$VM_CACHE/.initramfs.XXXXXX")
    mkdir -p "$root"/usr/{bin,sbin,lib/x86_64-linux-gnu,lib64} "$root"/{dev,proc,sys,tmp,run,root,mnt,etc/scanhil-vm}
    ln -s usr/bin "$root/bin"
    ln -s usr/sbin "$root/sbin"
    ln -s usr/lib "$root/lib"
    ln -s usr/lib64 "$root/lib64"

    install -m 0755 "$VM_DIR/init" "$root/init"
    install -m 0755 "$bash_path" "$root/usr/bin/bash"
    ln -s bash "$root/usr/bin/sh"
    install -m 0755 "$ip_path" "$root/usr/sbin/ip"
    local program
    for program in "${programs[@]}"; do
        install -m 0755 "$program" "$root/usr/bin/${program##*/}"
    done
    local library target
    for library in "${libraries[@]}"; do
        target=$root/$(guest_path "$library")
        mkdir -p "${target%/*}"
        cp -L "$library" "$target"
    done
    # The loader is looked up at the path compiled into each binary.
    [[ -e $root/usr/lib64/ld-linux-x86-64.so.2 ]] ||
        ln -s ../lib/x86_64-linux-gnu/ld-linux-x86-64.so.2 "$root/usr/lib64/ld-linux-x86-64.so.2"

    local busybox
    busybox=$(userland_busybox)
    install -m 0755 "$busybox" "$root/usr/bin/busybox"
    local applet link
    while read -r applet; do
        link=$root/$(guest_path "/$applet")
        # A real program of the same name wins, wherever it is on PATH (e.g. sbin/ip).
        [[ -e $root/usr/bin/${applet##*/} || -e $root/usr/sbin/${applet##*/} || -L $link ]] && continue
        mkdir -p "${link%/*}"
        ln -s /usr/bin/busybox "$link"
    done < <("$busybox" --list-full)

    local version module
    version=$(<"$VM_CACHE/kernel/version")
    while read -r module; do
        [[ -f $VM_CACHE/kernel/modules/$module ]] ||
            die "the kernel cache $VM_CACHE/kernel has no module $module (listed in ci/vm/modules.txt); run again with SCANHIL_VM_REFRESH=1 or delete that folder"
        mkdir -p "$root/usr/lib/modules/$version/kernel/${module%/*}"
        cp "$VM_CACHE/kernel/modules/$module" "$root/usr/lib/modules/$version/kernel/$module"
        printf '/lib/modules/%s/kernel/%s\n' "$version" "$module"
    done < <(module_list) >"$root/etc/scanhil-vm/modules"

    printf 'root:x:0:0:root:/root:/bin/bash\n' >"$root/etc/passwd"
    printf 'root:x:0:\n' >"$root/etc/group"
    printf '127.0.0.1 localhost\n::1 localhost\n' >"$root/etc/hosts"
    printf 'scanhil-vm\n' >"$root/etc/hostname"

    write_cpio "$root" "$archive.tmp"
    mv "$archive.tmp" "$archive"
    rm -rf "$root"
}

# Writes folder $1 as a newc cpio archive $2 (with the cache's busybox: hosts rarely have cpio).
write_cpio() {
    local busybox
    busybox=$(userland_busybox)
    (cd "$1" && find . -mindepth 1 | LC_ALL=C sort | "$busybox" cpio -o -H newc >"$2" 2>/dev/null) ||
        die "writing the cpio archive $2 from $1 failed"
}
