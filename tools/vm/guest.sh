#!/bin/bash
# Runs inside the pamc VM (started by vcan_setup.sh vm), chrooted into the host's root filesystem,
# with bash and iproute2 of the host. vcan_setup.sh copies it into the job directory JOB, which
# also holds:
#   conf  IFACE, TXQUEUELEN, CWD, OUT_TTY, ERR_TTY and the CMD array (bash, printf %q quoted)
#   env   the caller's exported environment, applied to the command only
# It writes JOB/rc, the command's exit status, which is how the status reaches the host:
# serial output can be cut or mixed with kernel messages, a file on the shared root cannot.
# Its own messages go to ttyS0 (the console log), the command's stdout to ttyS1, stderr to ttyS2.
set -u
job=$1
export PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin

say() { echo "pamc-vm: $*"; }

# shellcheck source=/dev/null
. "$job/conf"

# The command's streams. Raw mode: no \n -> \r\n translation, no echo, binary data passes as is.
exec 3>/dev/ttyS1 4>/dev/ttyS2
stty raw -echo <&3
stty raw -echo <&4

# Setup failures are also printed on the command's stderr, so the caller sees them without
# the console log; no rc file is written, so the host reports a VM failure (125).
fail() {
    say "$*"
    echo "vcan_setup.sh (in the VM): $*" >&4
    exit 1
}

# iproute2 of the host, not busybox: busybox `ip` cannot create links of type vcan.
ip link add dev "$IFACE" type vcan || fail "cannot create $IFACE"
ip link set dev "$IFACE" txqueuelen "$TXQUEUELEN" || fail "cannot set txqueuelen of $IFACE"
ip link set dev "$IFACE" up || fail "cannot bring $IFACE up"

# On the host the command's stdout/stderr are a terminal or not; give it the same here, so that
# buffering and colouring behave as they would on the host: the serial tty itself if the caller
# has a terminal, else a pipe that a cat copies to the tty.
pipe_pids=()
out=3
err=4
if [ "$OUT_TTY" != 1 ]; then
    exec 5> >(exec cat >&3) || fail "no pipe for stdout"
    out=5
    pipe_pids+=($!)
fi
if [ "$ERR_TTY" != 1 ]; then
    exec 6> >(exec cat >&4) || fail "no pipe for stderr"
    err=6
    pipe_pids+=($!)
fi

(
    # A failed redirection of `exec` does not end bash by itself.
    exec </dev/null >&"$out" 2>&"$err" 3>&- 4>&- 5>&- 6>&- || exit 125
    # shellcheck source=/dev/null
    . "$job/env"
    cd -- "$CWD" || { echo "vcan_setup.sh (in the VM): cannot cd to $CWD" >&2; exit 125; }
    exec "${CMD[@]}"
)
rc=$?

# Record the status first: nothing after this may change it.
echo "$rc" >"$job/rc.tmp" && mv -f "$job/rc.tmp" "$job/rc"
sync
say "command exited with status $rc"

# Let the cats copy what is left in the pipes. A background process of the command that still
# holds a pipe would keep its cat alive forever, so wait at most 5 s.
exec 5>&- 6>&-
for _ in $(seq 50); do
    alive=0
    for pid in "${pipe_pids[@]}"; do
        kill -0 "$pid" 2>/dev/null && alive=1
    done
    [ "$alive" = 0 ] && break
    sleep 0.1
done
exit 0
