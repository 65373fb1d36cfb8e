# Sourced by tools/main and tools/test (which set their own shell options): the environment of
# tools/env.sh, and stop the calling script if it could not be set up.
# shellcheck source=tools/env.sh
source "$(dirname "${BASH_SOURCE[0]}")/env.sh" || { echo "[venv] setting up the environment failed" >&2; exit 1; }
