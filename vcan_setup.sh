#!/usr/bin/env bash
# vcan_setup.sh - a virtual CAN interface (vcan0) for pamc's SocketCAN code and can-utils, without
# CAN hardware: on this host when its kernel has vcan, else inside a throw-away QEMU VM that runs
# Debian's stock kernel on the host's own root filesystem. `./vcan_setup.sh --help` has the modes.
#
# VM pieces: tools/vm/init (the initramfs' /init), tools/vm/guest.sh (runs in the VM, creates the
# interface, runs the command, writes its exit status), tools/vm/pamc-modprobe (module autoload).
set -euo pipefail
# Command substitutions such as initrd=$(build_initramfs ...) stop at the first failure too.
shopt -s inherit_errexit

PROG=vcan_setup.sh
HERE=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")" && pwd -P)
VM_FILES=$HERE/tools/vm
DEFAULT_IFACE=vcan0

# 1000 frames: a 1 kHz control loop that sends a burst of PDOs per cycle must not get ENOBUFS;
# the usual CAN default of 10 overflows.
TXQUEUELEN=${PAMC_VCAN_TXQUEUELEN:-1000}
VM_TIMEOUT=${PAMC_VM_TIMEOUT:-600}
VM_MEM=${PAMC_VM_MEM:-1024}
# One vCPU: TCG's second thread buys little at boot and the machine's cores are shared.
VM_SMP=${PAMC_VM_SMP:-1}
# TCG, not KVM: KVM hung on the machine this was written on (nested virtualisation).
VM_ACCEL=${PAMC_VM_ACCEL:-tcg}
if [ -n "${PAMC_VM_CACHE:-}" ]; then
    VM_CACHE=$PAMC_VM_CACHE
elif [ -n "${XDG_CACHE_HOME:-}" ] || [ -n "${HOME:-}" ]; then
    VM_CACHE=${XDG_CACHE_HOME:-$HOME/.cache}/pamc-vm
else
    VM_CACHE=/tmp/pamc-vm-$(id -u)
fi
# Loaded by the VM's /init in this order (dependencies from modules.dep go first). Any of them may
# be built into a given kernel or not exist there; those are skipped.
VM_MODULES=(virtio_ring virtio virtio_pci_modern_dev virtio_pci_legacy_dev virtio_pci
            netfs fscache 9pnet 9pnet_virtio 9p can-dev vcan can can-raw)
# Debian packages the VM needs; busybox-static because the initramfs has no C library.
VM_PACKAGES=(qemu-system-x86 linux-image-amd64 busybox-static can-utils)

usage() {
    cat <<EOF
Usage: $PROG [up] [IFACE]                      create IFACE (type vcan) and bring it up (root)
       $PROG down [IFACE]                      remove IFACE (root)
       $PROG vm [IFACE] -- COMMAND [ARG...]    run COMMAND in a throw-away VM with IFACE up
       $PROG auto [IFACE] -- COMMAND [ARG...]  run COMMAND here if IFACE is up or can be
                                               brought up, else as with vm
       $PROG -h | --help

IFACE defaults to $DEFAULT_IFACE. With no arguments the mode is 'up'.

up    modprobe vcan, 'ip link add dev IFACE type vcan' (fine if it exists), txqueuelen
      $TXQUEUELEN, link up. Needs root and a kernel with CONFIG_CAN_VCAN; if IFACE is already up
      it only says so. It stays up until 'down' or a reboot.
down  deletes IFACE if it is a vcan interface; fine if it does not exist.

vm    for hosts whose kernel has no CAN support. Boots Debian's kernel (the newest
      /boot/vmlinuz-* with CAN modules) in QEMU (TCG) with a busybox initramfs that mounts the
      host's root filesystem over 9p, read-write, creates IFACE, and runs COMMAND there as root,
      chrooted into the host's root:
        - in the caller's working directory, with the caller's exported environment;
        - files it writes (e.g. candump -l logs) are on the host afterwards;
        - its stdout and stderr reach the caller's stdout and stderr (as a terminal if the
          caller's are one, else as pipes); stdin is /dev/null;
        - /proc, /sys, /dev and /run are the VM's own, /tmp is the host's;
        - the exit status of $PROG is COMMAND's.
      It is the host's filesystem, not a copy: what COMMAND changes stays changed.
      One call takes about 6-8 s here, mostly the emulated boot. Missing packages
      (${VM_PACKAGES[*]})
      are installed by apt-get when run as root; others are told the command.
      The initramfs is cached in $VM_CACHE and rebuilt when the kernel changes.
auto  like vm, but without a VM when the host has IFACE up or can bring it up (root, vcan in
      the kernel); then IFACE stays up afterwards.

Exit status: 0 success; vm/auto: COMMAND's status, or 124 if the VM timed out, 125 if the VM
failed before COMMAND's status was known (the console log is printed); 2 bad usage; 1 other
errors.

Environment: PAMC_VM_TIMEOUT (seconds, default 600), PAMC_VM_MEM (MiB, 1024), PAMC_VM_SMP (1),
PAMC_VM_ACCEL (tcg; kvm where it works), PAMC_VM_CACHE (initramfs cache directory),
PAMC_VM_VERBOSE=1 (show the VM's console on stderr), PAMC_VM_KEEP=1 (keep the job directory),
PAMC_VCAN_TXQUEUELEN ($TXQUEUELEN).
EOF
}

note() { printf '%s: %s\n' "$PROG" "$*" >&2; }
die() { note "$*"; exit 1; }
usage_error() { note "$* (see '$PROG --help')"; exit 2; }
is_root() { [ "$(id -u)" -eq 0 ]; }
is_uint() { case $1 in '' | *[!0-9]*) return 1 ;; esac; }

check_iface_name() {
    # Linux interface names: at most 15 bytes, no '/', no whitespace; stricter here on purpose.
    [[ $1 =~ ^[A-Za-z0-9_.-]{1,15}$ ]] || usage_error "bad interface name '$1'"
}

# --- the host's own vcan -------------------------------------------------------------------

iface_exists() { [ -e "/sys/class/net/$1" ]; }
iface_is_vcan() { ip -details -oneline link show dev "$1" 2>/dev/null | grep -qw vcan; }
# Usable for CAN programs: link type 280 is ARPHRD_CAN, bit 0 of flags is IFF_UP.
iface_is_up_can() {
    local type flags
    type=$(cat "/sys/class/net/$1/type" 2>/dev/null) || return 1
    flags=$(cat "/sys/class/net/$1/flags" 2>/dev/null) || return 1
    [ "$type" = 280 ] && (((flags & 1) == 1))
}

# Whether the running kernel can have vcan at all, answered without root so that a user on a
# CAN-less kernel is pointed at 'vm' rather than at sudo.
kernel_has_vcan() {
    [ -d /sys/module/vcan ] && return 0
    if command -v modprobe >/dev/null 2>&1; then
        modprobe --dry-run --quiet vcan 2>/dev/null && return 0
    fi
    grep -qs '/vcan\.ko' "/lib/modules/$(uname -r)/modules.builtin"
}

cmd_up() {
    local ifc=$1 out
    command -v ip >/dev/null 2>&1 || die "'ip' not found (install iproute2)"
    if iface_is_up_can "$ifc"; then
        note "$ifc is already up"
        return 0
    fi
    kernel_has_vcan ||
        die "kernel $(uname -r) has no vcan support (CONFIG_CAN_VCAN); use '$0 vm -- COMMAND' to run COMMAND in a VM with $ifc"
    is_root || die "'up' needs root: sudo $0 up $ifc"
    if [ ! -d /sys/module/vcan ]; then
        out=$(modprobe vcan 2>&1) || die "modprobe vcan failed: ${out//$'\n'/ }"
    fi
    # can_raw is what candump/cansend and pamc open; the kernel would also autoload it.
    modprobe can_raw >/dev/null 2>&1 || true
    if iface_exists "$ifc"; then
        iface_is_vcan "$ifc" || die "$ifc exists and is not a vcan interface"
    else
        out=$(ip link add dev "$ifc" type vcan 2>&1) || die "cannot create $ifc: ${out//$'\n'/ }"
    fi
    out=$(ip link set dev "$ifc" txqueuelen "$TXQUEUELEN" 2>&1) ||
        die "cannot set txqueuelen of $ifc: ${out//$'\n'/ }"
    out=$(ip link set dev "$ifc" up 2>&1) || die "cannot bring $ifc up: ${out//$'\n'/ }"
    note "$ifc is up (vcan, txqueuelen $TXQUEUELEN)"
}

cmd_down() {
    local ifc=$1 out
    command -v ip >/dev/null 2>&1 || die "'ip' not found (install iproute2)"
    if ! iface_exists "$ifc"; then
        note "$ifc does not exist; nothing to do"
        return 0
    fi
    iface_is_vcan "$ifc" || die "$ifc is not a vcan interface; not removing it"
    is_root || die "'down' needs root: sudo $0 down $ifc"
    out=$(ip link delete dev "$ifc" 2>&1) || die "cannot remove $ifc: ${out//$'\n'/ }"
    note "$ifc removed"
}

# --- the VM ----------------------------------------------------------------------------------

# The newest installed kernel that has CAN modules. Not `uname -r`: the running kernel is the
# one without CAN, and /boot may hold several Debian kernels.
pick_kernel() {
    local k v
    for k in $(printf '%s\n' /boot/vmlinuz-* | sort -rV); do
        [ -f "$k" ] || continue
        v=${k#/boot/vmlinuz-}
        if [ -d "/lib/modules/$v/kernel/net/can" ] && [ -f "/lib/modules/$v/modules.dep" ]; then
            echo "$v"
            return 0
        fi
    done
    return 1
}

busybox_is_static() {
    [ -x /bin/busybox ] || return 1
    if command -v dpkg-query >/dev/null 2>&1 &&
        dpkg-query -W -f='${Status}' busybox-static 2>/dev/null | grep -q 'install ok installed'; then
        return 0
    fi
    # Elsewhere: a static binary makes ldd fail ("not a dynamic executable").
    ! ldd /bin/busybox >/dev/null 2>&1
}

# Installs what the VM needs when it is missing (root, apt), else says how.
ensure_vm_deps() {
    local missing=()
    command -v qemu-system-x86_64 >/dev/null 2>&1 || missing+=(qemu-system-x86)
    pick_kernel >/dev/null || missing+=(linux-image-amd64)
    busybox_is_static || missing+=(busybox-static)
    command -v candump >/dev/null 2>&1 || missing+=(can-utils)
    command -v timeout >/dev/null 2>&1 || missing+=(coreutils)
    ((${#missing[@]})) || return 0
    if ! is_root || ! command -v apt-get >/dev/null 2>&1; then
        die "the VM needs: ${missing[*]} (sudo apt-get install --no-install-recommends ${missing[*]})"
    fi
    note "installing: ${missing[*]}"
    # apt's progress would bury the command's output; it is shown only when something fails.
    local log
    log=$(mktemp)
    if ! { apt-get update -qq &&
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}"; } \
        >"$log" 2>&1; then
        tail -n 20 "$log" >&2
        rm -f "$log"
        die "installing ${missing[*]} failed"
    fi
    rm -f "$log"
    pick_kernel >/dev/null || die "no kernel with CAN modules in /boot after installing linux-image-amd64"
}

# Prints "dep_n ... dep_1 module" paths (relative to /lib/modules/KVER) for module NAME from
# modules.dep: its line lists every dependency, and modprobe loads them from the last to the first.
# Prints nothing when the module is built in or absent.
module_load_order() {
    local kver=$1 name=${2//-/_}
    awk -F': *' -v n="$name" '{
        b = $1; sub(/.*\//, "", b); sub(/\.ko(\.[a-z]+)?$/, "", b); gsub(/-/, "_", b)
        if (b == n) {
            c = split($2, d, " ")
            for (i = c; i >= 1; i--) print d[i]
            print $1
            exit
        }
    }' "/lib/modules/$kver/modules.dep"
}

# Copies module PATH of KVER, decompressed (busybox insmod takes plain ELF only), to DEST.
copy_module() {
    local src=/lib/modules/$1/$2 dest=$3
    case $src in
    *.ko) cp "$src" "$dest" ;;
    *.ko.xz) if command -v xz >/dev/null 2>&1; then xz -dc "$src" >"$dest"; else /bin/busybox xzcat "$src" >"$dest"; fi ;;
    *.ko.gz) gzip -dc "$src" >"$dest" ;;
    *.ko.zst) command -v zstd >/dev/null 2>&1 || die "zstd is needed to unpack $src"; zstd -qdc "$src" >"$dest" ;;
    *) die "unknown module format: $src" ;;
    esac
}

# Builds (if needed) the initramfs for kernel KVER and prints its path. Rebuilt when the kernel
# (version or file) or a file in tools/vm changes; written to a temporary name and renamed, so
# concurrent runs never see half an archive.
build_initramfs() {
    local kver=$1 img=$VM_CACHE/initramfs.cpio stamp want stage m rel base n=0
    local -A seen=()
    want="$kver $(stat -c %Y "/boot/vmlinuz-$kver") $(cat "$VM_FILES/init" "$VM_FILES/pamc-modprobe" \
        /bin/busybox | cksum) ${VM_MODULES[*]}"
    stamp=$img.stamp
    if [ -f "$img" ] && [ "$(cat "$stamp" 2>/dev/null)" = "$want" ]; then
        echo "$img"
        return 0
    fi
    note "building the VM's initramfs for kernel $kver in $VM_CACHE"
    mkdir -p "$VM_CACHE"
    stage=$(mktemp -d "$VM_CACHE/stage.XXXXXX")
    mkdir -p "$stage"/{bin,dev,proc,sys,host,lib/modules}
    cp /bin/busybox "$stage/bin/busybox"
    for m in $(/bin/busybox --list); do
        [ "$m" = busybox ] || ln -s busybox "$stage/bin/$m"
    done
    install -m 755 "$VM_FILES/init" "$stage/init"
    install -m 755 "$VM_FILES/pamc-modprobe" "$stage/bin/pamc-modprobe"
    : >"$stage/lib/modules/order"
    for m in "${VM_MODULES[@]}"; do
        for rel in $(module_load_order "$kver" "$m"); do
            [ -z "${seen[$rel]:-}" ] || continue
            seen[$rel]=1
            base=${rel##*/}
            base=$(printf '%02d-%s.ko' "$n" "${base%%.ko*}")
            n=$((n + 1))
            copy_module "$kver" "$rel" "$stage/lib/modules/$base"
            echo "$base" >>"$stage/lib/modules/order"
        done
    done
    # Uncompressed: QEMU loads it as is, and the kernel does not spend emulated time inflating it.
    (cd "$stage" && find . | /bin/busybox cpio -o -H newc 2>/dev/null) >"$img.tmp.$$"
    mv -f "$img.tmp.$$" "$img"
    echo "$want" >"$stamp"
    rm -rf "$stage"
    echo "$img"
}

# Writes KEY=VALUE lines that bash reads back exactly (printf %q).
emit_var() { printf '%s=%q\n' "$1" "$2"; }

VM_JOB=
VM_PIDS=()
vm_cleanup() {
    local pid
    for pid in "${VM_PIDS[@]}"; do kill -TERM "$pid" 2>/dev/null || true; done
    if [ -n "$VM_JOB" ] && [ -d "$VM_JOB" ]; then
        if [ "${PAMC_VM_KEEP:-0}" = 1 ]; then note "job directory kept: $VM_JOB"; else rm -rf "$VM_JOB"; fi
    fi
}

cmd_vm() {
    local ifc=$1 kver initrd qemu_pid status rc name value f tmp
    shift
    if ! is_uint "$VM_TIMEOUT" || [ "$VM_TIMEOUT" -eq 0 ]; then
        usage_error "PAMC_VM_TIMEOUT must be a positive number of seconds"
    fi
    is_uint "$VM_MEM" || usage_error "PAMC_VM_MEM must be a number of MiB"
    is_uint "$VM_SMP" || usage_error "PAMC_VM_SMP must be a number of CPUs"
    for f in init guest.sh pamc-modprobe; do
        [ -r "$VM_FILES/$f" ] || die "missing $VM_FILES/$f"
    done
    ensure_vm_deps
    # A user without a writable home (e.g. nobody) gets a private cache in /tmp.
    if ! mkdir -p "$VM_CACHE" 2>/dev/null || [ ! -w "$VM_CACHE" ]; then
        VM_CACHE=/tmp/pamc-vm-$(id -u)
        mkdir -m 700 "$VM_CACHE" 2>/dev/null || true
        [ -O "$VM_CACHE" ] || die "$VM_CACHE belongs to another user; set PAMC_VM_CACHE"
    fi
    kver=$(pick_kernel)
    [ -r "/boot/vmlinuz-$kver" ] || die "/boot/vmlinuz-$kver is not readable (run as root)"
    initrd=$(build_initramfs "$kver")

    # The job directory: on the host's root filesystem, which the VM sees at the same path. Its
    # path goes on the kernel command line and into QEMU options, hence the plain characters.
    tmp=${TMPDIR:-/tmp}
    [[ $tmp =~ ^/[A-Za-z0-9/._+-]*$ ]] || tmp=/tmp
    VM_JOB=$(mktemp -d "$tmp/pamc-vm.XXXXXX")
    trap vm_cleanup EXIT
    # Ctrl-C: QEMU runs in the background (see below), so stop it here.
    trap 'vm_cleanup; exit 130' INT
    trap 'vm_cleanup; exit 143' TERM HUP
    chmod 755 "$VM_JOB"
    cp "$VM_FILES/guest.sh" "$VM_JOB/guest.sh"
    # Tested here, not inside $(...), whose stdout is never a terminal.
    local out_tty=0 err_tty=0
    if [ -t 1 ]; then out_tty=1; fi
    if [ -t 2 ]; then err_tty=1; fi
    {
        emit_var IFACE "$ifc"
        emit_var TXQUEUELEN "$TXQUEUELEN"
        emit_var CWD "$PWD"
        emit_var OUT_TTY "$out_tty"
        emit_var ERR_TTY "$err_tty"
        printf 'CMD=('
        printf ' %q' "$@"
        printf ' )\n'
    } >"$VM_JOB/conf"
    # The caller's environment, minus what belongs to this shell or would be read-only in the
    # guest's bash.
    while IFS= read -r -d '' f; do
        name=${f%%=*}
        value=${f#*=}
        [[ $name =~ ^[A-Za-z_][A-Za-z0-9_]*$ ]] || continue
        case $name in
        BASH* | SHELLOPTS | PWD | OLDPWD | SHLVL | _ | UID | EUID | PPID | GROUPS) continue ;;
        esac
        printf 'export %s=%q\n' "$name" "$value"
    done < <(env -0) >"$VM_JOB/env"

    # Three serial ports: ttyS0 the kernel console (kept in console.log, shown if asked or on
    # failure), ttyS1 the command's stdout, ttyS2 its stderr. FIFOs, read by cat, carry them to
    # this process' streams as they come.
    mkfifo "$VM_JOB/console" "$VM_JOB/out" "$VM_JOB/err"
    if [ "${PAMC_VM_VERBOSE:-0}" = 1 ]; then
        tee "$VM_JOB/console.log" <"$VM_JOB/console" >&2 &
    else
        cat <"$VM_JOB/console" >"$VM_JOB/console.log" &
    fi
    VM_PIDS+=($!)
    cat <"$VM_JOB/out" &
    VM_PIDS+=($!)
    cat <"$VM_JOB/err" >&2 &
    VM_PIDS+=($!)

    # -nodefaults: no VGA, NIC or default serial, so no option ROMs are needed and the guest has no
    # network. -no-reboot with panic=-1: a kernel panic ends QEMU instead of hanging. multidevs=remap
    # keeps inode numbers unique where other filesystems are mounted under /.
    # In the background with `wait`, so that the INT trap can run while QEMU does.
    status=0
    timeout -k 10 "$VM_TIMEOUT" qemu-system-x86_64 \
        -accel "$VM_ACCEL" -m "$VM_MEM" -smp "$VM_SMP" \
        -nodefaults -no-user-config -display none -no-reboot \
        -kernel "/boot/vmlinuz-$kver" -initrd "$initrd" \
        -append "console=ttyS0 quiet panic=-1 pamc.job=$VM_JOB" \
        -serial "file:$VM_JOB/console" -serial "file:$VM_JOB/out" -serial "file:$VM_JOB/err" \
        -virtfs local,path=/,mount_tag=hostroot,security_model=none,multidevs=remap \
        </dev/null >"$VM_JOB/qemu.log" 2>&1 &
    qemu_pid=$!
    VM_PIDS+=("$qemu_pid")
    wait "$qemu_pid" || status=$?

    # If QEMU failed before opening a FIFO, its cat still waits in open(): a writer opening and
    # closing it (O_RDWR never blocks) lets the cat see end-of-file. Harmless otherwise.
    for f in console out err; do
        : <>"$VM_JOB/$f"
    done
    wait "${VM_PIDS[@]:0:3}" 2>/dev/null || true
    VM_PIDS=()

    if [ -s "$VM_JOB/rc" ]; then
        rc=$(cat "$VM_JOB/rc")
        is_uint "$rc" || rc=125
        exit "$rc"
    fi
    if [ "$status" = 124 ] || [ "$status" = 137 ]; then
        note "the VM timed out after ${VM_TIMEOUT}s (PAMC_VM_TIMEOUT)"
        status=124
    else
        note "the VM ended without the command's exit status (qemu: exit $status); its console:"
        status=125
    fi
    if [ "${PAMC_VM_VERBOSE:-0}" != 1 ]; then
        tail -n 25 "$VM_JOB/console.log" | sed 's/\r$//; s/^/  | /' >&2
    fi
    sed 's/^/  qemu: /' "$VM_JOB/qemu.log" >&2
    exit "$status"
}

cmd_auto() {
    local ifc=$1 why
    shift
    if iface_is_up_can "$ifc"; then
        exec "$@"
    fi
    if ! kernel_has_vcan; then
        why="kernel $(uname -r) has no vcan support"
    elif ! is_root; then
        why="$ifc is not up and creating it needs root"
    # In a subshell, because its die() must only mean "use the VM" here.
    elif why=$( (cmd_up "$ifc") 2>&1); then
        printf '%s\n' "$why" >&2
        exec "$@"
    fi
    note "${why#"$PROG: "}; running the command in a VM"
    cmd_vm "$ifc" "$@"
}

# Parses "[IFACE] -- COMMAND [ARG...]" of vm and auto; sets IFACE and CMD.
parse_vm_args() {
    local mode=$1
    shift
    IFACE=$DEFAULT_IFACE
    if [ $# -gt 0 ] && [ "$1" != -- ]; then
        IFACE=$1
        shift
    fi
    if [ $# -eq 0 ] || [ "$1" != -- ]; then
        usage_error "$mode needs '-- COMMAND'"
    fi
    shift
    [ $# -gt 0 ] || usage_error "$mode: no COMMAND after '--'"
    check_iface_name "$IFACE"
    CMD=("$@")
}

main() {
    local mode=up
    if [ $# -gt 0 ]; then
        case $1 in
        -h | --help | help) usage; exit 0 ;;
        up | down | vm | auto) mode=$1; shift ;;
        -*) usage_error "unknown option '$1'" ;;
        *) usage_error "unknown mode '$1'" ;;
        esac
    fi
    case $mode in
    up | down)
        [ $# -le 1 ] || usage_error "$mode takes at most one interface name"
        IFACE=${1:-$DEFAULT_IFACE}
        check_iface_name "$IFACE"
        "cmd_$mode" "$IFACE"
        ;;
    vm | auto)
        parse_vm_args "$mode" "$@"
        # Both end the script themselves, with COMMAND's exit status (exec or exit).
        "cmd_$mode" "$IFACE" "${CMD[@]}"
        ;;
    esac
}

main "$@"
