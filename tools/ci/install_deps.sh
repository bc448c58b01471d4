#!/usr/bin/env bash
# Install everything the build, tests and CI need, from Debian's archive only.
# Idempotent: skips packages already present. Run as root (CI machines are root).
#   tools/ci/install_deps.sh [--minimal]
#     --minimal : only what the README's test command needs (compiler, cmake, ruby-free Unity path)
set -euo pipefail

SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi

base_pkgs=(build-essential cmake git ca-certificates dpkg-dev)
full_pkgs=(gcc-arm-none-eabi libnewlib-arm-none-eabi binutils-arm-none-eabi
           qemu-system-arm valgrind cppcheck clang clang-tidy libclang-rt-14-dev
           libcjson-dev pkgconf ruby python3 python3-numpy python3-sklearn python3-matplotlib)

pkgs=("${base_pkgs[@]}")
if [ "${1:-}" != "--minimal" ]; then pkgs+=("${full_pkgs[@]}"); fi

missing=()
for p in "${pkgs[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

# No deb-src entry is added to the system: tools/get_debian_cjson.sh (Unity 2.4.3 and the cJSON
# fallback, run by the configure step) derives its own from these sources in a private apt state.

if [ ${#missing[@]} -gt 0 ]; then
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
fi
if [ ${#missing[@]} -gt 0 ]; then
  echo "install_deps: installing ${missing[*]}"
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
else
  echo "install_deps: all packages present"
fi
