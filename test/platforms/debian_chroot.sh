#!/usr/bin/env bash
# Run the repository's own `make setup`, `make test` and `make demo` in a Debian chroot, to test a
# Debian platform row (test/platforms/run: debian11, debian12, debian13) on a machine of another
# Debian release.
#
#   test/platforms/debian_chroot.sh SUITE [STEP...]   SUITE: bullseye | bookworm | trixie
#                                                     STEP: setup | test | demo | mission | shell
#                                                     (default: setup test demo mission)
#   setup: make setup; test: make test; demo: make demo (what a user runs); mission: the course
#   mission in lockstep at full speed (make demo DEMO_ARGS="--rtf 0"), its result written to
#   <repo>/test-results/platforms/ROW-mission.{json,png} (ROW: debian11, debian12, debian13) for
#   test/platforms/compare_missions.py; shell: an interactive shell in the chroot, offline.
#
# - The chroot is built once with `debootstrap --variant=minbase` under
#   ${TIAGO_NAV_PLATFORMS:-<repo>/.platforms}/SUITE/root, with only what `make` itself needs
#   (make); everything else, the ROS packages included, is installed by the repository's
#   `make setup`, so a run proves the Makefile's install steps. It is built anew when the script's
#   build steps, the mirrors or the Makefile's apt package lists change (a stamp holds their hash).
# - The repository's files (tracked and untracked-not-ignored, so uncommitted work is tested) are
#   copied to /root/tiago_nav in the chroot; the previous copy's .venv/ and .ws/ are kept (the
#   Makefile's stamps decide what to redo).
# - `setup` runs with the network; the other steps run in a new network namespace with only
#   loopback, so their ROS masters (fixed ports) cannot meet those of tests running on the host
#   or in another chroot at the same time.
# - The host's pip configuration, CA bundle, local apt settings and resolv.conf are copied in
#   before every step; /proc, /sys, /dev and /dev/pts are bound in. On every exit (Ctrl-C and
#   kill too) the processes still running in the chroot (a node a failed test left) are stopped
#   and everything mounted below it is unmounted.
# Needs root (debootstrap, mount, chroot, unshare).
set -euo pipefail

usage() { sed -n '5,12p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2; }
[ $# -ge 1 ] || usage
SUITE=$1; shift
case "$SUITE" in bullseye) ROW=debian11 ;; bookworm) ROW=debian12 ;; trixie) ROW=debian13 ;; *) usage ;; esac
STEPS=("$@")
[ ${#STEPS[@]} -gt 0 ] || STEPS=(setup test demo mission)
for s in "${STEPS[@]}"; do case "$s" in setup|test|demo|mission|shell) ;; *) usage ;; esac; done
[ "$(id -u)" = 0 ] || { echo "$0: needs root (debootstrap, mount, chroot)" >&2; exit 2; }

SCRIPT=$(readlink -f "$0")
REPO=$(cd "$(dirname "$SCRIPT")/../.." && pwd)
BASE=$(mkdir -p "${TIAGO_NAV_PLATFORMS:-$REPO/.platforms}/$SUITE" && cd "${TIAGO_NAV_PLATFORMS:-$REPO/.platforms}/$SUITE" && pwd -P)
ROOTFS=$BASE/root
COPY=/root/tiago_nav                      # the repository's copy, inside the chroot
MIRROR=${TIAGO_NAV_MIRROR:-http://deb.debian.org/debian}
# Debian 11's security suite: its index is still served but the packages it names are not (its
# LTS ended in August 2026), so apt-get install fails on them; Debian 11 runs on its last point
# release (11.11) and bullseye-updates. Set TIAGO_NAV_SECURITY_MIRROR to use a mirror that has them.
if [ "$SUITE" = bullseye ]; then SECURITY_MIRROR=${TIAGO_NAV_SECURITY_MIRROR:-}
else SECURITY_MIRROR=${TIAGO_NAV_SECURITY_MIRROR-http://deb.debian.org/debian-security}; fi
LOG=$BASE/log
mkdir -p "$LOG"
# one run at a time per chroot (a run unmounts everything below it when it ends)
exec 9>"$BASE/.lock"
flock -n 9 || { echo "$0: another run is using $BASE" >&2; exit 1; }

say() { printf '[%s %s] %s\n' "$SUITE" "$(date +%H:%M:%S)" "$*"; }

# ---- mounts: every mount point under $ROOTFS, deepest first, is unmounted on any exit ----------
mounts_under() {   # the mount points at or below $1 (from the kernel's table), deepest first
  awk -v r="$1" '{ gsub(/\\040/, " ", $5); if ($5 == r || index($5, r "/") == 1) print $5 }' \
    /proc/self/mountinfo | sort -r
}
unmount_all() {
  local m
  while read -r m; do
    [ -n "$m" ] || continue
    umount "$m" 2>/dev/null || umount -l "$m" 2>/dev/null || echo "warning: cannot unmount $m" >&2
  done < <(mounts_under "$ROOTFS")
}
chroot_pids() {   # the processes whose root is the chroot
  local p
  for p in /proc/[0-9]*; do
    [ "$(readlink "$p/root" 2>/dev/null)" != "$ROOTFS" ] || echo "${p#/proc/}"
  done
}
stop_chroot_processes() {   # TERM, up to 5 s, then KILL
  local pids i
  pids=$(chroot_pids)
  [ -n "$pids" ] || return 0
  echo "stopping what still runs in the chroot: $(echo $pids)" >&2
  kill -TERM $pids 2>/dev/null || true
  for i in 1 2 3 4 5 6 7 8 9 10; do
    sleep 0.5; pids=$(chroot_pids); [ -n "$pids" ] || return 0
  done
  kill -KILL $pids 2>/dev/null || true
  sleep 0.5
}
cleanup() { stop_chroot_processes; unmount_all; }
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

mount_all() {
  unmount_all              # what a killed earlier run may have left
  mount -t proc proc "$ROOTFS/proc"
  mount --bind /sys "$ROOTFS/sys"
  mount --bind /dev "$ROOTFS/dev"
  mount --bind /dev/pts "$ROOTFS/dev/pts"
  # pip's cache outside the chroot: a rebuilt chroot reuses the wheels pip built (pybullet)
  mkdir -p "$BASE/cache/pip" "$ROOTFS/root/.cache/pip"
  mount --bind "$BASE/cache/pip" "$ROOTFS/root/.cache/pip"
}

# rm -rf of the chroot only once nothing is mounted below it, and never across file systems
remove_rootfs() {
  unmount_all
  if [ -n "$(mounts_under "$ROOTFS")" ]; then
    echo "$0: still mounted below $ROOTFS, not removing it:" >&2; mounts_under "$ROOTFS" >&2; exit 1
  fi
  rm -rf --one-file-system "$ROOTFS"
}

# ---- what goes into the chroot before every step -------------------------------------------
# the environment a step sees: a clean one, with the host's CA and pip settings passed through
PASS_VARS=(PIP_CERT PIP_INDEX_URL PIP_EXTRA_INDEX_URL PIP_TRUSTED_HOST PIP_DEFAULT_TIMEOUT
  PIP_DISABLE_PIP_VERSION_CHECK SSL_CERT_FILE SSL_CERT_DIR REQUESTS_CA_BUNDLE CURL_CA_BUNDLE
  http_proxy https_proxy no_proxy HTTP_PROXY HTTPS_PROXY NO_PROXY)
chroot_env() {
  local v
  ENV=(HOME=/root LANG=C.UTF-8 TERM="${TERM:-dumb}"
       PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin)
  for v in "${PASS_VARS[@]}"; do [ -z "${!v:-}" ] || ENV+=("$v=${!v}"); done
}

host_files() {
  local f
  cp -L /etc/resolv.conf "$ROOTFS/etc/resolv.conf"
  # debootstrap writes no /etc/hosts; the nodes resolve localhost (ROS_HOSTNAME) and dask this
  # machine's name, offline too
  printf '127.0.0.1\tlocalhost\n127.0.1.1\t%s\n::1\tlocalhost ip6-localhost ip6-loopback\n' \
    "$(hostname)" > "$ROOTFS/etc/hosts"
  [ ! -f /etc/pip.conf ] || cp /etc/pip.conf "$ROOTFS/etc/pip.conf"
  if [ -d /etc/xdg/pip ]; then mkdir -p "$ROOTFS/etc/xdg"; rm -rf "$ROOTFS/etc/xdg/pip"; cp -r /etc/xdg/pip "$ROOTFS/etc/xdg/"; fi
  # the CA bundle the environment names (it may carry a CA that the registries need), at the
  # same paths; and as a local CA of the chroot's ca-certificates, whose update-ca-certificates
  # (when `make setup` installs it) would otherwise write a bundle without that CA
  for f in "${PIP_CERT:-}" "${SSL_CERT_FILE:-}" "${REQUESTS_CA_BUNDLE:-}" "${CURL_CA_BUNDLE:-}" \
           /etc/ssl/certs/ca-certificates.crt; do
    if [ -n "$f" ] && [ -f "$f" ]; then mkdir -p "$ROOTFS$(dirname "$f")"; cp -L "$f" "$ROOTFS$f"; fi
  done
  if [ -f /etc/ssl/certs/ca-certificates.crt ]; then
    mkdir -p "$ROOTFS/usr/local/share/ca-certificates"
    cp -L /etc/ssl/certs/ca-certificates.crt "$ROOTFS/usr/local/share/ca-certificates/host-bundle.crt"
  fi
  # the host's local apt settings (proxy, mirror options): files no Debian package owns
  for f in /etc/apt/apt.conf.d/*; do
    [ -f "$f" ] && ! dpkg -S "$f" >/dev/null 2>&1 && cp "$f" "$ROOTFS/etc/apt/apt.conf.d/"
  done
  return 0
}

in_chroot() {   # in_chroot CMD...: CMD as root in the chroot, in the repository's copy if it exists
  chroot_env
  chroot "$ROOTFS" /usr/bin/env -i "${ENV[@]}" /bin/bash -c \
    'cd '"$COPY"' 2>/dev/null || cd /root; exec "$@"' bash "$@"
}

in_chroot_offline() {   # as in_chroot, in a new network namespace that has only loopback
  chroot_env
  unshare --net -- /bin/bash -c 'ip link set lo up && exec chroot "$@"' bash \
    "$ROOTFS" /usr/bin/env -i "${ENV[@]}" /bin/bash -c \
    'cd '"$COPY"' 2>/dev/null || cd /root; exec "$@"' bash "$@"
}

sources() {
  echo "deb $MIRROR $SUITE main"
  echo "deb $MIRROR $SUITE-updates main"
  [ -z "$SECURITY_MIRROR" ] || echo "deb $SECURITY_MIRROR $SUITE-security main"
}

# ---- the chroot itself ---------------------------------------------------------------------
# the Makefile's apt package lists as written (every APT_* assignment with its continuation
# lines; not as evaluated: the host is another release and the chroot may have no make yet)
apt_list() { awk '/^APT_[A-Za-z0-9_]* *[:?+]?=/ { on = 1 } on { print } !/\\$/ { on = 0 }' "$REPO/Makefile"; }

build_rootfs() {
  command -v debootstrap >/dev/null || { say "apt-get install debootstrap (host)";
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq -o DPkg::Lock::Timeout=300 debootstrap >/dev/null; }
  [ ! -e "$ROOTFS" ] || { say "removing the old chroot"; remove_rootfs; }
  rm -f "$BASE/rootfs.stamp"
  local t0=$SECONDS
  say "debootstrap --variant=minbase $SUITE $ROOTFS ($MIRROR)"
  debootstrap --variant=minbase "$SUITE" "$ROOTFS" "$MIRROR" > "$LOG/debootstrap.log" 2>&1 \
    || { tail -30 "$LOG/debootstrap.log"; say "debootstrap failed, see $LOG/debootstrap.log"; exit 1; }
  sources > "$ROOTFS/etc/apt/sources.list"
  say "debootstrap: $((SECONDS - t0)) s"
  t0=$SECONDS
  mount_all
  host_files
  # what `make setup` needs to start: make (and sudo is not needed: it runs as root)
  in_chroot bash -c 'apt-get update -qq && DEBIAN_FRONTEND=noninteractive \
    apt-get install -y -qq --no-install-recommends make >/dev/null' > "$LOG/base.log" 2>&1 \
    || { tail -30 "$LOG/base.log"; say "apt-get install make failed"; exit 1; }
  unmount_all
  echo "$want" > "$BASE/rootfs.stamp"
  say "base packages: $((SECONDS - t0)) s"
}

# the stamp: what builds the chroot (these functions, the mirrors) and the Makefile's apt lists
want=$( { declare -f build_rootfs sources; echo "$MIRROR $SECURITY_MIRROR"; apt_list; } | sha256sum | cut -c1-16)
have=$(cat "$BASE/rootfs.stamp" 2>/dev/null || true)
if [ "$have" != "$want" ] || [ ! -x "$ROOTFS/usr/bin/make" ]; then
  build_rootfs
else
  say "chroot up to date ($ROOTFS)"
fi

# ---- the repository's copy -------------------------------------------------------------------
copy_repo() {
  local dst=$ROOTFS$COPY keep=$ROOTFS/root/.tiago_nav_keep
  rm -rf "$keep"; mkdir -p "$keep"
  if [ -d "$dst" ]; then
    local d
    for d in .venv .ws; do [ ! -d "$dst/$d" ] || mv "$dst/$d" "$keep/$d"; done
    rm -rf --one-file-system "$dst"
  fi
  mkdir -p "$dst"
  (cd "$REPO" && git ls-files -co --exclude-standard -z | while IFS= read -r -d '' f; do
     if [ -e "$f" ] || [ -L "$f" ]; then printf '%s\0' "$f"; fi; done \
   | tar --null -T - -cf -) | tar -C "$dst" -xf -
  for d in .venv .ws; do [ ! -d "$keep/$d" ] || mv "$keep/$d" "$dst/$d"; done
  rmdir "$keep"
  # the reference beside the repository (../shared/reference) that test_world compares with
  rm -rf "$ROOTFS/root/shared"
  if [ -d "$REPO/../shared/reference" ]; then
    mkdir -p "$ROOTFS/root/shared" && cp -r "$REPO/../shared/reference" "$ROOTFS/root/shared/"
  fi
}
copy_repo

mount_all
host_files

# ---- the steps ------------------------------------------------------------------------------
stamp_lines() {   # each line prefixed by the seconds since the step began
  local t0=$SECONDS line
  while IFS= read -r line; do printf '%4d s| %s\n' $((SECONDS - t0)) "$line"; done
}

run_step() {   # run_step STEP: the step's command, its output timestamped into $LOG/STEP.log
  case "$1" in
    setup)   in_chroot make setup ;;
    test)    in_chroot_offline make test ;;
    demo)    in_chroot_offline make demo ;;
    mission) in_chroot_offline make demo DEMO_ARGS="--rtf 0 --png $COPY/test-results/mission.png" ;;
  esac 2>&1 | stamp_lines | tee "$LOG/$1.log"
}

declare -A RESULT
rc=0
out=$REPO/test-results/platforms
for step in "${STEPS[@]}"; do
  t0=$SECONDS
  label="make $step"; [ "$step" != shell ] || label="bash (offline)"
  say "$label"
  if [ "$step" = shell ]; then
    in_chroot_offline bash -i || true
  else
    [ "$step" != mission ] || rm -f "$ROOTFS$COPY/test-results/mission."* "$out/$ROW-mission."*
    # in the background, waited for: a TERM or INT then ends the run at once (bash runs a trap
    # only once the foreground command is done), and cleanup stops the step's processes
    run_step "$step" &
    wait $! || { rc=1; RESULT[$step]="FAILED"; }
    if [ "$step" = mission ]; then
      mkdir -p "$out"
      for f in "$ROOTFS$COPY/test-results/mission."*; do
        [ ! -f "$f" ] || cp "$f" "$out/$ROW-mission.${f##*.}"
      done
    fi
  fi
  RESULT[$step]="${RESULT[$step]:-ok} in $((SECONDS - t0)) s"
  say "$label: ${RESULT[$step]}"
  if [ "$step" = setup ] && [ $rc != 0 ]; then break; fi
done

echo
echo "== $SUITE ($ROOTFS)"
for step in "${STEPS[@]}"; do
  [ -n "${RESULT[$step]:-}" ] || continue
  [ "$step" = shell ] || echo "make $step: ${RESULT[$step]}"
  case "$step" in
    test) sed 's/^ *[0-9]* s| //' "$LOG/test.log" | grep -E '^FAILED ' || true
          sed 's/^ *[0-9]* s| //' "$LOG/test.log" | grep -E '^[0-9]+ passed, [0-9]+ failed' | tail -1 \
            || echo "(no test summary line)" ;;
    demo|mission) sed 's/^ *[0-9]* s| //' "$LOG/$step.log" | grep -v '^\[' \
            | sed -n '/^== demo: /p;/^\(SUCCEEDED\|ABORTED\|PREEMPTED\|REJECTED\|final pose\|demo: \)/p;/^ground truth/,/^== demo /p' ;;
  esac
done
exit $rc
