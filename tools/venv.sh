# Sourced by the other tools: create or reuse ./.venv with the pinned
# requirements and this package installed in editable mode, then export the
# environment rclpy needs in the pip world (AMENT_PREFIX_PATH = venv prefix).
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${STEWART_VENV:-$REPO/.venv}"
PY="${PYTHON:-python3}"
stamp="$VENV/.requirements.sha"
want="$(cat "$REPO/requirements.txt" "$REPO/requirements-dev.txt" "$REPO/setup.py" | sha256sum | cut -d' ' -f1)"
if [ ! -x "$VENV/bin/python" ]; then
  echo "[venv] creating $VENV" >&2
  "$PY" -m venv "$VENV"
fi
# reinstall also when the editable install's metadata is gone (e.g. a removed *.egg-info)
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ] || \
   ! "$VENV/bin/python" -c "import importlib.metadata as m; m.distribution('stewart-vibration')" 2>/dev/null; then
  echo "[venv] installing requirements (first run takes about a minute)" >&2
  "$VENV/bin/python" -m pip install -q --disable-pip-version-check -r "$REPO/requirements-dev.txt" >&2
  "$VENV/bin/python" -m pip install -q --disable-pip-version-check --no-deps --no-build-isolation -e "$REPO" >&2
  echo "$want" > "$stamp"
fi
# setup.cfg puts executables in lib/stewart_vibration (the ros2 run layout).
export PATH="$VENV/lib/stewart_vibration:$VENV/bin:$PATH"
export AMENT_PREFIX_PATH="$VENV${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
export PYTHONUNBUFFERED=1
