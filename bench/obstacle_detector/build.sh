#!/bin/bash
# Builds tysik/obstacle_detector (the ROS detector bench/bench_detection.py compares with) in a
# catkin workspace of its own: its obstacle_extractor node and messages, without its rviz plugins
# and nodelets (minimal.patch: they need Qt and rviz's development packages, and the comparison
# uses neither). It is not a Debian package.
#
# Usage: bench/obstacle_detector/build.sh [WORKSPACE]   (default: .od_ws in the repository)
#   OD_SOURCE  git URL or directory to clone (default https://github.com/tysik/obstacle_detector)
#   OD_REV     the commit built (default: the one the patch and the published figures are for)
# Then `source WORKSPACE/devel/setup.bash --extend` on top of this package's workspace (`make bench`
# does it by itself for .od_ws).
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
WS=$(realpath -m "${1:-$HERE/../../.od_ws}")
SRC=${OD_SOURCE:-https://github.com/tysik/obstacle_detector}
REV=${OD_REV:-bd59d405b2284f05c46f7b99cb9cb4247934e2ff}
APT="catkin ros-core-dev libarmadillo-dev libtf-dev liblaser-geometry-dev"
SUDO=$([ "$(id -u)" = 0 ] || echo sudo)
missing=$(for p in $APT; do dpkg-query -W -f='${Status}\n' "$p" 2>/dev/null | grep -q '^install ok installed$' || echo "$p"; done)
if [ -n "$missing" ]; then
  echo "[obstacle_detector] apt-get install:" $missing
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends $missing >/dev/null
fi
rm -rf "$WS/src/obstacle_detector" "$WS/build" "$WS/devel"
mkdir -p "$WS/src"
git clone -q "$SRC" "$WS/src/obstacle_detector"
git -C "$WS/src/obstacle_detector" checkout -q "$REV"
patch -s -d "$WS/src/obstacle_detector" -p1 < "$HERE/minimal.patch"
echo "[obstacle_detector] catkin_make in $WS"
# Debian's catkin: the system python (a python3 earlier on PATH may lack catkin_pkg)
(cd "$WS" && catkin_make -j2 -DPYTHON_EXECUTABLE=/usr/bin/python3 > "$WS/build.log" 2>&1) \
  || { tail -40 "$WS/build.log"; echo "[obstacle_detector] catkin_make failed, see $WS/build.log"; exit 1; }
echo "[obstacle_detector] built; use it with: source $WS/devel/setup.bash --extend"
