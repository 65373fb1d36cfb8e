# Set up this shell for stewart_vibration in the pip world: create or reuse ./.venv with the pinned
# requirements and this package (editable), then export what rclpy needs (AMENT_PREFIX_PATH = the venv
# prefix) and put the executables (stewart-vibration, the nodes) on PATH. Safe to `source` from an
# interactive shell: it changes no shell options and returns (does not exit) on an error.
#   source tools/env.sh
_stewart_env() {
  local repo venv py stamp want
  repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)" || return 1
  venv="${STEWART_VENV:-$repo/.venv}"
  py="${PYTHON:-python3}"
  stamp="$venv/.requirements.sha"
  want="$(cat "$repo/requirements.txt" "$repo/requirements-dev.txt" "$repo/setup.py" | sha256sum | cut -d' ' -f1)"
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
    "$venv/bin/python" -m pip install -q --disable-pip-version-check --no-deps --no-build-isolation -e "$repo" >&2 \
      || return 1
    echo "$want" > "$stamp"
  fi
  REPO="$repo"
  # setup.cfg puts executables in lib/stewart_vibration (the ros2 run layout).
  export PATH="$venv/lib/stewart_vibration:$venv/bin:$PATH"
  export AMENT_PREFIX_PATH="$venv${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
  export PYTHONUNBUFFERED=1
}
_stewart_env
