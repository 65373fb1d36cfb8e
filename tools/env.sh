# Set up this shell for stewart_vibration in the pip world: create or reuse ./.venv with the pinned
# requirements, the interfaces package (built with colcon) and this package (editable), then export what
# rclpy needs (AMENT_PREFIX_PATH = the venv prefix; CMAKE_PREFIX_PATH too, for colcon builds) and put the
# executables (stewart-vibration, the nodes) on PATH. Safe to `source` from an interactive shell: it
# changes no shell options and returns (does not exit) on an error.
#   source tools/env.sh
# The suite's messages, services and actions (stewart_vibration_interfaces, an ament_cmake package): built
# with colcon into the venv itself (merged install: its Python modules land in site-packages and its ament
# index entry in share/), again whenever a file of the package changes.
_stewart_interfaces() {
  local repo="$1" venv="$2" src stamp want build tool
  src="$repo/stewart_vibration_interfaces"
  stamp="$venv/.interfaces.sha"
  want="$(cd "$src" && find . -type f -not -name '*~' | LC_ALL=C sort | xargs cat | sha256sum | cut -d' ' -f1)"
  [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ] && return 0
  if [ "${STEWART_VENV_NO_INSTALL:-0}" = 1 ]; then
    echo "[venv] $venv needs stewart_vibration_interfaces (re)built for $repo, but STEWART_VENV_NO_INSTALL=1" >&2
    return 1
  fi
  for tool in cmake cc c++; do
    if ! command -v "$tool" >/dev/null 2>&1; then
      echo "[venv] building stewart_vibration_interfaces needs cmake and a C and C++ compiler ('$tool' not found):" \
        "on Debian, apt-get install -y g++ cmake" >&2
      return 1
    fi
  done
  # one build at a time: two shells set up at once (a test run beside a main job) would build into the same
  # folder; the second waits and finds the stamp written
  (
    command -v flock >/dev/null 2>&1 && flock 9
    [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ] && exit 0
    echo "[venv] building stewart_vibration_interfaces with colcon (about 20 s)" >&2
    build="$venv/.interfaces_build"
    rm -rf "$build"
    if ! PATH="$venv/bin:$PATH" AMENT_PREFIX_PATH="$venv" CMAKE_PREFIX_PATH="$venv" "$venv/bin/colcon" --log-base "$build/log" build \
        --merge-install --base-paths "$src" --build-base "$build/build" --install-base "$venv" \
        --event-handlers console_cohesion- summary- status- > "$build.log" 2>&1; then
      tail -n 30 "$build.log" >&2
      echo "[venv] building stewart_vibration_interfaces failed; the whole log: $build.log" >&2
      exit 1
    fi
    echo "$want" > "$stamp"
  ) 9>"$venv/.interfaces.lock"
}
# The package's ament index entry in the venv, as colcon gives it on a ROS install: the index marker, and
# share/stewart_vibration/{package.xml,launch/*.py,config} linked to the checkout, and the executables in
# lib/stewart_vibration, so `ros2 run`, `ros2 pkg` and `ros2 launch` of a real ros2cli find the package. They
# are in bin/ too: activating the venv alone (the usual Python habit) puts stewart-vibration and the nodes on
# PATH.
_stewart_ament_entry() {
  local repo="$1" venv="$2" share="$2/share/stewart_vibration" marker
  marker="$venv/share/ament_index/resource_index/packages/stewart_vibration"
  # a checkout that borrows another one's venv leaves that venv's entry pointing at its owner
  if [ "${STEWART_VENV_NO_INSTALL:-0}" = 1 ] && [ -f "$marker" ]; then return 0; fi
  mkdir -p "$(dirname "$marker")" "$share" || return 1
  : > "$marker"
  ln -sfn "$repo/stewart_vibration/package.xml" "$share/package.xml" &&
    ln -sfn "$repo/stewart_vibration/config" "$share/config" || return 1
  # ros2 launch finds a launch file by os.walk of the share folder, which does not enter a linked folder:
  # a real launch/ folder, its files linked
  local file
  [ -L "$share/launch" ] && { rm -f "$share/launch" || return 1; }
  mkdir -p "$share/launch" || return 1
  for file in "$repo/stewart_vibration/launch/"*.py; do
    ln -sfn "$file" "$share/launch/$(basename "$file")" || return 1
  done
  # shellcheck disable=SC2046  # one word per executable name
  _stewart_link_executables "$venv" $("$venv/bin/python" -c "import importlib.metadata as m
print(' '.join(e.name for e in m.distribution('stewart-vibration').entry_points if e.group == 'console_scripts'))")
}
# Each named executable both in <venv>/lib/stewart_vibration (where ros2 run looks) and in <venv>/bin (PATH
# of an activated venv): setup.cfg asks for lib/stewart_vibration, but a pip that installs editables as
# wheels (PEP 660: a recent pip with a recent setuptools) puts them in bin/; whichever is missing is linked
# to the other.
_stewart_link_executables() {
  local venv="$1" name lib bin
  shift
  mkdir -p "$venv/lib/stewart_vibration" || return 1
  for name in "$@"; do
    lib="$venv/lib/stewart_vibration/$name" bin="$venv/bin/$name"
    if [ -f "$lib" ] && [ ! -L "$lib" ]; then
      ln -sfn "$lib" "$bin" || return 1
    elif [ -f "$bin" ] && [ ! -L "$bin" ]; then
      ln -sfn "$bin" "$lib" || return 1
    fi
  done
  return 0
}
_stewart_env() {
  local repo venv py stamp want
  repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)" || return 1
  venv="${STEWART_VENV:-$repo/.venv}"
  py="${PYTHON:-python3}"
  stamp="$venv/.requirements.sha"
  want="$(cat "$repo/requirements.txt" "$repo/requirements-dev.txt" "$repo/requirements-interfaces.txt" \
    "$repo/stewart_vibration/setup.py" | sha256sum | cut -d' ' -f1)"
  if [ ! -x "$venv/bin/python" ]; then
    echo "[venv] creating $venv" >&2
    "$py" -m venv "$venv" || return 1
  fi
  # reinstall also when the editable install's metadata is gone (e.g. a removed *.egg-info)
  if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ] || \
     ! "$venv/bin/python" -c "import importlib.metadata as m; m.distribution('stewart-vibration')" 2>/dev/null; then
    # a checkout that borrows another one's venv (STEWART_VENV_NO_INSTALL=1, e.g. the README test's copy)
    # must never re-point that venv's editable install at itself
    if [ "${STEWART_VENV_NO_INSTALL:-0}" = 1 ]; then
      echo "[venv] $venv needs (re)installing for $repo, but STEWART_VENV_NO_INSTALL=1" >&2
      return 1
    fi
    echo "[venv] installing requirements (first run takes about a minute)" >&2
    "$venv/bin/python" -m pip install -q --disable-pip-version-check -r "$repo/requirements-dev.txt" >&2 || return 1
    "$venv/bin/python" -m pip install -q --disable-pip-version-check --no-deps --no-build-isolation -e "$repo/stewart_vibration" >&2 \
      || return 1
    echo "$want" > "$stamp"
  fi
  _stewart_interfaces "$repo" "$venv" || return 1
  _stewart_ament_entry "$repo" "$venv" || return 1
  REPO="$repo"
  # setup.cfg puts executables in lib/stewart_vibration (the ros2 run layout).
  export PATH="$venv/lib/stewart_vibration:$venv/bin:$PATH"
  export AMENT_PREFIX_PATH="$venv${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
  # as a ROS install's setup script does: ament_cmake packages (colcon build) find the venv's ROS packages
  export CMAKE_PREFIX_PATH="$venv${CMAKE_PREFIX_PATH:+:$CMAKE_PREFIX_PATH}"
  export PYTHONUNBUFFERED=1
}
_stewart_env
