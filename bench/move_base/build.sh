#!/bin/bash
# Builds ROS's move_base (ros-planning/navigation, noetic-devel), the navigation candidate the
# people suite runs beside the project's own navigation (suites/people_move_base.yaml), in a
# catkin workspace of its own. Debian packages ROS 1's core libraries but not the navigation
# stack, so move_base, costmap_2d, navfn, base_local_planner, dwa_local_planner, the two recovery
# behaviours, nav_core and voxel_grid are built from source against them; nothing is patched.
#
# Usage: bench/move_base/build.sh [WORKSPACE]   (default: .mb_ws in the repository)
#   MB_SOURCE  git URL or directory to clone (default https://github.com/ros-planning/navigation)
#   MB_REV     the commit built (default: the one the published figures are for)
# Then `source WORKSPACE/devel/setup.bash --extend` on top of this package's workspace.
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
WS=$(realpath -m "${1:-$HERE/../../.mb_ws}")
SRC=${MB_SOURCE:-https://github.com/ros-planning/navigation}
REV=${MB_REV:-9ad644198e132d0e950579a3bc72c29da46e60b0}
PACKAGES="voxel_grid costmap_2d nav_core navfn base_local_planner dwa_local_planner clear_costmap_recovery rotate_recovery move_base"
APT="catkin ros-core-dev libactionlib-dev libeigen3-dev liblaser-geometry-dev libtf2-sensor-msgs-dev
     libtf2-geometry-msgs-dev libtf2-ros-dev libangles-dev libmap-msgs-dev libmove-base-msgs-dev
     libnav-msgs-dev libvisualization-msgs-dev libstd-srvs-dev libdynamic-reconfigure-config-init-mutex-dev
     python3-dynamic-reconfigure"
SUDO=$([ "$(id -u)" = 0 ] || echo sudo)
missing=$(for p in $APT; do dpkg-query -W -f='${Status}\n' "$p" 2>/dev/null | grep -q '^install ok installed$' || echo "$p"; done)
if [ -n "$missing" ]; then
  echo "[move_base] apt-get install:" $missing
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends $missing >/dev/null
fi
rm -rf "$WS/src/navigation" "$WS/build" "$WS/devel"
mkdir -p "$WS/src"
git clone -q "$SRC" "$WS/src/navigation"
git -C "$WS/src/navigation" checkout -q "$REV"
echo "[move_base] catkin_make in $WS (a few minutes)"
# Debian's catkin and ament (pluginlib): the system python (a python3 earlier on PATH may lack
# catkin_pkg and ament_package)
(cd "$WS" && catkin_make -j2 -DPYTHON_EXECUTABLE=/usr/bin/python3 -DPython3_EXECUTABLE=/usr/bin/python3 \
   -DCMAKE_BUILD_TYPE=Release \
   -DCATKIN_ENABLE_TESTING=OFF -DCATKIN_WHITELIST_PACKAGES="${PACKAGES// /;}" > "$WS/build.log" 2>&1) \
  || { tail -40 "$WS/build.log"; echo "[move_base] catkin_make failed, see $WS/build.log"; exit 1; }
echo "[move_base] built; use it with: source $WS/devel/setup.bash --extend"
