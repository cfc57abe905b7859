#!/usr/bin/env bash
# Set up terratheme in ./.venv on a fresh machine (Python >= 3.11 required).
#   bash setup.sh          # the tool and the editor
#   bash setup.sh --test   # plus the test tools (pytest, pytest-qt, hypothesis, ruff)
set -euo pipefail
cd "$(dirname "$0")"

extra="app"
[ "${1:-}" = "--test" ] && extra="test"

# System libraries the Qt editor needs (present on most desktops; installed via apt when root).
need=()
for pair in libGL.so.1:libgl1 libEGL.so.1:libegl1 libfontconfig.so.1:libfontconfig1 \
            libxkbcommon.so.0:libxkbcommon0 libdbus-1.so.3:libdbus-1-3 libglib-2.0.so.0:libglib2.0-0; do
  lib=${pair%%:*}; pkg=${pair##*:}
  ldconfig -p 2>/dev/null | grep -q "$lib" || need+=("$pkg")
done
if [ ${#need[@]} -gt 0 ]; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    echo "setup: installing system libraries: ${need[*]}"
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need[@]}" >/dev/null
  else
    echo "setup: warning: missing system libraries for the Qt editor: ${need[*]} (install them with your package manager)" >&2
  fi
fi

PY=${PYTHON:-python3}
"$PY" -c 'import sys; sys.exit(sys.version_info < (3, 11))' || { echo "setup: Python >= 3.11 required" >&2; exit 1; }
[ -x .venv/bin/python ] || "$PY" -m venv .venv
.venv/bin/python -m pip install -q --upgrade pip
.venv/bin/python -m pip install -q -e ".[$extra]"
echo "setup: ready (.venv/bin/terratheme)"
