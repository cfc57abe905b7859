#!/usr/bin/env bash
# Set up terratheme in ./.venv on a fresh machine (Python >= 3.11 required).
#   bash setup.sh          # the tool and the editor
#   bash setup.sh --test   # plus the test tools (pytest, pytest-qt, hypothesis, ruff)
set -euo pipefail
cd "$(dirname "$0")"

extra="app"
[ "${1:-}" = "--test" ] && extra="test"

# System libraries: Qt's xcb platform (a real X display) and fonts, and Mesa's EGL/GL with the
# llvmpipe software driver for the GPU path on machines without a GPU. Present on most
# desktops; installed via apt when root.
need=()
libs=$(PATH="$PATH:/sbin:/usr/sbin" ldconfig -p 2>/dev/null || true)
for pair in libGL.so.1:libgl1 libEGL.so.1:libegl1 libEGL_mesa.so.0:libegl-mesa0 \
            libgbm.so.1:libgbm1 libfontconfig.so.1:libfontconfig1 \
            libxkbcommon.so.0:libxkbcommon0 libxkbcommon-x11.so.0:libxkbcommon-x11-0 \
            libdbus-1.so.3:libdbus-1-3 libglib-2.0.so.0:libglib2.0-0 \
            libxcb-cursor.so.0:libxcb-cursor0 libxcb-icccm.so.4:libxcb-icccm4 \
            libxcb-keysyms.so.1:libxcb-keysyms1 libxcb-image.so.0:libxcb-image0 \
            libxcb-render-util.so.0:libxcb-render-util0 libxcb-randr.so.0:libxcb-randr0 \
            libxcb-shape.so.0:libxcb-shape0 libxcb-xkb.so.1:libxcb-xkb1 \
            libxcb-xinerama.so.0:libxcb-xinerama0 libX11-xcb.so.1:libx11-xcb1; do
  lib=${pair%%:*}; pkg=${pair##*:}
  grep -qF "$lib" <<<"$libs" || need+=("$pkg")
done
# Mesa's software rasteriser (llvmpipe) is a DRI driver, not on the linker path (Debian:
# /usr/lib/x86_64-linux-gnu/dri; others /usr/lib/dri or /usr/lib64/dri).
mesa=0
for f in /usr/lib/*/dri/swrast_dri.so /usr/lib/dri/swrast_dri.so /usr/lib64/dri/swrast_dri.so; do
  [ -e "$f" ] && mesa=1
done
[ "$mesa" = 1 ] || need+=(libgl1-mesa-dri)
if [ ${#need[@]} -gt 0 ]; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    echo "setup: installing system libraries: ${need[*]}"
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need[@]}" >/dev/null
  else
    echo "setup: warning: missing system libraries (editor on a real display, GPU path):" \
         "${need[*]} (install them with your package manager)" >&2
  fi
fi

PY=${PYTHON:-python3}
"$PY" -c 'import sys; sys.exit(sys.version_info < (3, 11))' || { echo "setup: Python >= 3.11 required" >&2; exit 1; }
if [ ! -x .venv/bin/python ]; then
  "$PY" -m venv .venv
  .venv/bin/python -m pip install -q --upgrade pip
fi
# The project and its dependencies: only when the venv is new, pyproject.toml changed or an
# extra is not installed yet (a stamp in the venv records what was installed).
stamp=.venv/terratheme-setup.stamp
digest=$(sha256sum pyproject.toml | cut -d' ' -f1)
have=""
[ -f "$stamp" ] && [ "$(sed -n 1p "$stamp")" = "$digest" ] && have=$(sed -n 2p "$stamp")
[ "$extra" = app ] || extra="app,$extra"  # the test extra holds the app's too
missing=0
for e in ${extra//,/ }; do
  case ",$have," in *",$e,"*) ;; *) missing=1 ;; esac
done
if [ "$missing" = 1 ]; then
  .venv/bin/python -m pip install -q -e ".[$extra]"
  printf '%s\n%s\n' "$digest" "$(tr ',' '\n' <<<"$have,$extra" | grep . | sort -u | paste -sd,)" \
    >"$stamp"
fi
# Compile the numba kernels that convert, render, export and the editor run (cached beside
# the sources), so a first run is as fast as a second; only when core's kernel sources or
# numba changed since the last time (app/warmup.py keeps a stamp with their hash).
.venv/bin/python -m terratheme.app.warmup --if-changed
# The project's own bytecode, for interpreters that do not write it (PYTHONDONTWRITEBYTECODE):
# compiling ~120 modules from source costs a quarter of a second on every command.
.venv/bin/python -m compileall -q core app
echo "setup: ready (.venv/bin/terratheme)"
