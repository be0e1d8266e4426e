#!/usr/bin/env bash
# Resolves package.xml with rosdep against a pinned copy of rosdep's key database, offline: every
# key must resolve on this machine's OS. Prints each key with the installer and packages it
# resolves to, then `rosdep install --from-paths PKG --ignore-src -y --simulate`; with --install,
# runs that install for real (root, or sudo).
#
#   TIAGO_NAV_ROSDEP_SOURCES=DIR test/platforms/rosdep_check.sh [--install] [--os=OS:VERSION] [PKG]
#
#   DIR: a copy of the rosdep/ folder of ros/rosdistro (base.yaml, python.yaml, ruby.yaml), kept
#        outside the repository; PKG: the package's folder (default: this repository).
#   --os: passed to rosdep, e.g. --os=debian:bookworm where rosdep cannot detect the OS.
#
# rosdep is Debian's (`apt-get install python3-rosdep2`): its sources list adds debian.yaml, which
# maps the ROS 1 packages (rospy, actionlib, ...) to Debian's own (python3-rospy, ...). The
# script uses the system's sources lists with every ros/rosdistro URL replaced by the same file in
# DIR (so a list that names a file DIR lacks is an error), keeps local `file://` sources, drops
# the legacy gbpdistro one, and gives rosdep an empty rosdistro index (TIAGO_NAV_ROSDISTRO_INDEX,
# a file:// URL, to use another): the index only adds the ros-<distro>-* builds of Ubuntu, which
# Debian's ROS packages replace. All of it in a temporary ROS_HOME and ROSDEP_SOURCE_PATH: the
# machine's own rosdep cache is not touched. ROS_PYTHON_VERSION is 3 (Debian's ROS 1 serves
# Python 3 only; rosdep otherwise reads it from the index).
set -euo pipefail

usage() { sed -n '7,12p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2; }
INSTALL=0 OS_ARGS=() PKG=
for a in "$@"; do
  case "$a" in
    --install) INSTALL=1 ;;
    --os=*) OS_ARGS=("$a") ;;
    -h|--help) usage ;;
    -*) usage ;;
    *) PKG=$a ;;
  esac
done
HERE=$(cd "$(dirname "$0")" && pwd)
PKG=$(cd "${PKG:-$HERE/../..}" && pwd)
SRC=${TIAGO_NAV_ROSDEP_SOURCES:-}
[ -n "$SRC" ] && [ -f "$SRC/base.yaml" ] && [ -f "$SRC/python.yaml" ] || {
  echo "$0: set TIAGO_NAV_ROSDEP_SOURCES to a copy of ros/rosdistro's rosdep/ (base.yaml, python.yaml, ...)" >&2
  exit 2; }
SRC=$(cd "$SRC" && pwd)
command -v rosdep >/dev/null || { echo "$0: no rosdep (apt-get install python3-rosdep2)" >&2; exit 2; }

WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
export ROS_HOME=$WORK/ros ROSDEP_SOURCE_PATH=$WORK/sources.list.d ROS_PYTHON_VERSION=3
mkdir -p "$ROS_HOME" "$ROSDEP_SOURCE_PATH"
unset ROS_DISTRO

# the system's sources lists, their ros/rosdistro files taken from $SRC
system_lists=(/etc/ros/rosdep/sources.list.d/*.list)
[ -e "${system_lists[0]}" ] || system_lists=()
{
  if [ ${#system_lists[@]} -eq 0 ]; then   # rosdep without lists of its own (e.g. from PyPI)
    printf 'yaml https://raw.githubusercontent.com/ros/rosdistro/master/rosdep/%s.yaml\n' base python ruby
  else
    cat "${system_lists[@]}"
  fi
} | while read -r type url tags; do
  case "$type" in ''|'#'*) continue ;; esac
  case "$type $url" in
    'yaml file://'*) echo "yaml $url $tags" ;;
    'yaml https://raw.githubusercontent.com/ros/rosdistro/'*/rosdep/*.yaml)
      f=$SRC/${url##*/}
      [ -f "$f" ] || { echo "$0: the sources list names ${url##*/}, which $SRC lacks" >&2; exit 1; }
      echo "yaml file://$f $tags" ;;
    'gbpdistro '*) ;;   # fuerte's, legacy
    *) echo "$0: cannot pin this source (not ros/rosdistro's): $type $url" >&2; exit 1 ;;
  esac
done > "$ROSDEP_SOURCE_PATH/20-pinned.list"
if [ -z "${TIAGO_NAV_ROSDISTRO_INDEX:-}" ]; then
  printf 'type: index\nversion: 4\ndistributions: {}\n' > "$WORK/index-v4.yaml"
  export ROSDISTRO_INDEX_URL=file://$WORK/index-v4.yaml
else
  export ROSDISTRO_INDEX_URL=$TIAGO_NAV_ROSDISTRO_INDEX
fi

echo "== rosdep $(rosdep --version), sources ($ROSDEP_SOURCE_PATH/20-pinned.list):"
sed 's/^/   /' "$ROSDEP_SOURCE_PATH/20-pinned.list"
[ ! -f "$SRC/COMMIT" ] || echo "   (ros/rosdistro $(cat "$SRC/COMMIT"))"
rosdep update > "$WORK/update.log" 2>&1 || { cat "$WORK/update.log" >&2; exit 1; }

# every key with what it resolves to (rosdep resolve prints "#ROSDEP[key]", "#installer", packages)
mapfile -t keys < <(rosdep keys --from-paths "$PKG" --ignore-src "${OS_ARGS[@]}" | sort)
echo "== ${#keys[@]} keys from $PKG/package.xml"
resolve_rc=0
rosdep resolve "${OS_ARGS[@]}" "${keys[@]}" > "$WORK/resolve.log" 2>&1 || resolve_rc=$?
awk '/^ERROR/ { next }
     /^#ROSDEP\[/ { k = substr($0, 9, length($0) - 9); next }
     /^#/ { inst = substr($0, 2); next }
     NF { printf "   %-24s %-4s %s\n", k, inst, $0 }' "$WORK/resolve.log"
grep -v '^#\|^[a-z0-9]' "$WORK/resolve.log" >&2 || true   # rosdep's errors (unresolved keys)
awk '/^#ROSDEP\[/ { next } /^#/ { n[substr($0, 2)]++ } END { for (i in n) printf "   %s: %d keys\n", i, n[i] }' \
  "$WORK/resolve.log" | sort
[ "$resolve_rc" -eq 0 ] || { echo "== rosdep resolve failed: a key above has no rule for this OS" >&2; exit 1; }

echo "== rosdep install --from-paths $PKG --ignore-src -y --simulate ${OS_ARGS[*]}"
rosdep install --from-paths "$PKG" --ignore-src -y --simulate "${OS_ARGS[@]}" | sed 's/^/   /'
# the same with --reinstall lists every package, the ones installed here too
rosdep install --from-paths "$PKG" --ignore-src -y --simulate --reinstall "${OS_ARGS[@]}" > "$WORK/all.log"
echo "== every package (--simulate --reinstall): $(grep -c 'apt-get install' "$WORK/all.log") by apt," \
  "$(grep -c 'pip3\? install' "$WORK/all.log") by pip:" \
  $(sed -n 's/.*apt-get install -y //p; s/.*pip3\{0,1\} install -U -I //p; s/.*pip3\{0,1\} install -I -U //p' "$WORK/all.log")
if [ "$INSTALL" = 1 ]; then
  echo "== rosdep install --from-paths $PKG --ignore-src -y ${OS_ARGS[*]}"
  rosdep install --from-paths "$PKG" --ignore-src -y "${OS_ARGS[@]}"
fi
