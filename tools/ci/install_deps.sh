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
           libcjson-dev ruby python3 python3-numpy python3-sklearn python3-matplotlib)

pkgs=("${base_pkgs[@]}")
if [ "${1:-}" != "--minimal" ]; then pkgs+=("${full_pkgs[@]}"); fi

missing=()
for p in "${pkgs[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

# deb-src entries: Unity 2.4.3 ships inside Debian's cjson source package (tests/unity/).
if ! grep -rqsE '^(Types:.*deb-src|deb-src )' /etc/apt/sources.list /etc/apt/sources.list.d/ 2>/dev/null; then
  if [ -f /etc/apt/sources.list.d/debian.sources ]; then
    $SUDO sed -i -E 's/^Types: deb$/Types: deb deb-src/' /etc/apt/sources.list.d/debian.sources
  elif [ -f /etc/apt/sources.list ]; then
    $SUDO sh -c "sed -n 's/^deb /deb-src /p' /etc/apt/sources.list >> /etc/apt/sources.list"
  fi
  NEED_UPDATE=1
fi

if [ ${#missing[@]} -gt 0 ] || [ -n "${NEED_UPDATE:-}" ]; then
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
fi
if [ ${#missing[@]} -gt 0 ]; then
  echo "install_deps: installing ${missing[*]}"
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
else
  echo "install_deps: all packages present"
fi
