# Shared by scripts/test, scripts/demo and scripts/bench: installing what is missing, building,
# and the environment ROS tools need on Debian. Source it; it defines functions only.

MVIS_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
MVIS_BUILD_DIR="${MVIS_BUILD_DIR:-$MVIS_ROOT/build}"

mvis_log() { printf '[mvis] %s\n' "$*" >&2; }

# Installs the packages of scripts/deps.txt that are not installed yet.
mvis_install_deps() {
  local wanted missing=()
  wanted=$(grep -v '^#' "$MVIS_ROOT/scripts/deps.txt" | tr -s ' \n' '\n' | sed '/^$/d')
  for pkg in $wanted; do
    dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q 'install ok installed' ||
      missing+=("$pkg")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  mvis_log "installing ${#missing[@]} missing Debian packages: ${missing[*]}"
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || { mvis_log "not root and no sudo: install them by hand"; return 1; }
    sudo="sudo"
  fi
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get -o DPkg::Lock::Timeout=600 update -q || return 1
  $sudo apt-get -o DPkg::Lock::Timeout=600 install -y -q --no-install-recommends "${missing[@]}"
}

# The environment ROS 1 tools need here: Debian's python first (the python3 on PATH may be
# another interpreter without the ROS modules), a private ROS_HOME, loopback networking.
mvis_ros_env() {
  export PATH="/usr/bin:$PATH"
  export ROS_HOSTNAME=localhost
  export ROS_HOME="${ROS_HOME:-$MVIS_BUILD_DIR/ros_home}"
  mkdir -p "$ROS_HOME"
  if [ -f "$MVIS_BUILD_DIR/devel/setup.bash" ]; then
    set +u
    # shellcheck disable=SC1091
    source "$MVIS_BUILD_DIR/devel/setup.bash"
    set -u
  fi
}

# Configures (once, or again after a configure that failed) and builds; extra arguments are make
# targets (default: all).
mvis_build() {
  export PATH="/usr/bin:$PATH"
  if [ ! -f "$MVIS_BUILD_DIR/CMakeCache.txt" ] || [ ! -f "$MVIS_BUILD_DIR/Makefile" ]; then
    # shellcheck disable=SC2086  # MVIS_CMAKE_ARGS: extra cache entries, word-split on purpose
    cmake -S "$MVIS_ROOT" -B "$MVIS_BUILD_DIR" -DCMAKE_BUILD_TYPE=Release \
      -DPYTHON_EXECUTABLE=/usr/bin/python3 -DPython3_EXECUTABLE=/usr/bin/python3 \
      ${MVIS_CMAKE_ARGS:-} || return 1
  fi
  make -C "$MVIS_BUILD_DIR" -j"${MVIS_JOBS:-2}" "${@:-all}"
}
