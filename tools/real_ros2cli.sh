#!/usr/bin/env bash
# The real ros2cli, launch and launch_ros (ROS 2 Jazzy, not on PyPI) built from their sources into a venv,
# with this project set up in it as `source tools/env.sh` does: to try the docs' `ros2 ...` lines as a ROS
# user would, where there is no ROS install. By hand only (the tests use test/ros2_shim.py).
#   tools/real_ros2cli.sh BASE            # BASE: a scratch folder (the venv, the sources and a clone go there)
# Sources: git clones of github.com/ros2/{ros2cli,launch,launch_ros,rosidl_runtime_py}, branch jazzy, or with
# MIRROR=<folder> bare mirrors named <folder>/ros2+<repo>/repo. Then, in each shell:
#   export STEWART_VENV=BASE/venv ROS_DOMAIN_ID=21 ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
#   cd BASE/p && source tools/env.sh      # ros2, stewart-vibration and the nodes on PATH; ros2 run/launch work
set -euo pipefail
BASE=$(realpath -m "${1:?usage: tools/real_ros2cli.sh BASE}")
PROJECT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
mkdir -p "$BASE/src"
cd "$BASE"
[ -d p ] || git clone -q "$PROJECT" p
[ -x venv/bin/python ] || python3 -m venv venv
venv/bin/python -m pip install -q -r p/requirements-dev.txt
# pure-Python dependencies of ros2cli's verbs and of launch (their rosdep keys, by PyPI name)
venv/bin/python -m pip install -q argcomplete packaging psutil netifaces catkin_pkg osrf-pycommon lark \
  ros-jazzy-lifecycle-msgs ros-jazzy-ament-index-python
for repo in ros2cli launch launch_ros rosidl_runtime_py; do
  [ -d "src/$repo" ] && continue
  if [ -n "${MIRROR:-}" ]; then
    mkdir -p "src/$repo" && git --git-dir="$MIRROR/ros2+$repo/repo" archive jazzy | tar -x -C "src/$repo"
  else
    git clone -q --depth 1 --branch jazzy "https://github.com/ros2/$repo" "src/$repo"
  fi
done
venv/bin/python -m pip install -q --no-deps --no-build-isolation src/rosidl_runtime_py \
  src/ros2cli/ros2cli src/ros2cli/ros2node src/ros2cli/ros2service src/ros2cli/ros2topic src/ros2cli/ros2param \
  src/ros2cli/ros2lifecycle src/ros2cli/ros2run src/ros2cli/ros2pkg src/ros2cli/ros2interface \
  src/ros2cli/ros2action src/launch/launch src/launch/launch_xml src/launch/launch_yaml \
  src/launch_ros/launch_ros src/launch_ros/ros2launch
# launch_ros imports composition_interfaces (a message package not on PyPI) at module level for composable
# nodes, which this project does not use: a stub that refuses any use lets it import
site=$(venv/bin/python -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
mkdir -p "$site/composition_interfaces"
echo '"""Stub: composition_interfaces is not on PyPI; composable nodes are unavailable."""' \
  > "$site/composition_interfaces/__init__.py"
cat > "$site/composition_interfaces/srv.py" <<'STUB'
"""Stub of composition_interfaces.srv: any use raises."""


class _Unavailable:
    def __init__(self, *args, **kwargs):
        raise RuntimeError("composition_interfaces is a stub here: composable nodes are unavailable")


class LoadNode(_Unavailable):
    Request = _Unavailable


class UnloadNode(_Unavailable):
    Request = _Unavailable


class ListNodes(_Unavailable):
    Request = _Unavailable
STUB
(cd p && STEWART_VENV="$BASE/venv" bash -c 'source tools/env.sh')
echo "done. In each shell:"
echo "  export STEWART_VENV=$BASE/venv ROS_DOMAIN_ID=21 ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST"
echo "  cd $BASE/p && source tools/env.sh && which ros2"
