#!/usr/bin/env bash
# Set up (or bring up to date) the flexarm environment in .venv:
#   1. a Python 3.11 venv,
#   2. every pinned dependency of requirements.txt: the runtime (ROS 2 Jazzy wheels, torch CPU,
#      ...), the tests' and the documentation site's (requirements/),
#   3. the interfaces: tf2_msgs and control_msgs (vendor/, no wheel exists) and flexarm_msgs
#      (ament_cmake + rosidl, built into the venv prefix),
#   4. the Python packages of src/ (editable), lowest layer first.
# Each step is skipped when its inputs did not change since it last succeeded, so a re-run
# takes about a second. Usage: scripts/setup.sh [--runtime] [--force]
#   --runtime  only requirements/runtime.txt and the packages a robot machine runs (no tests,
#              no docs site, no flexarm_test_support)
#   --force    redo every step
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
venv="$root/.venv"
stamps="$venv/.flexarm-stamps"
# A parent environment's ROS bootstrap guard would stop the venv's rclpy from loading.
unset _ROS_WHEELS_BOOTSTRAP_COMPLETE VIRTUAL_ENV PYTHONHOME PYTHONPATH

log() { printf '[setup] %s\n' "$*" >&2; }

requirements=requirements.txt
for arg in "$@"; do
  case $arg in
    --force) rm -rf "$stamps" ;;
    --runtime) requirements=requirements/runtime.txt ;;
    *) log "usage: scripts/setup.sh [--runtime] [--force]"; exit 2 ;;
  esac
done

# Content hash of files (paths relative to the repository root).
digest() { (cd "$root" && cat "$@" | sha256sum | cut -c1-16); }

# Run "$@" unless the stamp named $1 holds the hash $2; record it after success.
step() {
  local name=$1 hash=$2
  shift 2
  if [ "$(cat "$stamps/$name" 2>/dev/null)" = "$hash" ]; then
    return 0
  fi
  local start=$SECONDS
  "$@"
  mkdir -p "$stamps"
  echo "$hash" > "$stamps/$name"
  log "$name done in $((SECONDS - start)) s"
}

# pip, quiet on success; on failure its log (minus the local-index noise) is shown.
pip() {
  local out="$venv/.flexarm-pip.log"
  if ! "$venv/bin/python" -m pip --disable-pip-version-check "$@" >"$out" 2>&1; then
    grep -v '^WARNING: Location' "$out" | tail -n 40 >&2
    log "pip $1 failed (full log: $out)"
    return 1
  fi
}

create_venv() {
  local python
  python=$(command -v python3.11 || true)
  [ -n "$python" ] || { log "python3.11 not found (ROS 2 Jazzy wheels and torch need it)"; exit 1; }
  log "creating $venv with $python"
  rm -rf "$venv"
  "$python" -m venv "$venv"
}

install_requirements() {
  log "installing $requirements (first time: about a minute)"
  pip install -r "$root/$requirements"
}

install_tf2_msgs() {
  log "building tf2_msgs (about 30 s)"
  pip install --no-build-isolation --force-reinstall --no-deps "$root/vendor/tf2_msgs"
}

install_control_msgs() {
  log "building control_msgs (about 2 min)"
  pip install --no-build-isolation --force-reinstall --no-deps "$root/vendor/control_msgs"
}

install_msgs() {
  log "building flexarm_msgs (about 30 s)"
  pip install --no-build-isolation --force-reinstall --no-deps "$root/src/flexarm_msgs"
}

# The Python packages, lowest layer first (each imports only those before it).
packages=(flexarm_core flexarm_description flexarm_learning flexarm_deflection flexarm_vision
  flexarm_bridge flexarm_sim flexarm_motion flexarm_control flexarm_bringup flexarm_recording
  flexarm_viz flexarm_cli)
# The graph's test tooling, above all others, imports pytest: not on a robot machine.
[ "$requirements" = requirements/runtime.txt ] || packages+=(flexarm_test_support)

install_packages() {
  log "installing ${packages[*]} (editable)"
  local pkg args=()
  for pkg in "${packages[@]}"; do args+=(-e "$root/src/$pkg"); done
  pip install --no-build-isolation --no-deps "${args[@]}"
  # Editable installs skip data-files: register the packages in the ament index by hand.
  for pkg in "${packages[@]}"; do
    install -D -m 644 "$root/src/$pkg/resource/$pkg" \
      "$venv/share/ament_index/resource_index/packages/$pkg"
    install -D -m 644 "$root/src/$pkg/package.xml" "$venv/share/$pkg/package.xml"
  done
}

[ -x "$venv/bin/python" ] || { rm -rf "$stamps"; create_venv; }
if [ "$requirements" = requirements/runtime.txt ] && [ -e "$venv/bin/pytest" ]; then
  log "$venv already holds the test and docs sets: remove it first for a runtime-only one"
fi
requirement_files=$(cd "$root" && ls requirements.txt requirements/*.txt)
# shellcheck disable=SC2086
step requirements "$requirements $(digest $requirement_files)" install_requirements
# The interfaces are built against the runtime set (its ROS wheels and numpy) only.
tf2_files=$(cd "$root" && find vendor/tf2_msgs -type f -not -path "*/build/*" | sort)
# shellcheck disable=SC2086
step tf2_msgs "$(digest requirements/runtime.txt $tf2_files)" install_tf2_msgs
control_files=$(cd "$root" && find vendor/control_msgs -type f -not -path "*/build/*" | sort)
# shellcheck disable=SC2086
step control_msgs "$(digest requirements/runtime.txt $control_files)" install_control_msgs
msgs_files=$(cd "$root" && find src/flexarm_msgs -type f -not -path "*/build/*" | sort)
# shellcheck disable=SC2086
step msgs "$(digest requirements/runtime.txt $msgs_files)" install_msgs
package_files=()
for pkg in "${packages[@]}"; do
  package_files+=("src/$pkg/pyproject.toml" "src/$pkg/package.xml")
done
step packages "$(digest "${package_files[@]}")" install_packages
# Byte-compile the packages as pip does what it installs (an editable install is not): where
# PYTHONDONTWRITEBYTECODE is set, as on this project's machines, every node process compiled
# them anew. Python still reads these files, and recompiles a module whose source changed.
sources=()
for pkg in "${packages[@]}"; do sources+=("$root/src/$pkg/$pkg"); done
"$venv/bin/python" -m compileall -q "${sources[@]}" >/dev/null
